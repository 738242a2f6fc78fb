"""murk compare --ref: full-reference columns per image and method, paired differences to raw, --max-side."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import numpy as np
from typer.testing import CliRunner

from murk.cli.main import app
from murk.metrics import ciede2000, psnr
from murk.report.compare import run_compare
from murk.report.methods import parse_method

runner = CliRunner()


def _pair(root: Path, stem: str, seed: int, size: tuple[int, int] = (48, 64)) -> None:
    rng = np.random.default_rng(seed)
    ref = cv2.GaussianBlur((rng.random((*size, 3)) * 255).astype(np.uint8), (0, 0), 2.0)
    hazy = (0.5 * ref + np.array([20, 90, 80])).astype(np.uint8)  # a green veil over the reference
    (root / "input").mkdir(parents=True, exist_ok=True)
    (root / "reference").mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(root / "input" / f"{stem}.png"), hazy)
    cv2.imwrite(str(root / "reference" / f"{stem}.png"), ref)


def test_rows_hold_reference_scores_and_paired_differences(tmp_path: Path) -> None:
    for i in range(3):
        _pair(tmp_path, f"im{i}", i)
    images = sorted((tmp_path / "input").iterdir())
    methods = [parse_method(s) for s in ("raw", "greyworld")]
    res = run_compare(images, methods, tmp_path / "out", ref_dir=tmp_path / "reference")
    raw = [r for r in res.rows if r["method"] == "raw"]
    gw = [r for r in res.rows if r["method"] == "greyworld"]
    ref0 = cv2.imread(str(tmp_path / "reference" / "im0.png"))[:, :, ::-1].astype(np.float32) / 255
    in0 = cv2.imread(str(tmp_path / "input" / "im0.png"))[:, :, ::-1].astype(np.float32) / 255
    assert raw[0]["psnr"] == psnr(in0, ref0, data_range=1.0)
    assert raw[0]["ciede2000"] == ciede2000(in0, ref0, data_range=1.0)
    assert all(r["d_psnr"] == 0.0 for r in raw)
    for g, r in zip(gw, raw, strict=True):
        assert g["d_psnr"] == g["psnr"] - r["psnr"]
        assert g["d_ciede2000"] == g["ciede2000"] - r["ciede2000"]
    s = res.summary["greyworld"]
    assert s["d_psnr"]["n"] == 3 and s["d_psnr"]["better"] == sum(g["d_psnr"] > 0 for g in gw)
    assert s["psnr"]["mean"] == np.mean([g["psnr"] for g in gw])
    header = next(csv.reader((tmp_path / "out" / "metrics.csv").open()))
    assert {"psnr", "ssim", "ciede2000", "d_psnr", "d_ssim", "d_ciede2000"} <= set(header)
    doc = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert "d_ciede2000" in doc["summary"]["raw"]
    assert "&Delta;PSNR vs raw" in (tmp_path / "out" / "report.html").read_text()


def test_missing_or_mismatched_reference_is_one_error_record_each(tmp_path: Path) -> None:
    _pair(tmp_path, "good", 0)
    _pair(tmp_path, "small", 1)
    cv2.imwrite(str(tmp_path / "reference" / "small.png"), np.zeros((10, 10, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "input" / "lonely.png"), np.zeros((10, 10, 3), np.uint8))
    images = sorted((tmp_path / "input").iterdir())
    res = run_compare(images, [parse_method("raw")], tmp_path / "out", ref_dir=tmp_path / "reference")
    assert res.processed == 1 and res.exit_code == 1
    errors = {Path(e["input"]).stem: e["error"] for e in res.errors}
    assert "no image with stem 'lonely' in --ref" in errors["lonely"]
    assert "a full-reference score needs the same size" in errors["small"]


def test_max_side_downscales_input_and_reference(tmp_path: Path) -> None:
    _pair(tmp_path, "big", 0, size=(120, 160))
    images = [tmp_path / "input" / "big.png"]
    res = run_compare(images, [parse_method("raw")], tmp_path / "out", ref_dir=tmp_path / "reference", max_side=40)
    full = run_compare(images, [parse_method("raw")], tmp_path / "out2", ref_dir=tmp_path / "reference")
    assert res.processed == 1 and res.rows[0]["psnr"] != full.rows[0]["psnr"]


def test_cli_prints_the_full_reference_table(tmp_path: Path) -> None:
    _pair(tmp_path, "a", 0)
    r = runner.invoke(
        app,
        [
            "compare",
            str(tmp_path / "input"),
            "--ref",
            str(tmp_path / "reference"),
            "--method",
            "raw",
            "--method",
            "greyworld+clahe",
            "--out",
            str(tmp_path / "out"),
            "--max-side",
            "32",
        ],
    )
    assert r.exit_code == 0, r.output
    assert "dPSNR vs raw" in r.output and "greyworld+clahe" in r.output
