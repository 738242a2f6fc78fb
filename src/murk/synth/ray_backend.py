"""``murk synth --format webdataset --backend ray``: the shards of a synthesis run as Ray tasks.

One Ray task per tar shard runs exactly the local backend's work (:func:`murk.synth.shards.build_shard`: the
same per-sample seeds, rendering, PNG encoding and tar writing), so the bytes equal a local run's. Each task
writes its shard atomically into the output folder, which must therefore be on a file system that every node
of the cluster mounts (as must the inputs and the particle bank); the driver appends each finished shard to the
progress log as the task returns, so a killed driver loses nothing already finished and a rerun resumes.

Why tasks and not Ray Data: the unit of resume and of output is a shard, and a task per shard maps onto it
directly; Ray Data would add pyarrow blocks and its own ordering for no gain here. Install with
``pip install 'murk[ray]'`` on every node (the same murk, numpy and OpenCV versions everywhere: PNG bytes and
floating-point results depend on them).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from murk.synth.config import SynthConfig

_BANKS: dict[str, Any] = {}


def ray_available() -> bool:
    """True when Ray can be imported."""
    try:
        import ray  # noqa: F401
    except ImportError:
        return False
    return True


def _build(plan: Any, config: SynthConfig, out_dir: str, bank_path: str | None) -> Any:
    """The body of one Ray task: the particle bank is loaded once per Ray worker process."""
    import cv2

    from murk.synth.shards import build_shard

    cv2.setNumThreads(1)
    bank = None
    if bank_path:
        if bank_path not in _BANKS:
            from murk.snow.bank import load_bank

            _BANKS[bank_path] = load_bank(bank_path)
        bank = _BANKS[bank_path]
    return build_shard(plan, config, out_dir, bank)


def build_shards_ray(
    plans: Sequence[Any],
    config: SynthConfig,
    out_dir: str,
    bank_path: str | None,
    *,
    address: str | None = None,
    on_result: Callable[[Any], None],
) -> None:
    """Build ``plans`` as Ray tasks (one CPU each) and call ``on_result`` with each result as it finishes.

    Joins the cluster at ``address`` (``"auto"``, ``"ray://head:10001"``, ...) or starts a local Ray when None;
    a Ray already initialised by the caller is used as it is and left running.

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
        task = ray.remote(num_cpus=1, max_retries=2)(_build)
        pending = [task.remote(p, config, out_dir, bank_path) for p in plans]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            for ref in done:
                on_result(ray.get(ref))
    finally:
        if started:
            ray.shutdown()
