"""``murk synth --format webdataset``: tar shards, index, determinism across workers/partitions, resume (issue 19)."""

from __future__ import annotations

import hashlib
import json
import tarfile
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from murk._config import merge
from murk.cli.main import app
from murk.io import discover, read_jsonl
from murk.io.atomic import TMP_PREFIX
from murk.io.jobs import read_errors
from murk.synth import shards as shards_mod
from murk.synth.common import Shard
from murk.synth.config import SynthConfig
from murk.synth.shards import plan_shards, sample_key, write_shards

pytest.importorskip("webdataset", reason="the webdataset package is needed for --format webdataset")

CFG = SynthConfig(variants=3)


def _digest(folder: Path) -> dict[str, str]:
    """sha256 of the shards and index.json (not config.yaml: it records --workers; not the progress logs)."""
    files = [*sorted((folder / "shards").iterdir()), folder / "index.json"]
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


def test_layout_members_index_and_json(small_rgbd: Path, tmp_path: Path) -> None:
    import webdataset as wds

    sources, problems = discover(small_rgbd)
    out = tmp_path / "out"
    job = write_shards(sources, out, CFG, samples_per_shard=4, problems=problems)
    assert (job.processed, job.skipped, job.failed, job.exit_code) == (6, 0, 0, 0)
    assert sorted(p.name for p in (out / "shards").iterdir()) == ["000000.tar", "000001.tar"]
    with tarfile.open(out / "shards" / "000000.tar") as tf:
        members = tf.getmembers()
    names = [m.name for m in members]
    assert names[:4] == ["a_v0.clean.png", "a_v0.degraded.png", "a_v0.depth.png", "a_v0.json"]
    assert len(names) == 16 and {(m.mtime, m.uid, m.gid, m.uname, m.mode) for m in members} == {
        (0, 0, 0, "murk", 0o444)
    }
    index = json.loads((out / "index.json").read_text())
    assert index["complete"] and index["samples"] == 6 and index["samples_per_shard"] == 4
    assert [s["keys"] for s in index["shards"]] == [["a_v0", "a_v1", "a_v2", "b_v0"], ["b_v1", "b_v2"]]
    assert index["pattern"] == "shards/{000000..000001}.tar" and index["config"]["variants"] == 3
    assert "format: webdataset" in (out / "config.yaml").read_text()
    # the standard WebDataset reader sees the samples with every member; the json holds the manifest record
    ds = wds.WebDataset(str(out / index["pattern"]), shardshuffle=False, empty_check=False)
    got = list(ds)
    assert [s["__key__"] for s in got] == ["a_v0", "a_v1", "a_v2", "b_v0", "b_v1", "b_v2"]
    rec = json.loads(got[4]["json"])
    assert (rec["stem"], rec["variant"], rec["degraded"]) == ("b", 1, "b_v1.degraded.png")
    assert {"water_type", "beta", "B_inf", "H", "sigma_max", "seed", "params"} <= set(rec)
    import cv2

    depth = cv2.imdecode(np.frombuffer(got[0]["depth.png"], np.uint8), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and depth.shape == (48, 64)


def test_bytes_do_not_depend_on_workers_or_partitions(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    write_shards(sources, tmp_path / "one", CFG, samples_per_shard=2)
    write_shards(sources, tmp_path / "two", merge(CFG, {"workers": 2}), samples_per_shard=2)
    for i in (1, 0):  # two array tasks into one folder, in either order
        job = write_shards(sources, tmp_path / "parts", CFG, samples_per_shard=2, shard=Shard(i, 2))
        assert job.processed == (2 if i == 1 else 4)
    ref = _digest(tmp_path / "one")
    assert len(ref) == 4  # 3 shards + index
    assert _digest(tmp_path / "two") == ref
    assert _digest(tmp_path / "parts") == ref
    # the loose-file pipeline renders the same images (same seeds, same parameters)
    import webdataset as wds

    from murk.io import read_rgb

    sample = next(iter(wds.WebDataset(str(tmp_path / "one/shards/000001.tar"), shardshuffle=False)))
    assert sample["__key__"] == "a_v2"
    from murk.synth.runner import run_synthesis

    run_synthesis(sources[:1], tmp_path / "loose", CFG)
    import cv2

    arr = cv2.imdecode(np.frombuffer(sample["degraded.png"], np.uint8), cv2.IMREAD_COLOR)[:, :, ::-1]
    assert np.array_equal(arr, np.round(read_rgb(tmp_path / "loose/degraded/a_v2.png") * 255).astype(np.uint8))


def test_resume_after_a_kill_keeps_finished_shards_and_redoes_the_partial_one(
    small_rgbd: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    sources, _ = discover(small_rgbd)
    write_shards(sources, tmp_path / "ref", CFG, samples_per_shard=2)
    out = tmp_path / "out"
    real = shards_mod.render_source_samples
    calls = {"n": 0}

    def dies_on_the_third_source(*args, **kwargs):  # shard 0 = a_v0,a_v1; shard 1 = a_v2 (done), b_v0 (killed)
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt("killed")
        return real(*args, **kwargs)

    monkeypatch.setattr(shards_mod, "render_source_samples", dies_on_the_third_source)
    with pytest.raises(KeyboardInterrupt):
        write_shards(sources, out, CFG, samples_per_shard=2)
    monkeypatch.setattr(shards_mod, "render_source_samples", real)
    assert sorted(p.name for p in (out / "shards").iterdir()) == ["000000.tar"]  # nothing half-written
    (out / "shards" / f"{TMP_PREFIX}abc-000001.tar").write_bytes(b"half a tar")  # as a SIGKILL would leave
    first = (out / "shards" / "000000.tar").stat()
    job = write_shards(sources, out, CFG, samples_per_shard=2)
    assert (job.processed, job.skipped) == (4, 2)
    again = (out / "shards" / "000000.tar").stat()
    assert (again.st_ino, again.st_mtime_ns) == (first.st_ino, first.st_mtime_ns)  # never rewritten
    assert not [p for p in out.rglob(f"{TMP_PREFIX}*")]
    assert _digest(out) == _digest(tmp_path / "ref")
    job = write_shards(sources, out, CFG, samples_per_shard=2)
    assert (job.processed, job.skipped) == (0, 6)
    # a deleted (or truncated) shard is built again, identically
    (out / "shards" / "000002.tar").write_bytes(b"truncated")
    assert write_shards(sources, out, CFG, samples_per_shard=2).processed == 2
    assert _digest(out) == _digest(tmp_path / "ref")


def test_failed_input_is_recorded_and_its_shard_redone(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    good = (small_rgbd / "rgb" / "b.png").read_bytes()
    (small_rgbd / "rgb" / "b.png").write_bytes(b"not a png")
    out = tmp_path / "out"
    job = write_shards(sources, out, CFG, samples_per_shard=4)
    assert (job.processed, job.failed, job.exit_code) == (3, 3, 1)  # a_v0..a_v2 written; b's 3 variants failed
    errs = read_errors(out / "errors.jsonl")
    assert [(Path(e.input).name, e.stage, e.variant) for e in errs] == [("b.png", "read", k) for k in range(3)]
    index = json.loads((out / "index.json").read_text())
    assert not index["complete"] and index["shards"] == []  # both shards miss a sample of b: not finished
    with tarfile.open(out / "shards" / "000000.tar") as tf:
        assert len(tf.getnames()) == 12  # what worked is kept in the file (3 samples x 4 members)
    (small_rgbd / "rgb" / "b.png").write_bytes(good)
    job = write_shards(sources, out, CFG, samples_per_shard=4)
    assert (job.processed, job.skipped, job.failed) == (6, 0, 0) and not (out / "errors.jsonl").exists()
    assert json.loads((out / "index.json").read_text())["samples"] == 6


def test_refusals(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    write_shards(sources, tmp_path / "out", CFG, samples_per_shard=2)
    with pytest.raises(ValueError, match="--samples-per-shard 2, got 3"):
        write_shards(sources, tmp_path / "out", CFG, samples_per_shard=3)
    with pytest.raises(ValueError, match="different configuration"):
        write_shards(sources, tmp_path / "out", merge(CFG, {"seed": 1}), samples_per_shard=2)
    with pytest.raises(ValueError, match="samples-per-shard: expected an integer >= 1"):
        plan_shards(sources, 3, 0)
    with pytest.raises(ValueError, match="--backend: expected 'local' or 'ray'"):
        write_shards(sources, tmp_path / "x", CFG, samples_per_shard=2, backend="spark")  # type: ignore[arg-type]
    from murk.synth.runner import run_synthesis

    run_synthesis(sources, tmp_path / "loose", CFG)
    with pytest.raises(ValueError, match="loose-file dataset"):
        write_shards(sources, tmp_path / "loose", CFG, samples_per_shard=2)
    assert sample_key("img.001", 2) == "img_001_v2"
    from murk.io.pairs import RGBDSource

    twins = [RGBDSource("x.1", "r/x.1.png", "d/x.1.png"), RGBDSource("x_1", "r/x_1.png", "d/x_1.png")]
    with pytest.raises(ValueError, match="same shard key"):
        plan_shards(twins, 1, 2)


def test_cli_writes_shards_and_refuses_ray_for_files(small_rgbd: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    out = tmp_path / "out"
    args = ["synth", str(small_rgbd), str(out), "--variants", "2", "--format", "webdataset"]
    r = runner.invoke(app, [*args, "--samples-per-shard", "3", "--shard", "1/2"])
    assert r.exit_code == 0, r.output
    assert "1 sample processed" in r.output and "shard 1/2" in r.output  # 4 samples: shard 1 holds the last
    assert [p.name for p in (out / "shards").iterdir()] == ["000001.tar"]
    r = runner.invoke(app, [*args, "--samples-per-shard", "3"])
    assert r.exit_code == 0 and "3 samples processed, 1 skipped" in r.output, r.output
    assert json.loads((out / "index.json").read_text())["complete"]
    assert read_jsonl(next((out / ".murk").glob("shards-all.jsonl")))[0]["shard"] == "000000.tar"
    r = runner.invoke(app, ["synth", str(small_rgbd), str(tmp_path / "o2"), "--backend", "ray"])
    assert r.exit_code == 2 and "need --format webdataset" in r.output


def test_full_disk_stops_with_the_shard_named_and_nothing_partial(
    small_rgbd: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import errno

    import webdataset as wds

    from murk.errors import OutputError

    sources, _ = discover(small_rgbd)
    real = wds.TarWriter.write
    calls = {"n": 0}

    def full_after_five_samples(self, obj):
        calls["n"] += 1
        if calls["n"] > 5:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real(self, obj)

    monkeypatch.setattr(wds.TarWriter, "write", full_after_five_samples)
    with pytest.raises(OutputError, match=r"000001\.tar: no space left on device"):
        write_shards(sources, tmp_path / "out", CFG, samples_per_shard=4)
    monkeypatch.setattr(wds.TarWriter, "write", real)
    assert [p.name for p in (tmp_path / "out" / "shards").iterdir()] == ["000000.tar"]
    job = write_shards(sources, tmp_path / "out", CFG, samples_per_shard=4)
    assert (job.processed, job.skipped) == (2, 4)


def test_slurm_array_variables_pick_the_shards(small_rgbd: Path, tmp_path: Path) -> None:
    env = {"SLURM_ARRAY_TASK_ID": "11", "SLURM_ARRAY_TASK_MIN": "10", "SLURM_ARRAY_TASK_COUNT": "3"}
    out = tmp_path / "out"
    args = ["synth", str(small_rgbd), str(out), "--variants", "3", "--format", "webdataset", "--samples-per-shard"]
    r = CliRunner().invoke(app, [*args, "1"], env=env)
    assert r.exit_code == 0 and "shard 1/3" in r.output, r.output
    assert [p.name for p in sorted((out / "shards").iterdir())] == ["000001.tar", "000004.tar"]
