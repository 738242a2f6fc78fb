"""benchmarks/bench_arms.py ``--probe``: a file's own methods become arms; the probes of benchmarks/probes/ load,
declare their options and are listed in their README; the gate, ``desnow`` on the input and ``detail`` without its
small parts reduce to the methods they change at their neutral settings; the two ``detail`` filters drop what they
say; mirrored copies average as they say; the two analysis scripts import and measure. (The test-time adaptation
is only loaded: it trains per image.)"""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import Any

import cv2
import numpy as np
import pytest

from murk.data import sample_underwater_images
from murk.enhance.equalize import luma
from murk.enhance.restorer import options_of, unregister
from murk.errors import InputFileError

from .bench_arms_run import BENCH_ARMS, ROOT, run_bench_arms
from .bench_arms_run import load_file as _load

PROBES = ROOT / "benchmarks" / "probes"
REGISTERED = {
    "detail_area.py": ("detail_area", {"area", "threshold"}),
    "detail_contrast.py": ("detail_contrast", {"base", "contrast", "threshold"}),
    "desnow_input.py": ("desnow_input", {"base", "source", "threshold", "crowd", "size"}),
    "cast_gate.py": ("cast_gate", {"cast", "below"}),
    "tta.py": ("tta", {"target", "steps", "lr", "mix"}),
    "flip_average.py": ("flip_average", {"base", "views", "checkpoint"}),
    "water_guided.py": ("water_guided", {"radius", "eps", "guide", "strength"}),
}


def _bench_arms() -> ModuleType:
    return _load(BENCH_ARMS)


def _unbuilt(file: str, method: str, cls: str, **settings: float) -> Any:
    """The probe class ``cls`` of ``file`` with ``settings`` and no network loaded (its filters are numpy only)."""
    try:
        module = _load(PROBES / file)
    finally:
        unregister(method)
    probe = getattr(module, cls).__new__(getattr(module, cls))
    for name, value in settings.items():
        setattr(probe, name, value)
    return probe


@pytest.mark.parametrize("file", sorted(REGISTERED))
def test_each_probe_registers_its_method_with_its_options(file: str) -> None:
    name, options = REGISTERED[file]
    try:
        _bench_arms().load_probe(PROBES / file)
        assert set(options_of(name)) == options
    finally:
        unregister(name)


def test_every_probe_is_in_the_readme_and_every_named_file_exists() -> None:
    readme = (PROBES / "README.md").read_text()
    files = sorted(p.name for p in PROBES.glob("*.py"))
    assert set(REGISTERED) <= set(files)
    missing = [f for f in files if f"`{f}`" not in readme]
    assert not missing, f"benchmarks/probes/README.md does not list {missing}"
    named = {line.split("`")[1] for line in readme.splitlines() if line.startswith("| `") and ".py`" in line}
    assert named == set(files)


