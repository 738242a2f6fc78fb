"""``murk synth --format webdataset --backend ray`` writes the same bytes as the local backend (issue 19).

Runs a local Ray with 2 CPUs (a few seconds); skipped where Ray is not installed (CI installs the dev extras,
not the heavy ``murk[ray]`` extra).
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from murk.io import discover
from murk.synth.common import Shard
from murk.synth.config import SynthConfig
from murk.synth.shards import write_shards

pytest.importorskip("webdataset", reason="the webdataset package is needed for --format webdataset")
ray = pytest.importorskip("ray", reason="Ray is not installed (pip install 'murk[ray]'); the Ray backend is untested")


@pytest.fixture(scope="module")
def local_ray() -> Iterator[None]:
    src = str(Path(__file__).resolve().parents[2] / "src")
    path = os.pathsep.join(p for p in (src, os.environ.get("PYTHONPATH", "")) if p)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, runtime_env={"env_vars": {"PYTHONPATH": path}})
    yield
    ray.shutdown()


def _digest(folder: Path) -> dict[str, str]:
    files = [*sorted((folder / "shards").iterdir()), folder / "index.json"]
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def test_ray_backend_equals_local(local_ray: None, small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    cfg = SynthConfig(variants=3)
    write_shards(sources, tmp_path / "local", cfg, samples_per_shard=2)
    job = write_shards(sources, tmp_path / "ray", cfg, samples_per_shard=2, backend="ray")
    assert (job.processed, job.failed) == (6, 0)
    assert _digest(tmp_path / "ray") == _digest(tmp_path / "local")
    # a Ray run resumes a folder partly written by a local array task, and skips what is done
    write_shards(sources, tmp_path / "mixed", cfg, samples_per_shard=2, shard=Shard(0, 2))
    job = write_shards(sources, tmp_path / "mixed", cfg, samples_per_shard=2, backend="ray")
    assert (job.processed, job.skipped) == (2, 4)
    assert _digest(tmp_path / "mixed") == _digest(tmp_path / "local")
