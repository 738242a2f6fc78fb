"""``murk eval``: tables, CSV/JSON outputs, presets, references, depth, failures and usage errors.

Provenance: expected numbers come from the public API on the same files (pinned elsewhere) or, for the
``--preset funie`` check, from ``tests/data/metrics_reference.json`` (the original FUnIE code's output).
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_underwater_dir
from murk.io import read_depth, read_image, to_float
from murk.metrics import (
    MEASURE_KEYS,
    depth_errors,
    flags,
    pil_bicubic_resize,
    psnr,
    restoration_measures,
    ssim,
    uciqe,
    uiqm,
)

from .metrics_refdata import records

runner = CliRunner()
SAMPLES = ("suim/n_l_52_.jpg", "funie_euvp/3.jpg")


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    d = tmp_path / "imgs"
    d.mkdir()
    for rel in SAMPLES:
        shutil.copy(sample_underwater_dir() / rel, d / Path(rel).name)
    return d


def _run(*args: str) -> Any:
    return runner.invoke(app, ["eval", *args])


def _err(res: Any) -> str:
    """stderr with rich's line wrapping undone."""
    return " ".join(res.stderr.split())


def test_folder_table_json_csv(folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    res = _run(str(folder), "--json", str(out / "r.json"), "--csv", str(out / "r.csv"))
    assert res.exit_code == 0, res.output
    assert "n_l_52_.jpg" in res.stdout and "mean" in res.stdout and "std" in res.stdout
    doc = json.loads((out / "r.json").read_text())
    assert (doc["uiqm_preset"], doc["uciqe_preset"]) == ("panetta2016", "uciqe_m")
    assert [r["file"] for r in doc["images"]] == ["3.jpg", "n_l_52_.jpg"]
    values = []
    for row in doc["images"]:
        rgb, _ = read_image(folder / row["file"])
        q, c = uiqm(rgb, data_range=255), uciqe(rgb, data_range=255)
        assert row["uiqm"] == pytest.approx(q.uiqm, rel=1e-12)
        assert row["uiconm"] == pytest.approx(q.uiconm, rel=1e-12)
        assert row["uciqe"] == pytest.approx(c.uciqe, rel=1e-12)
        values.append(q.uiqm)
    assert doc["summary"]["images"]["uiqm"]["mean"] == pytest.approx(np.mean(values), rel=1e-12)
    assert doc["summary"]["images"]["uiqm"]["std"] == pytest.approx(np.std(values), rel=1e-12)
    assert doc["errors"] == [] and not (out / "errors.jsonl").exists()
    rows = list(csv.DictReader((out / "r.csv").open()))
    assert [r["file"] for r in rows] == ["3.jpg", "n_l_52_.jpg"]
    assert float(rows[1]["uism"]) == pytest.approx(doc["images"][1]["uism"], rel=1e-12)


def test_preset_funie_reproduces_the_original_code(folder: Path, tmp_path: Path) -> None:
    ref = next(r for r in records("uiqm", "funie_py3") if r["image"].endswith("n_l_52_.jpg") and r["size"] == "native")
    res = _run(
        str(folder / "n_l_52_.jpg"), "--preset", "funie", "--preset", "cielab_raw", "--json", str(tmp_path / "r.json")
    )
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "r.json").read_text())
    assert (doc["uiqm_preset"], doc["uciqe_preset"]) == ("funie", "cielab_raw")
    assert abs(doc["images"][0]["uiqm"] - ref["value"]) <= 1e-4
    assert doc["images"][0]["uciqe"] > 5  # raw CIELAB units


def test_resize_like_measure_uiqm(folder: Path, tmp_path: Path) -> None:
    res = _run(str(folder / "3.jpg"), "--resize", "256x200", "--json", str(tmp_path / "r.json"))
    assert res.exit_code == 0, res.output
    rgb, _ = read_image(folder / "3.jpg")
    expected = uiqm(pil_bicubic_resize(rgb, (256, 200)), data_range=255).uiqm
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["resize"] == [256, 200]
    assert doc["images"][0]["uiqm"] == pytest.approx(expected, rel=1e-12)


