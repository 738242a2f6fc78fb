"""``murk synth --format webdataset --backend ray``: the shards of a synthesis run as Ray tasks.

One Ray task per tar shard runs exactly the local backend's work (:func:`murk.synth.shards.build_shard_task`,
which :func:`murk.synth.shards.write_shards` hands to :func:`run_ray_tasks`: the same per-sample seeds,
rendering, PNG encoding and tar writing), so the bytes equal a local run's. Each task writes its shard atomically
into the output folder, which must therefore be on a file system that every node of the cluster mounts (as must
the inputs and the particle bank); the driver appends each finished shard to the progress log as the task
returns, so a killed driver loses nothing already finished and a rerun resumes.

Why tasks and not Ray Data: the unit of resume and of output is a shard, and a task per shard maps onto it
directly; Ray Data would add pyarrow blocks and its own ordering for no gain here. Install with
``pip install 'murk[ray]'`` on every node (the same murk, numpy and OpenCV versions everywhere: PNG bytes and
floating-point results depend on them).

This module only runs tasks: it imports nothing of murk.synth (the shard writer imports it, not the reverse).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar

R = TypeVar("R")


def ray_available() -> bool:
    """True when Ray can be imported."""
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


def run_ray_tasks(
    task: Callable[..., R],
    calls: Sequence[tuple[Any, ...]],
    *,
    address: str | None = None,
    on_result: Callable[[R], None],
) -> None:
    """Run ``task(*args)`` for every ``args`` of ``calls`` as a Ray task (one CPU each, retried twice) and call
    ``on_result`` with each result as it finishes.

    ``task`` must be a module-level function (Ray workers import it by name). Joins the cluster at ``address``
    (``"auto"``, ``"ray://head:10001"``, ...) or starts a local Ray when None; a Ray already initialised by the
    caller is used as it is and left running.

    Raises:
        ValueError: Ray is not installed (the message says how to install it).
    """
    try:
        import ray
    except ImportError:
        raise ValueError("--backend ray: Ray is not installed; pip install 'murk[ray]'") from None
    started = False
    if not ray.is_initialized():
        ray.init(address=address, log_to_driver=False, include_dashboard=False)
        started = True
    try:
        remote = ray.remote(num_cpus=1, max_retries=2)(task)
        pending = [remote.remote(*args) for args in calls]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                on_result(ray.get(ref))
    finally:
        if started:
            ray.shutdown()
