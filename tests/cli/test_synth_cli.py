from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from typer.testing import CliRunner

from murk import __version__
from murk.cli.main import app
from murk.data import sample_rgbd_dir
from murk.io import read_jsonl

from ..io._bombs import npy_bomb

runner = CliRunner()


def test_version_and_help() -> None:
    r = runner.invoke(app, ["--version"])
    assert r.exit_code == 0 and r.stdout.strip() == f"murk {__version__}"
    r = runner.invoke(app, ["--help"])
    assert r.exit_code == 0 and "synth" in r.stdout and "snow" in r.stdout


def test_synth_end_to_end_on_the_shipped_pairs(tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = [
        "synth",
        str(sample_rgbd_dir()),
        str(out),
        "--variants",
        "2",
        "--size",
        "160x120",
        "--water-types",
        "I,9C",
        "--stages",
        "basic,forward_scatter,marine_snow",
        "--save-intermediate",
        "-q",
    ]
    r = runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    recs = read_jsonl(out / "manifest.jsonl")
    assert len(recs) == 6 and {r["water_type"] for r in recs} <= {"I", "9C"}
    for sub in ("degraded", "clean", "depth", "snow_alpha", "basic", "transmission"):
        assert any((out / sub).iterdir()), sub
    assert cv2.imread(str(out / "degraded" / "tum_fr1_v1.png")).shape == (120, 160, 3)
    assert "synth: 6 variants processed" in r.output and "3 clean images" in r.output
    r = runner.invoke(app, args)  # resume: nothing left to do
    assert r.exit_code == 0 and "0 variants processed, 6 skipped (already done)" in r.output


def test_synth_config_file_and_cli_override(tmp_path: Path) -> None:
    cfg = tmp_path / "c.yaml"
    cfg.write_text("variants: 3\nmedium:\n  water_types: [II]\ninput:\n  size: [64, 48]\n")
    r = runner.invoke(
        app, ["synth", str(sample_rgbd_dir()), str(tmp_path / "o"), "--config", str(cfg), "--variants", "1"]
    )
    assert r.exit_code == 0, r.output
    recs = read_jsonl(tmp_path / "o" / "manifest.jsonl")
    assert len(recs) == 3 and {x["water_type"] for x in recs} == {"II"}
    assert "variants: 1" in (tmp_path / "o" / "config.yaml").read_text()


def test_synth_list_file(tmp_path: Path) -> None:
    rgbd = sample_rgbd_dir()
    lst = tmp_path / "pairs.txt"
    lst.write_text(f"{rgbd}/rgb/redwood_00000.jpg {rgbd}/depth/redwood_00000.png\n")
    r = runner.invoke(app, ["synth", "--list", str(lst), str(tmp_path / "o"), "--variants", "1", "--size", "64x48"])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "o" / "degraded" / "redwood_00000_v0.png").exists()


def test_synth_partial_failure_exit_code_1(small_rgbd: Path, tmp_path: Path) -> None:
    (small_rgbd / "rgb" / "broken.png").write_bytes(b"nope")
    cv2.imwrite(str(small_rgbd / "depth" / "broken.png"), np.ones((4, 4), np.uint16))
    r = runner.invoke(app, ["synth", str(small_rgbd), str(tmp_path / "o"), "--variants", "1"])
    assert r.exit_code == 1
    assert "1 failed" in r.output and "broken.png: cannot decode image" in r.output
    assert len(read_jsonl(tmp_path / "o" / "errors.jsonl")) == 1


def test_synth_usage_errors_exit_2(tmp_path: Path) -> None:
    r = runner.invoke(app, ["synth", str(tmp_path / "missing"), str(tmp_path / "o")])
    assert r.exit_code == 2 and "missing: not found" in r.output
    r = runner.invoke(app, ["synth", str(sample_rgbd_dir()), str(tmp_path / "o"), "--water-types", "I,12C"])
    assert r.exit_code == 2 and "--water-types: unknown type '12C'" in r.output  # the flag, not the config path
    r = runner.invoke(app, ["synth", str(sample_rgbd_dir()), str(tmp_path / "o"), "--stages", "basic,haze"])
    assert r.exit_code == 2 and "--stages: unknown stage(s) 'haze'" in r.output
    r = runner.invoke(app, ["synth", str(sample_rgbd_dir()), str(tmp_path / "o"), "--size", "big"])
    assert r.exit_code == 2 and "--size: expected WxH" in r.output
    r = runner.invoke(app, ["synth", str(sample_rgbd_dir()), str(tmp_path / "o"), "--size", "16384x16384"])
    assert r.exit_code == 2 and "over the limit of 100,000,000" in " ".join(r.output.split())  # not an OOM later
    r = runner.invoke(app, ["synth", str(tmp_path)])
    assert r.exit_code == 2 and "expected RGBD_DIR OUT_DIR" in r.output
    r = runner.invoke(app, ["synth", str(sample_rgbd_dir()), str(tmp_path / "o"), "--invalid-depth", "fail"])
    assert r.exit_code == 1 and "invalid depth pixels" in r.output  # Redwood/TUM have holes


