"""``murk scenes``: output layout, depth encoding, worker independence, resume, errors."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from murk.cli.main import app
from murk.io import discover, load_pair, read_depth, read_rgb
from murk.io.pairs import DepthOptions
from murk.rng import derive_seed
from murk.scenes import render_scene, sample_scene, scene_from_dict

runner = CliRunner()


def _run(*args: str):
    return runner.invoke(app, ["scenes", *args])


def _digest(folder: Path) -> dict[str, bytes]:
    files = sorted((folder / "rgb").iterdir()) + sorted((folder / "depth").iterdir()) + [folder / "scenes.jsonl"]
    return {f.relative_to(folder).as_posix(): f.read_bytes() for f in files}


def test_writes_the_synth_layout(tmp_path: Path) -> None:
    out = tmp_path / "sc"
    res = _run(str(out), "--count", "3", "--size", "64x48", "--seed", "7", "-q")
    assert res.exit_code == 0, res.output
    assert "3 scenes processed" in res.output
    assert sorted(p.name for p in (out / "rgb").iterdir()) == [f"scene_00000{i}.png" for i in range(3)]
    lines = [json.loads(x) for x in (out / "scenes.jsonl").read_text().splitlines()]
    assert [x["index"] for x in lines] == [0, 1, 2]
    assert lines[1]["seed"] == derive_seed(7, 1)
    assert lines[1]["file_name"] == "rgb/scene_000001.png" and lines[1]["depth_file"] == "depth/scene_000001.png"
    assert lines[1]["size"] == [64, 48] and lines[1]["intrinsics"]["cx"] == 31.5
    assert "not z-depth" in lines[1]["depth"]
    settings = yaml.safe_load((out / "scenes_config.yaml").read_text())
    assert settings["seed"] == 7 and settings["scene_config"]["far_m"] == 15.0 and "murk_version" in settings
    # The depth PNG is uint16 millimetres of the renderer's distance; the RGB the 8-bit image.
    params = scene_from_dict(lines[1]["scene"])
    assert params == sample_scene(derive_seed(7, 1))
    rgb, dist = render_scene(params, (64, 48))
    raw = cv2.imread(str(out / "depth" / "scene_000001.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16
    np.testing.assert_array_equal(raw, np.rint(dist.astype(np.float64) * 1000).astype(np.uint16))
    np.testing.assert_allclose(read_rgb(out / "rgb" / "scene_000001.png"), rgb, atol=0.5 / 255 + 1e-6)
    # murk synth reads it as a clean RGB-D folder.
    sources, problems = discover(out)
    assert len(sources) == 3 and problems == []
    clean, depth_m, valid = load_pair(sources[0], DepthOptions())
    assert clean.shape == (48, 64, 3) and valid.all() and depth_m.min() >= 0.3 and depth_m.max() <= 15.0
    assert read_depth(out / "depth" / "scene_000002.png").max() <= 15.0


def test_workers_do_not_change_the_bytes_and_resume_skips(tmp_path: Path) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    assert _run(str(a), "-n", "4", "--size", "40x30", "--seed", "3", "-q").exit_code == 0
    res = _run(str(b), "-n", "4", "--size", "40x30", "--seed", "3", "--workers", "2", "-q")
    assert res.exit_code == 0, res.output
    assert _digest(a) == _digest(b)
    # Resume: a deleted depth map is re-rendered, the rest is skipped; the result is byte-identical.
    (b / "depth" / "scene_000002.png").unlink()
    (b / "rgb" / "scene_000003.png").write_bytes(b"stale but present")
    res = _run(str(b), "-n", "4", "--size", "40x30", "--seed", "3", "-q")
    assert res.exit_code == 0 and "1 scene processed, 3 skipped (already done)" in res.output
    assert (b / "rgb" / "scene_000003.png").read_bytes() == b"stale but present"  # skipped, not re-rendered
    assert (b / "depth" / "scene_000002.png").read_bytes() == (a / "depth" / "scene_000002.png").read_bytes()
    # Growing the dataset keeps the first scenes and appends consistent lines.
    res = _run(str(a), "-n", "6", "--size", "40x30", "--seed", "3", "-q")
    assert res.exit_code == 0 and "2 scenes processed, 4 skipped (already done)" in res.output
    assert len((a / "scenes.jsonl").read_text().splitlines()) == 6


def test_config_textures_and_jpeg(tmp_path: Path) -> None:
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text("layouts: [piles]\nhfov_deg: [60, 70]\ntexture_probability: 1.0\n")
    tex = tmp_path / "tex"
    tex.mkdir()
    img = (np.random.default_rng(0).random((64, 80, 3)) * 255).astype(np.uint8)
    cv2.imwrite(str(tex / "rust.png"), img)
    out = tmp_path / "o"
    res = _run(
        str(out), "-n", "2", "--size", "40x30", "--config", str(cfg), "--textures", str(tex), "--rgb-format", "jpg"
    )
    assert res.exit_code == 0, res.output
    assert (out / "rgb" / "scene_000000.jpg").is_file()
    lines = [json.loads(x) for x in (out / "scenes.jsonl").read_text().splitlines()]
    assert all(60 <= x["scene"]["camera"]["hfov_deg"] <= 70 for x in lines)
    assert any(m.get("texture") == "rust.png" for x in lines for m in x["scene"]["materials"])
    settings = yaml.safe_load((out / "scenes_config.yaml").read_text())
    assert settings["textures"] == ["rust.png"] and settings["scene_config"]["layouts"] == ["piles"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--size", "64by48"], "--size: expected WxH"),
        (["--size", "4x48"], "size: expected 8 <= width, height <= 16384"),
        (["--rgb-format", "tif"], "--rgb-format: expected png or jpg"),
        (["--config", "missing.yaml"], "missing.yaml: config file not found"),
        (["--textures", "nowhere"], "nowhere: not a folder"),
    ],
)
def test_usage_errors_exit_2(tmp_path: Path, args: list[str], message: str) -> None:
    res = _run(str(tmp_path / "o"), "-n", "1", *args)
    assert res.exit_code == 2
    assert message in " ".join(res.output.split())


def test_bad_config_values_name_the_file(tmp_path: Path) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text("hfov_deg: [50, 200]\n")
    res = _run(str(tmp_path / "o"), "-n", "1", "--config", str(cfg))
    assert res.exit_code == 2
    assert "c.yaml: hfov_deg[1]: expected a number in [10.0, 150.0]" in " ".join(res.output.split())
    cfg.write_text("- a list\n")
    res = _run(str(tmp_path / "o"), "-n", "1", "--config", str(cfg))
    assert res.exit_code == 2 and "expected a mapping of SceneConfig fields" in res.output


def test_refuses_to_mix_settings(tmp_path: Path) -> None:
    out = tmp_path / "o"
    assert _run(str(out), "-n", "1", "--size", "32x24", "--seed", "1", "-q").exit_code == 0
    res = _run(str(out), "-n", "1", "--size", "32x24", "--seed", "2", "-q")
    assert res.exit_code == 2
    assert "written with different settings (seed)" in " ".join(res.output.split())


def test_a_smaller_count_than_an_earlier_run_says_which_scenes_remain(tmp_path: Path) -> None:
    out = tmp_path / "sc"
    assert runner.invoke(app, ["scenes", str(out), "--count", "4", "--size", "64x48", "-q"]).exit_code == 0
    r = runner.invoke(app, ["scenes", str(out), "--count", "2", "--size", "64x48"])
    assert r.exit_code == 0, r.output
    assert "2 scene(s) of an earlier run with a larger --count remain" in " ".join(r.output.split())
    assert len((out / "scenes.jsonl").read_text().splitlines()) == 2
