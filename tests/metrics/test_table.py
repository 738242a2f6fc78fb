"""The metric table (murk.metrics.table): every row loads, the default sets are the columns murk has always
written (in that order), refusals, and adding a metric is one row plus its function: a toy metric registered
that way is scored by ``murk eval`` (by default and picked with --metrics) and ``murk compare``."""

from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_underwater_dir
from murk.io import read_image
from murk.metrics import table
from murk.metrics.table import Metric

runner = CliRunner()


def mean_red(image: np.ndarray, *, data_range: float) -> float:
    """The toy metric: the mean of the red channel as a share of the data range."""
    return float(np.asarray(image, np.float64)[..., 0].mean() / data_range)


@pytest.fixture
def toy() -> Iterator[Metric]:
    row = table.register(
        Metric("mean_red", f"{__name__}:mean_red", "mean red", better="higher", data_range="native", help="toy")
    )
    yield row
    table.unregister("mean_red")


@pytest.fixture
def folder(tmp_path: Path) -> Path:
    d = tmp_path / "imgs"
    d.mkdir()
    for rel in ("suim/n_l_52_.jpg", "funie_euvp/3.jpg"):
        shutil.copy(sample_underwater_dir() / rel, d / Path(rel).name)
    return d


def test_importing_the_table_imports_no_metric() -> None:
    code = "import sys, murk.metrics.table; print(sorted(m for m in ('numpy', 'cv2', 'torch') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_package_names_are_imported_on_first_use() -> None:
    import murk.metrics as mm

    assert sorted(mm.__all__) == sorted(mm._LAZY)
    import murk.metrics.uciqe  # noqa: F401  (a submodule named like its function)
    from murk.metrics import uciqe

    assert callable(uciqe) and uciqe.__module__ == "murk.metrics.uciqe"
    assert all(callable(getattr(mm, n)) or getattr(mm, n) is not None for n in mm.__all__)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        mm.nope  # noqa: B018


@pytest.mark.parametrize("row", table.metrics(), ids=lambda m: m.name)
def test_every_row_loads_its_functions(row: Metric) -> None:
    assert callable(row.load())
    if row.torch_function is not None:
        assert callable(row.load(torch=True))
    assert row.heading.startswith(row.label) and row.sign in (1.0, -1.0)


def test_the_default_sets_are_the_columns_murk_has_always_written() -> None:
    from murk.metrics import DEPTH_ERROR_NAMES, MEASURE_KEYS

    assert table.names("none", default=True) == ("uiqm", "uicm", "uism", "uiconm", "uciqe", "sigma_c", "con_l", "mu_s")
    assert table.names("reference", default=True) == ("psnr", "ssim", "ciede2000")
    assert table.names("input", default=True) == MEASURE_KEYS
    assert table.names("depth", default=True) == DEPTH_ERROR_NAMES
    assert "abs_rel_median" in DEPTH_ERROR_NAMES
    assert table.names("snow_pair") == ("snow_residue", "snow_sites_left", "snow_free_gms", "snow_colour_residue")
    assert table.names(default=False) == ("affine_psnr",)
    assert table.get("affine_psnr").needs == "reference" and table.get("ciede2000").better == "lower"


def test_compute_calls_each_function_once_with_its_settings() -> None:
    from murk.metrics import uiqm

    img = read_image(sample_underwater_dir() / "suim" / "n_l_52_.jpg")[0]
    rows = [table.get("uicm"), table.get("uiqm")]
    got = table.compute(rows, img, data_range=255.0, settings={"uiqm": {"preset": "funie"}})
    ref = uiqm(img, data_range=255.0, preset="funie")
    assert got == {"uicm": ref.uicm, "uiqm": ref.uiqm}


def test_refusals() -> None:
    with pytest.raises(ValueError, match=r"metric: unknown 'psnrr' \(did you mean 'psnr'\?\)"):
        table.get("psnrr")
    with pytest.raises(ValueError, match="metrics: expected at least one metric name"):
        table.pick(" , ")
    with pytest.raises(ValueError, match="metric 'psnr': already in the table"):
        table.register(Metric("psnr", "m:f", "PSNR"))
    with pytest.raises(ValueError, match="a built-in row cannot be removed"):
        table.unregister("psnr")
    with pytest.raises(TypeError, match="metric: expected a Metric, got str"):
        table.register("psnr")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="function: expected 'module:function', got 'f'"):
        Metric("x", "f", "x")
    with pytest.raises(ValueError, match="needs: expected one of none, reference"):
        Metric("x", "m:f", "x", needs="ref")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="better: expected 'higher', 'lower' or None"):
        Metric("x", "m:f", "x", better="up")  # type: ignore[arg-type]


def test_a_toy_metric_is_one_row_plus_its_function_in_eval(toy: Metric, folder: Path, tmp_path: Path) -> None:
    listed = runner.invoke(app, ["eval", "--list-metrics"])
    assert listed.exit_code == 0 and "mean_red" in listed.stdout and "abs_rel_median" in listed.stdout
    res = runner.invoke(
        app, ["eval", str(folder), "--json", str(tmp_path / "e.json"), "--csv", str(tmp_path / "e.csv")]
    )
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "e.json").read_text())
    for row in doc["images"]:
        rgb = read_image(folder / row["file"])[0]
        assert row["mean_red"] == pytest.approx(rgb[..., 0].mean() / 255.0, abs=1e-12)
        assert list(row)[1:10] == ["uiqm", "uicm", "uism", "uiconm", "uciqe", "sigma_c", "con_l", "mu_s", "mean_red"]
    assert doc["summary"]["images"]["mean_red"]["n"] == 2
    with (tmp_path / "e.csv").open() as f:
        assert "mean_red" in next(csv.reader(f))
    # picked alone: only its column; a metric that needs a reference is refused without --ref
    res = runner.invoke(app, ["eval", str(folder), "--metrics", "mean_red", "--json", str(tmp_path / "p.json")])
    assert res.exit_code == 0, res.output
    picked = json.loads((tmp_path / "p.json").read_text())
    assert picked["metrics"] == ["mean_red"] and set(picked["images"][0]) == {"file", "mean_red", "warnings"}
    res = runner.invoke(app, ["eval", str(folder), "--metrics", "mean_red,psnr"])
    assert res.exit_code == 2 and "--metrics psnr: needs --ref" in res.output


def test_a_toy_metric_is_scored_by_compare(toy: Metric, folder: Path, tmp_path: Path) -> None:
    methods = ["--method", "raw", "--method", "greyworld"]
    res = runner.invoke(app, ["compare", str(folder), *methods, "--out", str(tmp_path / "rep")])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    raw = [r for r in doc["rows"] if r["method"] == "raw"]
    for row in raw:
        rgb = read_image(Path(row["path"]))[0]
        assert row["mean_red"] == pytest.approx(rgb[..., 0].mean() / 255.0, abs=1e-6)  # scored in [0, 1]
    assert doc["summary"]["greyworld"]["mean_red"]["n"] == 2
    with (tmp_path / "rep" / "metrics.csv").open() as f:
        assert "mean_red" in next(csv.reader(f))