def test_synth_warns_about_implausible_depth_and_explains_unpaired_files(small_rgbd: Path, tmp_path: Path) -> None:
    r = runner.invoke(app, ["synth", str(small_rgbd), str(tmp_path / "o"), "--variants", "1", "--depth-scale", "10"])
    assert r.exit_code == 0 and "median depth" in r.output and "is implausible" in r.output
    bad = tmp_path / "bad"
    (bad / "rgb").mkdir(parents=True)
    (bad / "depth").mkdir()
    cv2.imwrite(str(bad / "rgb" / "x.png"), np.zeros((4, 4, 3), np.uint8))
    cv2.imwrite(str(bad / "depth" / "y.png"), np.ones((4, 4), np.uint16))
    r = runner.invoke(app, ["synth", str(bad), str(tmp_path / "o2")])
    assert r.exit_code == 2 and "no RGB-D pairs found" in r.output and "no depth file with stem 'x'" in r.output


def test_synth_config_yaml_of_an_output_reproduces_it_byte_for_byte(tmp_path: Path) -> None:
    """`murk synth IN OUT2 --config OUT1/config.yaml` writes the same files as the run that made OUT1 (issue 13)."""
    a, b = tmp_path / "a", tmp_path / "b"
    args = ["--variants", "2", "--size", "96x72", "--water-types", "3C,IB", "--seed", "11", "-q"]
    args += ["--stages", "basic,forward_scatter,marine_snow"]
    r = runner.invoke(app, ["synth", str(sample_rgbd_dir()), str(a), *args])
    assert r.exit_code == 0, r.output
    r = runner.invoke(app, ["synth", str(sample_rgbd_dir()), str(b), "--config", str(a / "config.yaml"), "-q"])
    assert r.exit_code == 0, r.output
    files = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
    assert len(files) > 10 and files == sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
    for rel in files:
        assert (a / rel).read_bytes() == (b / rel).read_bytes(), rel


def test_synth_refused_inputs_fail_their_pair_only(small_rgbd: Path, tmp_path: Path) -> None:
    """Issue 13: a .npy bomb, a truncated .npy and two RGB files sharing a stem are recorded in errors.jsonl
    with the file and the problem; the good pairs are written, the exit code is 1, there is no traceback."""
    rgb, depth = small_rgbd / "rgb", small_rgbd / "depth"
    for stem in ("bomb", "short"):
        cv2.imwrite(str(rgb / f"{stem}.png"), np.zeros((48, 64, 3), np.uint8))
    npy_bomb(depth / "bomb.npy")
    npy_bomb(depth / "short.npy", (48, 64), "<f4", data=b"\x00" * 100)
    cv2.imwrite(str(rgb / "dup.png"), np.zeros((48, 64, 3), np.uint8))
    cv2.imwrite(str(rgb / "dup.jpg"), np.zeros((48, 64, 3), np.uint8))
    cv2.imwrite(str(depth / "dup.png"), np.ones((48, 64), np.uint16))
    out = tmp_path / "o"
    r = runner.invoke(app, ["synth", str(small_rgbd), str(out), "--variants", "1"])
    assert r.exit_code == 1, r.output
    assert "Traceback" not in r.output and isinstance(r.exception, SystemExit)
    errors = {Path(e["input"]).name: e["error"] for e in read_jsonl(out / "errors.jsonl")}
    assert set(errors) == {"bomb.png", "short.png", "dup.jpg"}
    assert "bomb.npy: declares float64 (100000, 100000) = 10,000,000,000 elements, over" in errors["bomb.png"]
    assert "short.npy: truncated: the header declares float32 (48, 64) = 12,288 bytes" in errors["short.png"]
    assert f"ambiguous stem 'dup': {rgb / 'dup.jpg'}, {rgb / 'dup.png'} share it" in errors["dup.jpg"]
    assert sorted(p.name for p in (out / "degraded").iterdir()) == ["a_v0.png", "b_v0.png"]
    assert "3 failed" in r.output


def test_synth_with_no_unambiguous_pair_is_a_usage_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad"
    (bad / "rgb").mkdir(parents=True)
    (bad / "depth").mkdir()
    for name in ("x.png", "x.jpg"):
        cv2.imwrite(str(bad / "rgb" / name), np.zeros((4, 4, 3), np.uint8))
    cv2.imwrite(str(bad / "depth" / "x.png"), np.ones((4, 4), np.uint16))
    r = runner.invoke(app, ["synth", str(bad), str(tmp_path / "o")])
    text = " ".join(r.output.split())
    assert r.exit_code == 2 and "no RGB-D pairs found" in text and "ambiguous stem 'x'" in text
    assert "Traceback" not in r.output


def test_a_snow_bank_without_the_marine_snow_stage_is_noted_as_unused(tmp_path: Path) -> None:
    from murk.data import default_snow_bank

    args = ["synth", str(sample_rgbd_dir()), str(tmp_path / "o"), "--stages", "basic", "--variants", "1"]
    r = runner.invoke(app, [*args, "--size", "64x48", "--snow-bank", str(default_snow_bank())])
    assert r.exit_code == 0, r.output
    assert "was not used: marine_snow is not among the stages" in " ".join(r.output.split())
