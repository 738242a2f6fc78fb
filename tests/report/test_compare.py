from __future__ import annotations

import csv
import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_underwater_dir
from murk.enhance import restorer as restorer_registry
from murk.enhance.restorer import Restored, Restorer
from murk.io import read_rgb
from murk.io.images import to_float, to_uint
from murk.metrics import FLAG_NAMES, MEASURE_KEYS, restoration_measures, uciqe, uiqm
from murk.report.compare import metric_keys, run_compare, summarise
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
    shipped = parse_method("jointid+post")  # no checkpoint: the weights shipped with murk
    assert (shipped.label, shipped.method, shipped.checkpoint) == ("jointid+post", "jointid+post", None)
    with pytest.raises(ValueError, match="expected KEY=VALUE options"):
        parse_method("post?he")
    with pytest.raises(ValueError, match="trust_checkpoint cannot be set inside a method spec"):
        parse_method("jointid:file.pt?trust_checkpoint=true")  # trust only from the explicit flag or API


def test_method_spec_options_are_checked_against_the_method() -> None:
    from murk.report.methods import build_restorer

    shared = {"device": "cpu", "precision": "fp32", "tile": None, "policy": "native", "trust_checkpoint": False}
    post = build_restorer(parse_method("clahe=post?he=clahe,clahe_clip=3,lam=0.9"), **shared)
    assert (post.params.he, post.params.clahe_clip, post.params.lam) == ("clahe", 3.0, 0.9)
    with pytest.raises(ValueError, match=r"unknown option 'lamda' \(did you mean 'lam'\?\); options of post: "):
        build_restorer(parse_method("post?lamda=0.9"), **shared)
    with pytest.raises(ValueError, match=r"method post: unknown option 'checkpoint'"):
        build_restorer(parse_method("post:weights.pt"), **shared)  # post has no weights
    with pytest.raises(ValueError, match=r"raw \(the input itself\) takes no checkpoint or options"):
        build_restorer(parse_method("raw?lam=0.9"))


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
    # restoration measures: identity values for raw, restoration_measures(input, output) for post
    assert set(MEASURE_KEYS) <= set(metric_keys()) and set(MEASURE_KEYS) <= set(csv_rows[0])
    for r in (r for r in doc["rows"] if r["method"] == "raw"):
        assert r["structure_gms"] == 1.0 and r["artefact_periodic_ratio"] == 1.0 and r["contrast_ratio"] == 1.0
        assert r["particle_residue_ratio"] == 1.0 and r["flags"] == ""
    post_lake = next(r for r in doc["rows"] if r["method"] == "post" and r["image"] == "Lake.jpg")
    from murk.report.methods import build_restorer

    restored = np.clip(build_restorer(parse_method("post")).restore(img[None]).images[0], 0.0, 1.0)
    delivered = to_float(to_uint(restored, 8))  # scored as written: at the input's 8 bits
    expected = restoration_measures(img, delivered)
    for k in MEASURE_KEYS:
        assert post_lake[k] == pytest.approx(expected[k], rel=1e-9, abs=1e-12), k
    assert post_lake["contrast_ratio"] > 1.1  # HE stretches the hazy lake image
    gms = np.array([r["structure_gms"] for r in doc["rows"] if r["method"] == "post"])
    assert doc["summary"]["post"]["structure_gms"]["mean"] == pytest.approx(gms.mean())
    # flags: joined names in the rows and the CSV, counted per method in the summary
    for c, j in zip(csv_rows, doc["rows"], strict=True):
        assert c["flags"] == j["flags"]
    post_flags = [r["flags"] for r in doc["rows"] if r["method"] == "post"]
    assert doc["summary"]["post"]["flags"]["n"] == 3
    assert doc["summary"]["post"]["flags"]["flagged"] == sum(bool(f) for f in post_flags)
    assert doc["summary"]["raw"]["flags"] == {"flagged": 0, "n": 3, **dict.fromkeys(FLAG_NAMES, 0)}
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
    assert summarise([], ["x"])["x"]["flags"]["flagged"] == 0


class _Checkerboard(Restorer):
    """A destroyed output: the input plus a period-2 checkerboard (what a broken pixel-shuffle produces)."""

    name = "checkerboard"

    def restore(self, images: np.ndarray) -> Restored:
        yy, xx = np.mgrid[0 : images.shape[1], 0 : images.shape[2]]
        board = np.float32(0.06) * (2.0 * ((yy + xx) % 2) - 1.0)[None, :, :, None]
        return Restored(np.clip(images + board, 0.0, 1.0).astype(np.float32))


