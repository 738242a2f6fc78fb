from __future__ import annotations

import hashlib
import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk._config import merge
from murk.data import default_snow_bank
from murk.io import DepthOptions, discover, load_pair, read_jsonl, read_rgb
from murk.io.pairs import RGBDSource
from murk.snow.bank import load_bank
from murk.synth.common import Shard, depth_range_note, fit_size
from murk.synth.config import SynthConfig
from murk.synth.params import variant_from_dict
from murk.synth.render import render
from murk.synth.runner import run_synthesis


def _digest(folder: Path) -> dict[str, str]:
    """sha256 of every data and index file (not the progress logs, not config.yaml which records --workers)."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and ".murk" not in p.parts and p.name != "config.yaml"
    }


CFG = SynthConfig(variants=3)


def test_outputs_layout_and_index_files(small_rgbd: Path, tmp_path: Path) -> None:
    sources, problems = discover(small_rgbd)
    s = run_synthesis(sources, tmp_path / "out", CFG, problems=problems)
    out = tmp_path / "out"
    assert (s.images, s.variants_written, s.variants_skipped, s.failures) == (2, 6, 0, [])
    assert sorted(p.name for p in (out / "degraded").iterdir()) == [f"{st}_v{k}.png" for st in "ab" for k in range(3)]
    assert cv2.imread(str(out / "depth" / "a.png"), cv2.IMREAD_UNCHANGED).dtype == np.uint16
    lines = read_jsonl(out / "manifest.jsonl")
    assert [(r["stem"], r["variant"]) for r in lines] == [(st, k) for st in "ab" for k in range(3)]
    spec_fields = {"water_type", "beta", "B_inf", "D", "H", "d_near", "sigma0", "k", "gamma", "sigma_max", "seed"}
    assert spec_fields <= set(lines[0])
    train = (out / "train.txt").read_text().splitlines()
    assert train[0] == "degraded/a_v0.png clean/a.png depth/a.png 1000"
    meta = read_jsonl(out / "metadata.jsonl")
    assert meta[0]["file_name"] == "degraded/a_v0.png" and meta[0]["water_type"] == lines[0]["water_type"]
    assert "seed: 0" in (out / "config.yaml").read_text() and "murk_version" in (out / "config.yaml").read_text()
    assert not (out / "errors.jsonl").exists()


def test_manifest_line_re_renders_the_same_bytes(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    run_synthesis(sources, tmp_path, CFG)
    rec = read_jsonl(tmp_path / "manifest.jsonl")[4]  # b_v1
    rgb, depth, _ = load_pair(sources[1], DepthOptions())
    again = render(rgb, depth, variant_from_dict(rec["params"]))
    written = read_rgb(tmp_path / rec["degraded"])
    assert np.abs(written - again.degraded).max() <= 0.5 / 255 + 1e-6
    assert rec["sigma_max"] == pytest.approx(again.sigma_max_px)


def test_workers_and_interruption_do_not_change_bytes(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    run_synthesis(sources, tmp_path / "one", CFG)
    run_synthesis(sources, tmp_path / "two", merge(CFG, {"workers": 2}))
    assert _digest(tmp_path / "one") == _digest(tmp_path / "two")
    # "interrupted": only image a was done, a stale temporary was left behind; the rerun finishes the job
    run_synthesis(sources[:1], tmp_path / "resumed", CFG)
    (tmp_path / "resumed" / "degraded" / ".murk-tmp-abc-b_v0.png").write_bytes(b"half")
    s = run_synthesis(sources, tmp_path / "resumed", CFG)
    assert (s.variants_written, s.variants_skipped) == (3, 3)
    assert _digest(tmp_path / "one") == _digest(tmp_path / "resumed")
    # a deleted output is regenerated identically
    (tmp_path / "resumed" / "degraded" / "a_v2.png").unlink()
    s = run_synthesis(sources, tmp_path / "resumed", CFG)
    assert s.variants_written == 1 and _digest(tmp_path / "one") == _digest(tmp_path / "resumed")


def test_shards_cover_everything_once(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    run_synthesis(sources, tmp_path / "full", CFG)
    for i in range(2):
        run_synthesis(sources, tmp_path / "sharded", CFG, shard=Shard(i, 2))
    assert _digest(tmp_path / "full") == _digest(tmp_path / "sharded")


def test_shard_parsing() -> None:
    assert Shard.parse("1/4") == Shard(1, 4)
    assert Shard.parse(
        None, env={"SLURM_ARRAY_TASK_ID": "5", "SLURM_ARRAY_TASK_COUNT": "4", "SLURM_ARRAY_TASK_MIN": "3"}
    ) == Shard(2, 4)
    assert Shard.parse(None, env={}) == Shard(0, 1)
    with pytest.raises(ValueError, match="--shard: expected i/N"):
        Shard.parse("2-4")
    with pytest.raises(ValueError, match="shard: expected 0 <= i < N"):
        Shard.parse("4/4")
    with pytest.raises(ValueError, match=r"SLURM_ARRAY_TASK_ID: expected an integer .* got 'abc'"):
        Shard.parse(None, env={"SLURM_ARRAY_TASK_ID": "abc", "SLURM_ARRAY_TASK_COUNT": "4"})
    with pytest.raises(ValueError, match="SLURM array variables: shard: expected 0 <= i < N"):
        Shard.parse(None, env={"SLURM_ARRAY_TASK_ID": "9", "SLURM_ARRAY_TASK_COUNT": "4"})


def test_bad_inputs_are_recorded_and_the_rest_continues(small_rgbd: Path, tmp_path: Path) -> None:
    (small_rgbd / "rgb" / "c.png").write_bytes(b"garbage")
    cv2.imwrite(str(small_rgbd / "depth" / "c.png"), np.ones((48, 64), np.uint16))
    cv2.imwrite(str(small_rgbd / "rgb" / "d.png"), np.zeros((10, 10, 3), np.uint8))
    cv2.imwrite(str(small_rgbd / "depth" / "d.png"), np.ones((12, 12), np.uint16))
    cv2.imwrite(str(small_rgbd / "rgb" / "e.png"), np.zeros((10, 10, 3), np.uint8))  # no depth
    sources, problems = discover(small_rgbd)
    s = run_synthesis(sources, tmp_path, CFG, problems=problems)
    assert s.variants_written == 6 and len(s.failures) == 3
    errs = {Path(e["input"]).name: e["error"] for e in read_jsonl(tmp_path / "errors.jsonl")}
    assert "cannot decode image" in errs["c.png"]
    assert "does not match depth" in errs["d.png"]
    assert "no depth file with stem 'e'" in errs["e.png"]


def test_changed_config_is_refused(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    run_synthesis(sources, tmp_path, CFG)
    with pytest.raises(ValueError, match=r"different configuration \(differs in: medium\)"):
        run_synthesis(sources, tmp_path, merge(CFG, {"medium": {"water_types": ["I"]}}))
    run_synthesis(sources, tmp_path, merge(CFG, {"workers": 2}))  # workers do not matter


def test_a_folder_made_before_an_option_existed_still_resumes(small_rgbd: Path, tmp_path: Path) -> None:
    import yaml

    sources, _ = discover(small_rgbd)
    run_synthesis(sources, tmp_path, CFG)
    written = yaml.safe_load((tmp_path / "config.yaml").read_text())
    del written["medium"]["illuminant"], written["input"]["depth_from"]  # as an older murk wrote it
    (tmp_path / "config.yaml").write_text(yaml.safe_dump(written))
    run_synthesis(sources, tmp_path, CFG)  # the defaults of the new options reproduce what it did: accepted
    with pytest.raises(ValueError, match=r"differs in: medium"):
        run_synthesis(sources, tmp_path, merge(CFG, {"medium": {"illuminant": [0.0, 1.0]}}))


def test_marine_snow_outputs(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    cfg = merge(
        CFG,
        {
            "stages": ["basic", "forward_scatter", "marine_snow"],
            "variants": 1,
            "marine_snow": {"n_particles": [50, 60]},
        },
    )
    run_synthesis(sources, tmp_path, cfg, bank_path=str(default_snow_bank()))
    rec = read_jsonl(tmp_path / "manifest.jsonl")[0]
    assert 50 <= rec["N_p"] <= 60 and rec["s"] == [0.3, 0.6] and 0.2 <= rec["rho"] <= 1.0
    assert rec["bank_id"] == load_bank(default_snow_bank()).bank_id
    alpha = cv2.imread(str(tmp_path / rec["snow_alpha"]), cv2.IMREAD_UNCHANGED)
    assert alpha.dtype == np.uint8 and alpha.shape == (48, 64) and alpha.max() > 0
    with pytest.raises(ValueError, match="marine_snow needs a particle bank"):
        run_synthesis(sources, tmp_path / "x", cfg)


def test_fit_size_crops_to_aspect_then_resizes() -> None:
    rgb = np.zeros((100, 200, 3), np.float32)
    rgb[:, 50:150] = 1.0  # the centre square survives a crop to 1:1
    depth = np.ones((100, 200), np.float32)
    r, d, v = fit_size(rgb, depth, np.ones((100, 200), bool), (50, 50))
    assert r.shape == (50, 50, 3) and d.shape == (50, 50) and v.all()
    assert r.min() == pytest.approx(1.0)


def test_relative_depth_and_size_via_config(tmp_path: Path) -> None:
    root = tmp_path / "in"
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    cv2.imwrite(str(root / "rgb" / "x.jpg"), np.full((40, 60, 3), 128, np.uint8))
    cv2.imwrite(str(root / "depth" / "x.png"), np.tile(np.arange(60, dtype=np.uint8) * 4, (40, 1)))
    sources, _ = discover(root)
    cfg = merge(CFG, {"variants": 1, "input": {"depth_relative": True, "size": [30, 30]}})
    run_synthesis(sources, tmp_path / "out", cfg)
    out = read_rgb(tmp_path / "out" / "degraded" / "x_v0.png")
    assert out.shape == (30, 30, 3)
    rec = json.loads((tmp_path / "out" / "manifest.jsonl").read_text().splitlines()[0])
    assert rec["width"] == 30 and rec["dist_max_m"] == pytest.approx(rec["H"], rel=1e-5)


def test_the_depth_warning_uses_the_exact_median() -> None:
    """The median behind the implausible-depth warning (a partial sort, so that workers skip numpy.ma's import)
    is numpy's, for odd and even sizes: 20 m is plausible, the mean of the two middle values 20.05 m is not."""
    src = RGBDSource(stem="x", rgb_path="x.png", depth_path="x_depth.png")
    assert depth_range_note(src, np.array([0.5, 20.0, 20.1, 30.0], np.float32)) is not None  # median 20.05
    assert depth_range_note(src, np.array([0.5, 19.9, 20.1, 30.0], np.float32)) is None  # median 20.0
    assert depth_range_note(src, np.array([30.0, 0.5, 20.0], np.float32)) is None  # median 20.0
    assert depth_range_note(src, np.array([30.0, 0.5, 21.0], np.float32)) is not None


def test_photographs_without_depth_get_the_layout_prior_through_murk_synth(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from typer.testing import CliRunner

    from murk.cli.main import app
    from murk.io.pairs import layout_depth

    photos = tmp_path / "photos"
    photos.mkdir()
    g = np.random.default_rng(0)
    for name in ("quay.png", "wall.jpg"):
        cv2.imwrite(str(photos / name), (g.random((36, 48, 3)) * 255).astype(np.uint8))
    monkeypatch.chdir(tmp_path)  # relative paths below the working folder: no depth file makes "." an input
    r = CliRunner().invoke(app, ["synth", "photos", "out", "--depth-from", "layout", "--variants", "2", "-q"])
    assert r.exit_code == 0, r.output
    records = read_jsonl(tmp_path / "out" / "manifest.jsonl")
    assert sorted(rec["stem"] for rec in records) == ["quay", "quay", "wall", "wall"]
    assert all(rec["depth_from"] == "layout" for rec in records)
    from murk.train.data import PairDataset, items_from_synth_folder

    items = items_from_synth_folder(tmp_path / "out")
    assert all(it.depth_path == "" for it in items)  # the prior is no depth target for a network
    assert float(PairDataset(items, (32, 32))[0]["depth"].abs().sum()) == 0.0
    written = cv2.imread(str(tmp_path / "out" / "depth" / "quay.png"), cv2.IMREAD_UNCHANGED).astype(np.float32)
    np.testing.assert_allclose(written / 1000.0, layout_depth("quay", 36, 48, 0), atol=6e-4)  # uint16 mm
    refused = CliRunner().invoke(app, ["synth", str(photos), str(tmp_path / "o2"), "-q"])
    assert refused.exit_code != 0 and "depth" in refused.output  # without the flag a depth/ folder is expected
    lst = tmp_path / "pairs.txt"
    lst.write_text("quay.png quay.png\n")
    r = CliRunner().invoke(app, ["synth", "--list", str(lst), str(tmp_path / "o3"), "--depth-from", "layout", "-q"])
    assert r.exit_code == 2 and "give RGBD_DIR, not --list" in r.output