def test_reference_folder_adds_psnr_ssim(folder: Path, tmp_path: Path) -> None:
    refs = tmp_path / "refs"
    refs.mkdir()
    shutil.copy(folder / "3.jpg", refs / "3.jpg")  # identical: PSNR inf, SSIM 1
    rgb, _ = read_image(folder / "n_l_52_.jpg")
    other = np.clip(rgb.astype(np.int16) + 9, 0, 255).astype(np.uint8)
    cv2.imwrite(str(refs / "n_l_52_.png"), other[:, :, ::-1])  # matched by stem, another suffix
    res = _run(str(folder), "--ref", str(refs), "--json", str(tmp_path / "r.json"), "--csv", str(tmp_path / "r.csv"))
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "r.json").read_text())
    same, diff = doc["images"]
    assert same["psnr"] == "inf" and same["ssim"] == pytest.approx(1.0)
    assert diff["psnr"] == pytest.approx(psnr(to_float(rgb), to_float(other), data_range=1.0), rel=1e-12)
    assert diff["ssim"] == pytest.approx(ssim(to_float(rgb), to_float(other), data_range=1.0), rel=1e-12)
    assert doc["summary"]["images"]["psnr"]["n_inf"] == 1
    assert doc["summary"]["images"]["psnr"]["mean"] == pytest.approx(diff["psnr"])
    assert "inf" in res.stdout


def test_input_folder_adds_restoration_measures_and_flags(folder: Path, tmp_path: Path) -> None:
    """--input pairs each scored (restored) image with its raw input by stem: measures, flags, summary."""
    restored = tmp_path / "restored"
    restored.mkdir()
    shutil.copy(folder / "3.jpg", restored / "3.jpg")  # unchanged: identity values, no flag
    raw, _ = read_image(folder / "n_l_52_.jpg")
    yy, xx = np.mgrid[0 : raw.shape[0], 0 : raw.shape[1]]
    board = np.where((yy + xx) % 2 == 0, 12, -12)[..., None]
    broken = np.clip(raw.astype(np.int16) + board, 0, 255).astype(np.uint8)  # a period-2 checkerboard
    cv2.imwrite(str(restored / "n_l_52_.png"), broken[:, :, ::-1])  # matched by stem, another suffix
    out = tmp_path / "out"
    res = _run(str(restored), "--input", str(folder), "--json", str(out / "r.json"), "--csv", str(out / "r.csv"))
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "r.json").read_text())
    same, bad = doc["images"]
    assert Path(same["input"]).name == "3.jpg" and Path(bad["input"]).name == "n_l_52_.jpg"
    assert same["structure_gms"] == 1.0 and same["artefact_periodic_ratio"] == 1.0 and same["flags"] == ""
    expected = restoration_measures(to_float(raw), to_float(broken))
    for k in MEASURE_KEYS:
        assert bad[k] == pytest.approx(expected[k], rel=1e-9, abs=1e-12), k
    assert bad["artefact_periodic_ratio"] > 10.0 and "artefacts" in flags(expected)
    assert bad["flags"] == "; ".join(flags(expected))
    assert bad["uiqm"] > uiqm(raw, data_range=255).uiqm  # UIQM prefers the destroyed image
    summary = doc["summary"]["images"]
    assert summary["flags"]["flagged"] == 1 and summary["flags"]["n"] == 2 and summary["flags"]["artefacts"] == 1
    assert summary["structure_gms"]["mean"] == pytest.approx((1.0 + bad["structure_gms"]) / 2)
    rows = list(csv.DictReader((out / "r.csv").open()))
    assert [r["flags"] for r in rows] == ["", bad["flags"]]
    assert float(rows[1]["artefact_periodic_ratio"]) == pytest.approx(bad["artefact_periodic_ratio"], rel=1e-12)
    assert "1/2 flagged" in res.stdout and "artefacts" in res.stdout


def test_input_without_match_or_size_is_a_file_failure(folder: Path, tmp_path: Path) -> None:
    raws = tmp_path / "raws"
    raws.mkdir()
    rgb, _ = read_image(folder / "3.jpg")
    cv2.imwrite(str(raws / "3.png"), cv2.resize(rgb, (64, 48))[:, :, ::-1])
    res = _run(str(folder), "--input", str(raws), "--json", str(tmp_path / "r.json"))
    assert res.exit_code == 1
    assert "no raw input image with stem 'n_l_52_' in --input" in _err(res)
    assert "differs from the raw input" in _err(res)
    doc = json.loads((tmp_path / "r.json").read_text())
    assert doc["images"] == [] and len(doc["errors"]) == 2
    res = _run(str(folder), "--json", str(tmp_path / "plain.json"), "--csv", str(tmp_path / "plain.csv"))
    assert res.exit_code == 0
    assert "flags" not in json.loads((tmp_path / "plain.json").read_text())["summary"]["images"]
    header = (tmp_path / "plain.csv").read_text().splitlines()[0].split(",")
    assert "flags" not in header and "input" not in header and "structure_gms" not in header