def test_a_probe_at_its_neutral_setting_scores_as_the_method_it_changes(tmp_path: Path) -> None:
    pairs = tmp_path / "snow"
    (pairs / "clean").mkdir(parents=True)
    (pairs / "snowy").mkdir()
    rng = np.random.default_rng(3)
    for i, path in enumerate(sample_underwater_images()[:2]):
        clean = cv2.resize(cv2.imread(str(path)), (192, 144), interpolation=cv2.INTER_AREA)
        snowy = clean.copy()
        for y, x in rng.integers(4, 140, size=(30, 2)):
            cv2.circle(snowy, (int(x), int(y)), 1, (235, 240, 240), -1)
        cv2.imwrite(str(pairs / "clean" / f"{i}.png"), clean)
        cv2.imwrite(str(pairs / "snowy" / f"{i}.png"), snowy)
    proc = run_bench_arms(
        "--probe", str(PROBES / "detail_area.py"), "--probe", str(PROBES / "cast_gate.py"),
        "--probe", str(PROBES / "desnow_input.py"),
        "d=detail", "a0=detail_area?area=0", "a9=detail_area?area=9", "l=lite", "g1=cast_gate?below=1",
        "cb=colorbalance", "g0=cast_gate?cast=1000,below=0", "ld=lite+desnow", "di=desnow_input?source=output",
        "--ref", "d,l", "--snow-pairs", str(pairs), "--heldout-scenes", "0", "--threads", "1",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    line = next(s for s in proc.stdout.splitlines() if s.startswith("snow residue, mean:"))
    residue = {k: float(v) for k, v in (part.split() for part in line.split(":", 1)[1].split(";"))}
    assert residue["a0"] == residue["d"] and residue["g1"] == residue["l"]
    assert residue["g0"] == residue["cb"] and residue["di"] == residue["ld"]
    assert residue["a9"] != residue["d"] and residue["cb"] != residue["l"] and residue["ld"] != residue["l"]


def test_flip_average_averages_the_mirrored_passes_and_keeps_the_first_pass_depth() -> None:
    try:
        module = _load(PROBES / "flip_average.py")
        lite, jointid = module.create("lite"), module.create("jointid")
        probes = {v: module.FlipAverage("lite", v) for v in ("none", "h", "v", "hv", "vonly")}
        jv, jvonly = module.FlipAverage("jointid", "v"), module.FlipAverage("jointid", "vonly")
    finally:
        unregister("flip_average")
    images = np.stack([cv2.resize(cv2.imread(str(p))[..., ::-1], (96, 64)) for p in sample_underwater_images()[:2]])
    images = images.astype(np.float32) / 255.0
    h, v = (lambda x: x[:, :, ::-1]), (lambda x: x[:, ::-1])  # mirrors of a batch (B, H, W, 3)
    by_lite = {f: f(lite.restore(np.ascontiguousarray(f(images))).images) for f in (h, v)}
    alone = lite.restore(images).images
    both = v(h(lite.restore(np.ascontiguousarray(v(h(images)))).images))
    expected = {"none": alone, "h": (alone + by_lite[h]) / 2, "v": (alone + by_lite[v]) / 2}
    expected["hv"], expected["vonly"] = (alone + by_lite[h] + by_lite[v] + both) / 4, by_lite[v]
    for views, want in expected.items():
        np.testing.assert_allclose(probes[views].restore(images).images, want, atol=1e-6, err_msg=views)
    assert min(np.abs(want - alone).max() for want in list(expected.values())[1:]) > 1e-3  # lite is not symmetric
    restored, own = jv.restore(images), jointid.restore(images)
    assert restored.depth_m is not None and own.depth_m is not None
    np.testing.assert_array_equal(restored.depth_m, own.depth_m)  # the unmirrored pass's depth
    assert np.abs(restored.depth_m - own.depth_m[:, ::-1]).max() > 1e-3  # which the mirrored one is not
    upside_down = jointid.restore(np.ascontiguousarray(v(images))).depth_m
    assert upside_down is not None  # vonly: the upside-down pass's depth, mirrored back
    np.testing.assert_array_equal(jvonly.restore(images).depth_m, upside_down[:, ::-1])


def test_flip_average_loads_its_checkpoint_into_the_base(tmp_path: Path) -> None:
    copy, missing = tmp_path / "copy.pt", tmp_path / "missing.pt"
    try:
        module = _load(PROBES / "flip_average.py")
        copy.write_bytes(Path(module.create("lite").weights or "").read_bytes())
        loaded = module.FlipAverage("lite", "none", checkpoint=str(copy)).base
        with pytest.raises(InputFileError, match=r"missing\.pt"):
            module.FlipAverage("lite", "none", checkpoint=str(missing))
    finally:
        unregister("flip_average")
    assert loaded.weights == str(copy)


def test_detail_area_drops_the_small_parts_and_keeps_the_large() -> None:
    probe = _unbuilt("detail_area.py", "detail_area", "DetailArea", area=9, threshold=0.02)
    x = np.zeros((32, 32, 3), np.float32)
    y = x.copy()
    y[4, 4] = 0.5  # a 1-pixel part of the residual
    y[20:25, 20:25] = 0.5  # a 25-pixel part
    out = probe._kept(x, y)
    assert out[4, 4].max() == 0.0
    assert np.allclose(out[22, 22], 0.5, atol=0.02)


def test_detail_contrast_keeps_the_parts_that_are_bright_specks_on_the_input() -> None:
    probe = _unbuilt("detail_contrast.py", "detail_contrast", "DetailContrast", contrast=10.0, threshold=0.02)
    image = np.full((40, 40, 3), 0.3, np.float32)
    image[6:11, 6:11] = 0.8  # a bright speck on the input at the first part only
    restored = np.full((40, 40, 3), 0.5, np.float32)
    detailed = restored.copy()
    detailed[6:11, 6:11] = 0.2
    detailed[26:31, 26:31] = 0.2
    out = probe._kept(image, restored, detailed)
    assert np.allclose(out[8, 8], 0.2, atol=0.02)  # kept: the input shows it
    assert np.allclose(out[28, 28], 0.5)  # dropped: the input is flat there


def test_water_guided_keeps_a_distance_that_follows_the_frame_and_smooths_one_that_does_not() -> None:
    try:
        refine = _load(PROBES / "water_guided.py").refine_distance
    finally:
        unregister("water_guided")
    rng = np.random.default_rng(5)
    guide = cv2.GaussianBlur(rng.random((48, 64, 3), dtype=np.float32), (0, 0), 2.0)
    grey = luma(guide)
    follows_m = (2.0 + 30.0 * grey).astype(np.float32)  # a linear function of the guide: the filter keeps it
    assert refine(guide, follows_m, 0.0, 1e-6) is follows_m
    assert np.allclose(refine(guide, follows_m, 0.1, 1e-8), follows_m, rtol=1e-3)
    flat = np.full_like(guide, 0.5)  # no edge to follow: two box means of side 2 * 6 + 1 (b, then its mean)
    noisy_m = (4.0 + rng.random((48, 64))).astype(np.float32)
    box = cv2.blur(cv2.blur(noisy_m, (13, 13), borderType=cv2.BORDER_REFLECT), (13, 13), borderType=cv2.BORDER_REFLECT)
    assert np.allclose(refine(flat, noisy_m, 0.1, 1e-3), box, rtol=1e-4)


def test_distance_error_where_splits_the_error_by_edges_and_rows() -> None:
    split = _load(PROBES / "distance_error_where.py").error_split
    true_m = np.full((40, 60), 3.0, np.float32)
    true_m[10:30, 20:40] = 1.5  # a near block: its border is the depth edge
    true_m[0, 0] = np.nan  # no surface: left out
    exact = split(2.0 * true_m, true_m)  # only the scale is wrong
    assert exact.abs_rel_median == pytest.approx(0.0, abs=1e-6) and exact.abs_rel_rows == pytest.approx(0, abs=1e-6)
    trend = true_m * np.linspace(0.6, 1.4, 40, dtype=np.float32)[:, None]  # wrong from row to row only
    by_rows = split(trend, true_m)
    assert by_rows.abs_rel_median > 0.1 and by_rows.abs_rel_rows < 0.01
    at_edge = true_m.copy()
    at_edge[10, 20:40] *= 1.5  # wrong on the block's top edge only
    edges = split(at_edge, true_m)
    assert edges.near_edge_error_share == pytest.approx(1.0) and 0.1 < edges.near_edge_pixel_share < 0.5


def test_the_analysis_probes_import_and_measure() -> None:
    white = np.ones((4, 4, 3), np.float32)
    assert np.allclose(_load(PROBES / "reference_colour.py").mean_lab(white), [100.0, 0.0, 0.0], atol=0.01)
    rng = np.random.default_rng(0)
    restored = rng.random((48, 64, 3), dtype=np.float32)
    detailed = restored.copy()
    detailed[10:13, 10:13] -= 0.2
    values = _load(PROBES / "snow_frame_features.py").features(restored, detailed)
    assert len(values) == 8 and all(np.isfinite(values))
    assert values[1] == pytest.approx(1000 * 9 / (48 * 64))  # the 3x3 darkened by 0.2, per thousand pixels


def test_a_missing_probe_file_and_one_that_fails_to_import_are_named(tmp_path: Path) -> None:
    missing = "benchmarks/probes/nothing_here.py"
    proc = run_bench_arms("--probe", missing, "l=lite", "--ref", "l", "--heldout-scenes", "0")
    assert proc.returncode == 2
    assert "--probe benchmarks/probes/nothing_here.py: no such file" in proc.stderr
    broken = tmp_path / "broken_probe.py"
    broken.write_text("import murk_has_no_such_module\n")
    proc = run_bench_arms("--probe", str(broken), "l=lite", "--ref", "l", "--heldout-scenes", "0")
    assert proc.returncode == 2
    assert f"--probe {broken}: No module named 'murk_has_no_such_module'" in proc.stderr