def test_compare_flags_a_destroyed_method(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    restorer_registry.available()  # load the built-in methods first
    monkeypatch.setitem(restorer_registry._REGISTRY, "checkerboard", lambda: _Checkerboard())
    images = [sample_underwater_dir() / "suim" / "n_l_52_.jpg", sample_underwater_dir() / "funie_euvp" / "3.jpg"]
    res = run_compare(images, [parse_method("raw"), parse_method("broken=checkerboard")], tmp_path / "rep")
    assert not res.errors
    broken = [r for r in res.rows if r["method"] == "broken"]
    assert len(broken) == 2
    for r in broken:
        raw = next(x for x in res.rows if x["method"] == "raw" and x["image"] == r["image"])
        assert r["uiqm"] > raw["uiqm"]  # UIQM is fooled ...
        assert r["artefact_periodic_ratio"] > 10.0 and "artefacts" in r["flags"].split("; ")  # ... the flags are not
    assert res.summary["broken"]["flags"]["flagged"] == 2 and res.summary["broken"]["flags"]["artefacts"] == 2
    assert res.summary["raw"]["flags"]["flagged"] == 0
    html = (tmp_path / "rep" / "report.html").read_text()
    summary_rows = re.findall(r'<tr class="([^"]*)"><td class="l">(raw|broken)</td><td class="l"><code>', html)
    assert dict((lab, cls.split()) for cls, lab in summary_rows) == {"raw": [], "broken": ["best", "flagged"]}
    assert "2/2 flagged: artefacts 2" in html
    per_image = re.findall(r'<tr class="(flagged|)"><td class="l">(raw|broken)</td><td>', html)
    assert sorted(per_image) == [("", "raw"), ("", "raw"), ("flagged", "broken"), ("flagged", "broken")]
    with open(tmp_path / "rep" / "metrics.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["flags"] != "" for r in rows] == [r["method"] == "broken" for r in rows]


def test_same_stem_in_two_folders_gives_two_grids(tmp_path: Path) -> None:
    """a/x.jpg and b/x.jpg no longer overwrite each other's grid (issue 13)."""
    from murk.report.compare import output_names

    for sub, name in (("a", "suim/d_r_47_.jpg"), ("b", "funie_euvp/16.jpg")):
        (tmp_path / "in" / sub).mkdir(parents=True)
        shutil.copy(sample_underwater_dir() / name, tmp_path / "in" / sub / "x.jpg")
    images = [tmp_path / "in" / "a" / "x.jpg", tmp_path / "in" / "b" / "x.jpg"]
    res = run_compare(images, [parse_method("raw")], tmp_path / "out", save_outputs=True)
    assert not res.errors and len(res.rows) == 2
    assert sorted(p.name for p in (tmp_path / "out" / "grids").iterdir()) == ["a_x.jpg", "b_x.jpg"]
    assert len(list((tmp_path / "out" / "restored" / "raw").iterdir())) == 2
    assert output_names([Path("p/x.jpg"), Path("p/x.png"), Path("p/y.jpg")]) == {
        Path("p/x.jpg"): "p_x_jpg",
        Path("p/x.png"): "p_x_png",
        Path("p/y.jpg"): "y",
    }


def test_scores_are_those_of_the_written_output(tmp_path: Path) -> None:
    """compare scores each output at the input's bit depth, as `murk enhance` writes it: `murk eval` of the
    saved file gives the same UIQM and UCIQE (scoring the float output was 1-2 % off)."""
    (tmp_path / "in").mkdir()
    shutil.copy(sample_underwater_dir() / "suim" / "d_r_47_.jpg", tmp_path / "in" / "x.jpg")
    res = run_compare([tmp_path / "in" / "x.jpg"], [parse_method("post")], tmp_path / "out", save_outputs=True)
    (row,) = res.rows
    saved = read_rgb(tmp_path / "out" / "restored" / "post" / "x.png")
    assert row["uiqm"] == pytest.approx(uiqm(saved, data_range=1.0).uiqm, abs=1e-9)
    assert row["uciqe"] == pytest.approx(uciqe(saved, data_range=1.0).uciqe, abs=1e-9)


def _snow_pair(folder: Path, seed: int, hw: tuple[int, int], count: int, half_px: int) -> Path:
    """``folder/snowy/s.png`` and ``folder/clean/s.png``: a smooth 8-bit scene with and without ``count`` bright
    squares of side ``2 half_px + 1``; returns the snowy file."""
    import cv2

    rng = np.random.default_rng(seed)
    h, w = hw
    clean = (cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 4) * 0.5 + 0.2).astype(np.float32)
    snowy = clean.copy()
    for y, x in rng.integers(half_px + 3, min(h, w) - half_px - 3, (count, 2)):
        snowy[y - half_px : y + half_px + 1, x - half_px : x + half_px + 1] += 0.35
    for sub, img in (("snowy", snowy), ("clean", clean)):
        (folder / sub).mkdir()
        cv2.imwrite(str(folder / sub / "s.png"), cv2.cvtColor(to_uint(np.clip(img, 0, 1), 8), cv2.COLOR_RGB2BGR))
    return folder / "snowy" / "s.png"


def test_snow_pairs_add_the_luma_and_colour_residues(tmp_path: Path) -> None:
    snowy = _snow_pair(tmp_path, 5, (60, 80), 12, 1)
    res = run_compare([snowy], [parse_method("raw")], tmp_path / "rep", snow_clean=tmp_path / "clean")
    (row,) = res.rows
    assert row["snow_residue"] == pytest.approx(1.0) and row["snow_colour_residue"] == pytest.approx(1.0)
    assert res.summary["raw"]["snow_colour_residue"]["mean"] == pytest.approx(1.0)


def test_the_identity_scores_the_identity_values_after_a_max_side_resize(tmp_path: Path) -> None:
    snowy = _snow_pair(tmp_path, 6, (150, 200), 20, 2)
    res = run_compare(
        [snowy], [parse_method("raw")], tmp_path / "rep", snow_clean=tmp_path / "clean", max_side=97
    )  # the 97-px copy was scored unrounded against the rounded output: GMS 0.97-0.99, "particles not removed"
    (row,) = res.rows
    assert row["flags"] == "" and row["structure_gms"] == pytest.approx(1.0) and row["particle_residue_ratio"] == 1.0
    assert row["snow_residue"] == pytest.approx(1.0)
