from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_underwater_dir
from murk.io import read_rgb
from murk.metrics import uciqe, uiqm
from murk.report.compare import run_compare, summarise
from murk.report.figures import Box, auto_boxes, comparison_grid, parse_box
from murk.report.methods import parse_method

runner = CliRunner()


@pytest.fixture
def three_images(tmp_path: Path) -> Path:
    d = tmp_path / "real"
    d.mkdir()
    for name in ("suim/d_r_47_.jpg", "funie_euvp/16.jpg", "ufen_gan/Lake.jpg"):
        shutil.copy(sample_underwater_dir() / name, d / Path(name).name)
    return d


def test_parse_method() -> None:
    m = parse_method("retrained+post=jointid+post:runs/x/best.pt?precision=bf16,tile=512")
    assert (m.label, m.method, m.checkpoint) == ("retrained+post", "jointid+post", "runs/x/best.pt")
    assert dict(m.options) == {"precision": "bf16", "tile": 512}
    assert parse_method("post").label == "post" and parse_method("jointid:runs/abc/best.pt").label == "jointid:abc"
    with pytest.raises(ValueError, match="Joint-ID needs weights"):
        parse_method("jointid+post")
    with pytest.raises(ValueError, match="expected KEY=VALUE options"):
        parse_method("post?he")


def test_compare_outputs_are_consistent(three_images: Path, tmp_path: Path) -> None:
    images = sorted(three_images.iterdir())
    methods = [parse_method("raw"), parse_method("post")]
    res = run_compare(images, methods, tmp_path / "rep")
    out = tmp_path / "rep"
    assert len(res.rows) == 6 and not res.errors
    # CSV, JSON and the in-memory rows agree
    with open(out / "metrics.csv") as f:
        csv_rows = list(csv.DictReader(f))
    doc = json.loads((out / "metrics.json").read_text())
    assert [(r["image"], r["method"]) for r in csv_rows] == [(r["image"], r["method"]) for r in doc["rows"]]
    for c, j in zip(csv_rows, doc["rows"], strict=True):
        assert float(c["uiqm"]) == pytest.approx(j["uiqm"], abs=1e-6)
    # the raw rows are the metrics of the input images themselves
    raw_lake = next(r for r in doc["rows"] if r["method"] == "raw" and r["image"] == "Lake.jpg")
    img = read_rgb(three_images / "Lake.jpg")
    assert raw_lake["uiqm"] == pytest.approx(uiqm(img, data_range=1.0).uiqm, rel=1e-9)
    assert raw_lake["uciqe"] == pytest.approx(uciqe(img, data_range=1.0).uciqe, rel=1e-9)
    # the summary is the mean and population std of the rows
    post_uiqm = np.array([r["uiqm"] for r in doc["rows"] if r["method"] == "post"])
    assert doc["summary"]["post"]["uiqm"]["mean"] == pytest.approx(post_uiqm.mean())
    assert doc["summary"]["post"]["uiqm"]["std"] == pytest.approx(post_uiqm.std())
    assert doc["summary"]["post"]["uiqm"]["mean"] > doc["summary"]["raw"]["uiqm"]["mean"]  # HE+LoG raises UIQM
    # the HTML has the summary table, one grid per image, and embeds everything
    html = (out / "report.html").read_text()
    assert html.count("<section>") == 3 and html.count('src="data:image/jpeg;base64,') == 3
    assert 'id="summary"' in html and "http://" not in html.replace("http://www.w3.org/2000/svg", "")
    assert sorted(p.name for p in (out / "grids").iterdir()) == ["16.jpg", "Lake.jpg", "d_r_47_.jpg"]


def test_compare_cli_partial_failure_and_boxes(three_images: Path, tmp_path: Path) -> None:
    (three_images / "broken.png").write_bytes(b"no")
    r = runner.invoke(
        app,
        [
            "compare",
            str(three_images),
            "--method",
            "raw",
            "--method",
            "clahe=post?he=clahe",
            "--out",
            str(tmp_path / "rep"),
            "--box",
            "10,10,40,40",
            "--save-outputs",
        ],
    )
    assert r.exit_code == 1, r.output
    assert "broken.png" in r.output and (tmp_path / "rep" / "errors.jsonl").exists()
    assert len(list((tmp_path / "rep" / "restored" / "clahe").iterdir())) == 3
    doc = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert {r["method"] for r in doc["rows"]} == {"raw", "clahe"}
    r = runner.invoke(
        app, ["compare", str(three_images), "--method", "raw", "--out", str(tmp_path / "r2"), "--box", "1,2"]
    )
    assert r.exit_code == 2 and "--box: expected x,y,w,h" in r.output
    r = runner.invoke(
        app, ["compare", str(three_images), "--method", "raw", "--method", "raw", "--out", str(tmp_path / "r3")]
    )
    assert r.exit_code == 2 and "labels must be unique" in r.output


def test_auto_boxes_find_structure_and_snow() -> None:
    img = np.full((120, 160, 3), 0.3, np.float32)
    img[20:60, 100:130] = 0.9  # a bright block (structure) at the top right
    g = np.random.default_rng(0)
    for _ in range(40):  # small bright dots at the bottom left
        y, x = g.integers(80, 115), g.integers(5, 50)
        img[y : y + 2, x : x + 2] = 1.0
    structure, snow = auto_boxes(img)
    assert (structure.kind, snow.kind) == ("structure", "snow")
    assert structure.x + structure.w > 95 and structure.y < 60
    assert snow.x < 60 and snow.y + snow.h > 80


def test_grid_layout() -> None:
    imgs = [np.zeros((100, 200, 3), np.float32), np.ones((100, 200, 3), np.float32)]
    grid = comparison_grid(imgs, ["a", "b"], [Box(0, 0, 50, 50), Box(100, 50, 50, 50)], panel_width=200)
    assert grid.dtype == np.uint8 and grid.shape[1] == 2 * 200 + 4
    assert grid.shape[0] == 22 + 100 + 100  # label bar, full image, zoom row (two 100-px squares)
    assert parse_box("1,2,30,40") == Box(1, 2, 30, 40)
    assert summarise([], ["x"])["x"]["uiqm"]["n"] == 0
