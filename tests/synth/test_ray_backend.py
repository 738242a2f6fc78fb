"""The Ray backend's driver (``murk.synth.ray_backend.run_ray_tasks``) with a stand-in for Ray, so that CI, which
does not install ``murk[ray]``, still checks how ``write_shards(backend="ray")`` uses it: tasks are module-level
functions with picklable arguments (Ray ships both to its workers), results come back out of order, and the
bytes equal the local backend's. ``tests/synth/test_shards_ray.py`` runs a real local Ray where one is installed.
"""

from __future__ import annotations

import hashlib
import pickle
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from murk.data import default_snow_bank
from murk.io import discover
from murk.synth.config import SynthConfig
from murk.synth.ray_backend import run_ray_tasks
from murk.synth.shards import build_shard_task, write_shards

pytest.importorskip("webdataset", reason="the webdataset package is needed for --format webdataset")


class _Ref:
    def __init__(self, thunk: Callable[[], Any]) -> None:
        self.thunk = thunk


class FakeRay:
    """What run_ray_tasks uses of Ray: init/shutdown, remote (pickling the task and its arguments as Ray does),
    wait (finishing the LAST pending task first) and get."""

    def __init__(self, initialised: bool = False) -> None:
        self.initialised = initialised
        self.inits: list[dict[str, Any]] = []
        self.options: list[dict[str, Any]] = []
        self.shutdowns = 0

    def is_initialized(self) -> bool:
        return self.initialised

    def init(self, **kwargs: Any) -> None:
        self.inits.append(kwargs)
        self.initialised = True

    def shutdown(self) -> None:
        self.shutdowns += 1
        self.initialised = False

    def remote(self, **options: Any) -> Callable[[Callable[..., Any]], Any]:
        self.options.append(options)

        def wrap(fn: Callable[..., Any]) -> Any:
            task = pickle.loads(pickle.dumps(fn))  # a module-level function pickles by name; a closure fails here

            class Remote:
                @staticmethod
                def remote(*args: Any) -> _Ref:
                    shipped = pickle.loads(pickle.dumps(args))
                    return _Ref(lambda: task(*shipped))

            return Remote

        return wrap

    def wait(self, pending: list[_Ref], num_returns: int = 1) -> tuple[list[_Ref], list[_Ref]]:
        assert num_returns == 1
        return [pending[-1]], pending[:-1]

    def get(self, ref: _Ref) -> Any:
        return pickle.loads(pickle.dumps(ref.thunk()))


def _digest(folder: Path) -> dict[str, str]:
    files = [*sorted((folder / "shards").iterdir()), folder / "index.json"]
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def test_ray_backend_writes_the_local_bytes(small_rgbd: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    sources, _ = discover(small_rgbd)
    cfg = SynthConfig(variants=3, stages=("basic", "marine_snow"))  # the bank is loaded inside the task
    bank = str(default_snow_bank())
    write_shards(sources, tmp_path / "local", cfg, samples_per_shard=2, bank_path=bank)
    ray = FakeRay()
    monkeypatch.setitem(sys.modules, "ray", ray)
    seen: list[int] = []
    job = write_shards(
        sources,
        tmp_path / "ray",
        cfg,
        samples_per_shard=2,
        bank_path=bank,
        backend="ray",
        ray_address="auto",
        on_progress=lambda done, total: seen.append(done),
    )
    assert (job.processed, job.failed) == (6, 0)
    assert _digest(tmp_path / "ray") == _digest(tmp_path / "local")
    assert seen == [0, 1, 2, 3]  # 3 shards of 2 samples, reported as each task returns
    assert ray.inits == [{"address": "auto", "log_to_driver": False, "include_dashboard": False}]
    assert ray.options == [{"num_cpus": 1, "max_retries": 2}]
    assert ray.shutdowns == 1 and not ray.initialised  # a Ray it started is stopped


def test_run_ray_tasks_leaves_a_running_ray_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    ray = FakeRay(initialised=True)
    monkeypatch.setitem(sys.modules, "ray", ray)
    got: list[Any] = []
    run_ray_tasks(divmod, [(7, 2), (9, 4), (5, 5)], on_result=got.append)
    assert got == [(1, 0), (2, 1), (3, 1)]  # finished last-first by the stand-in
    assert ray.inits == [] and ray.shutdowns == 0 and ray.initialised


def test_run_ray_tasks_without_ray_says_how_to_install(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray raises ImportError
    with pytest.raises(ValueError, match=r"Ray is not installed; pip install 'murk\[ray\]'"):
        run_ray_tasks(build_shard_task, [], on_result=print)