def test_missing_reference_is_a_file_failure(folder: Path, tmp_path: Path) -> None:
    refs = tmp_path / "refs"
    refs.mkdir()
    shutil.copy(folder / "3.jpg", refs / "3.jpg")
    res = _run(str(folder), "--ref", str(refs))
    assert res.exit_code == 1
    assert "no reference image with stem 'n_l_52_'" in _err(res)


def test_failed_files_exit_1_with_errors_jsonl(folder: Path, tmp_path: Path) -> None:
    (folder / "broken.png").write_bytes(b"not a png")
    out = tmp_path / "out"
    res = _run(str(folder), "--json", str(out / "r.json"))
    assert res.exit_code == 1
    assert "broken.png" in _err(res) and "cannot decode" in _err(res)
    errors = [json.loads(line) for line in (out / "errors.jsonl").read_text().splitlines()]
    assert [(Path(e["input"]).name, e["stage"]) for e in errors] == [("broken.png", "score")]
    doc = json.loads((out / "r.json").read_text())
    assert len(doc["images"]) == 2 and len(doc["errors"]) == 1


def test_failed_files_without_outputs_are_printed_only(folder: Path, tmp_path: Path) -> None:
    (folder / "broken.png").write_bytes(b"not a png")
    res = _run(str(folder))
    assert res.exit_code == 1
    assert "broken.png" in _err(res)
    assert not list(tmp_path.rglob("errors.jsonl"))


def test_warnings_are_reported(tmp_path: Path) -> None:
    cv2.imwrite(str(tmp_path / "gray.png"), np.full((32, 32, 3), 128, np.uint8))
    res = _run(str(tmp_path / "gray.png"), "--preset", "funie", "--json", str(tmp_path / "r.json"))
    assert res.exit_code == 0
    assert "constant" in _err(res)
    doc = json.loads((tmp_path / "r.json").read_text())
    assert any("Sobel rescale" in w for w in doc["images"][0]["warnings"])
    assert doc["images"][0]["uism"] == 0.0


def test_quiet_prints_only_the_summary(folder: Path) -> None:
    res = _run(str(folder), "--quiet")
    assert res.exit_code == 0
    assert "mean" in res.stdout and "n_l_52_.jpg" not in res.stdout


def test_recursive(tmp_path: Path) -> None:
    res = _run(str(sample_underwater_dir()))
    assert res.exit_code == 2 and "--recursive" in _err(res)
    res = _run(str(sample_underwater_dir()), "-r", "--quiet", "--json", str(tmp_path / "r.json"))
    assert res.exit_code == 0
    assert len(json.loads((tmp_path / "r.json").read_text())["images"]) == 13


def _write_depth_mm(path: Path, depth_m: np.ndarray) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.rint(depth_m * 1000).astype(np.uint16))


def test_depth_folders(tmp_path: Path, rng: np.random.Generator) -> None:
    for stem in ("a", "b"):
        gt = rng.uniform(0.5, 12.0, (24, 32))
        _write_depth_mm(tmp_path / "gt" / f"{stem}.png", gt)
        _write_depth_mm(tmp_path / "pred" / f"{stem}.png", gt * rng.uniform(0.8, 1.2, gt.shape))
    _write_depth_mm(tmp_path / "pred" / "c.png", np.ones((24, 32)))  # no ground truth
    res = _run(
        "--depth", str(tmp_path / "pred"), "--depth-ref", str(tmp_path / "gt"), "--json", str(tmp_path / "r.json")
    )
    assert res.exit_code == 1
    assert "no ground-truth depth with stem 'c'" in _err(res)
    doc = json.loads((tmp_path / "r.json").read_text())
    assert [Path(r["file"]).stem for r in doc["depth"]] == ["a", "b"]
    for row in doc["depth"]:
        ref = depth_errors(read_depth(row["file"]), read_depth(row["ref"]))
        assert row["abs_rel"] == pytest.approx(ref.abs_rel, rel=1e-12)
        assert row["d1"] == pytest.approx(ref.d1)
    assert doc["summary"]["depth"]["rmse"]["mean"] == pytest.approx(np.mean([r["rmse"] for r in doc["depth"]]))


def test_depth_single_files(tmp_path: Path) -> None:
    gt = np.linspace(1.0, 9.0, 48).reshape(6, 8)
    _write_depth_mm(tmp_path / "gt.png", gt)
    _write_depth_mm(tmp_path / "pred.png", gt)
    res = _run(
        "--depth", str(tmp_path / "pred.png"), "--depth-ref", str(tmp_path / "gt.png"), "--csv", str(tmp_path / "d.csv")
    )
    assert res.exit_code == 0, res.output
    row = next(csv.DictReader((tmp_path / "d.csv").open()))
    assert float(row["rmse"]) == 0.0 and float(row["d1"]) == 1.0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ([], "nothing to evaluate"),
        (["{folder}", "--preset", "matlab"], "--preset: expected a UIQM preset"),
        (["{folder}", "--preset", "funie", "--preset", "jointid"], "two UIQM presets"),
        (["{folder}", "--resize", "256"], "--resize: expected WxH"),
        (["{folder}", "--ssim-window", "box"], "--ssim-window"),
        (["{folder}/missing.png"], "no such file or folder"),
        (["--depth", "{folder}"], "give both"),
        (["--ref", "{folder}"], "--ref: needs IMAGES"),
        (["{folder}", "--ref", "{folder}/3.jpg"], "expected a folder of reference images"),
        (["--input", "{folder}"], "--input: needs IMAGES"),
        (["{folder}", "--input", "{folder}/3.jpg"], "--input: expected a folder of raw input images"),
    ],
)
def test_usage_errors_exit_2(folder: Path, args: list[str], message: str) -> None:
    res = _run(*(a.format(folder=folder) for a in args))
    assert res.exit_code == 2
    assert message in _err(res)


def test_eval_and_compare_agree_on_the_same_file(folder: Path, tmp_path: Path) -> None:
    """murk eval scores the file (uint8), murk compare its float32 copy ('raw'): the same UIQM/UCIQE (issue 13)."""
    from murk.report.compare import run_compare
    from murk.report.methods import parse_method

    res = _run(str(folder), "--json", str(tmp_path / "e.json"))
    assert res.exit_code == 0, res.output
    ev = {r["file"]: r for r in json.loads((tmp_path / "e.json").read_text())["images"]}
    cmp = run_compare(sorted(folder.iterdir()), [parse_method("raw")], tmp_path / "cmp")
    assert len(cmp.rows) == len(ev) == 2
    for row in cmp.rows:
        assert row["uiqm"] == pytest.approx(ev[row["image"]]["uiqm"], abs=1e-6)
        assert row["uciqe"] == pytest.approx(ev[row["image"]]["uciqe"], abs=1e-6)


def test_depth_stem_shared_by_two_files_is_reported_not_guessed(tmp_path: Path, rng: np.random.Generator) -> None:
    """pred/a.png + pred/a.npy (or the same in --depth-ref): which one is meant is unknown -> recorded error."""
    for stem in ("a", "b"):
        gt = rng.uniform(0.5, 12.0, (24, 32))
        _write_depth_mm(tmp_path / "gt" / f"{stem}.png", gt)
        _write_depth_mm(tmp_path / "pred" / f"{stem}.png", gt)
    np.save(tmp_path / "pred" / "a.npy", np.ones((24, 32), np.float32))
    np.save(tmp_path / "gt" / "b.npy", np.ones((24, 32), np.float32))
    res = _run(
        "--depth", str(tmp_path / "pred"), "--depth-ref", str(tmp_path / "gt"), "--json", str(tmp_path / "r.json")
    )
    assert res.exit_code == 1
    err = _err(res)
    assert "ambiguous stem 'a'" in err and "a.npy" in err and "a.png" in err
    assert "ambiguous stem 'b'" in err and "b.npy" in err
    assert "Traceback" not in res.output
    assert json.loads((tmp_path / "r.json").read_text())["depth"] == []
