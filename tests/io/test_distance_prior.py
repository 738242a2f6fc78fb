"""The ground-plane layout prior (murk.io.distance_prior) and photographs without depth in murk.io.pairs."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.errors import InputFileError
from murk.io.distance_prior import (
    CAMERA_HEIGHT_RANGE_M,
    FAR_RATIO_RANGE,
    HORIZON_RANGE,
    Layout,
    layout_distance,
    sample_layout,
)
from murk.io.pairs import DepthOptions, discover, discover_photos, layout_depth, load_pair


def _ray_to_floor(u: float, v: float, focal: float, pitch: float, roll: float, height_m: float) -> float:
    """Independent geometry: rotate the camera ray by rotation matrices (roll about the optical axis, then pitch
    about the horizontal axis), intersect it with the floor plane ``height_m`` below the camera."""
    c, s = math.cos(roll), math.sin(roll)
    rolled = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array([u, v, focal])
    c, s = math.cos(pitch), math.sin(pitch)
    world = np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]]) @ rolled  # x right, y down, z forward
    return float(height_m * np.linalg.norm(world) / world[1]) if world[1] > 0 else math.inf


def test_every_ray_meets_the_floor_where_3d_geometry_says() -> None:
    for lay in (
        Layout(-0.25, 0.0, 60.0, 1.5, 40.0),
        Layout(0.1, 5.0, 50.0, 2.0, 60.0),
        Layout(-0.4, -6.0, 70.0, 0.7, 9.0),
    ):
        h, w = 40, 30
        d = layout_distance(h, w, lay)
        focal = 0.5 * h / math.tan(math.radians(lay.fov_deg / 2))
        pitch = math.atan2((0.5 - lay.horizon) * h, focal)
        for row, col in ((0, 0), (17, 5), (39, 29), (25, 14)):
            u, v = col + 0.5 - 0.5 * w, row + 0.5 - 0.5 * h
            want = min(_ray_to_floor(u, v, focal, pitch, math.radians(lay.roll_deg), lay.camera_height_m), lay.far_m)
            assert d[row, col] == pytest.approx(want, rel=1e-5)
    level = layout_distance(40, 30, Layout(-0.25, 0.0, 60.0, 1.5, 40.0))
    assert np.all(np.diff(level[:, 15]) < 0)  # farther towards the top of the frame
    assert np.all(level[:, 15] <= level[:, 0])  # an off-centre ray travels farther to the same floor


def test_at_and_above_the_horizon_the_backdrop_is_at_far() -> None:
    lay = Layout(horizon=0.5, roll_deg=0.0, fov_deg=50.0, camera_height_m=1.0, far_m=6.0)
    d = layout_distance(20, 8, lay)
    assert np.all(d[:10] == np.float32(6.0))  # rows above the horizon (row 10)
    assert np.all(d[-5:] < 6.0) and d.dtype == np.float32 and d.min() >= 1.0


def test_roll_tilts_the_horizon() -> None:
    level = layout_distance(24, 32, Layout(0.2, 0.0, 55.0, 1.0, 8.0))
    rolled = layout_distance(24, 32, Layout(0.2, 5.0, 55.0, 1.0, 8.0))
    assert np.allclose(level[:, 0], level[:, -1])
    assert not np.allclose(rolled[:, 0], rolled[:, -1])


def test_sampled_layouts_stay_in_their_ranges_and_repeat_by_seed() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        lay = sample_layout(rng)
        assert HORIZON_RANGE[0] <= lay.horizon <= HORIZON_RANGE[1]
        assert CAMERA_HEIGHT_RANGE_M[0] <= lay.camera_height_m <= CAMERA_HEIGHT_RANGE_M[1]
        ratio = lay.far_m / lay.camera_height_m
        assert FAR_RATIO_RANGE[0] <= ratio <= FAR_RATIO_RANGE[1] + 1e-9
    assert sample_layout(np.random.default_rng(9)) == sample_layout(9)


def test_bad_layouts_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="fov_deg"):
        Layout(0.0, 0.0, 190.0, 1.0, 5.0)
    with pytest.raises(ValueError, match="roll_deg"):
        Layout(0.0, 89.0, 60.0, 1.0, 5.0)
    with pytest.raises(ValueError, match="camera_height_m"):
        Layout(0.0, 0.0, 60.0, 2.0, 1.0)
    with pytest.raises(ValueError, match="height, width"):
        layout_distance(0, 5, Layout(0.0, 0.0, 60.0, 1.0, 5.0))


def _photos(folder: Path, names: list[str], hw: tuple[int, int] = (30, 40)) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    g = np.random.default_rng(len(names))
    for n in names:
        cv2.imwrite(str(folder / n), (g.random((*hw, 3)) * 255).astype(np.uint8))
    return folder


def test_photographs_are_found_in_rgb_or_in_the_folder_itself(tmp_path: Path) -> None:
    flat = _photos(tmp_path / "flat", ["a.png", "b.jpg"])
    sources, problems = discover(flat, "layout")
    assert [s.stem for s in sources] == ["a", "b"] and problems == []
    assert all(s.depth_path == "" for s in sources)
    nested = _photos(tmp_path / "nested" / "rgb", ["c.png"]).parent
    _photos(nested, ["ignored.png"])
    assert [s.stem for s in discover_photos(nested)[0]] == ["c"]
    clash = _photos(tmp_path / "clash", ["x.png", "x.jpg", "y.png"])
    sources, problems = discover(clash, "layout")
    assert [s.stem for s in sources] == ["y"] and "ambiguous stem 'x'" in problems[0].error


def test_a_folder_without_photographs_is_refused_naming_it(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputFileError, match="no images found") as info:
        discover(tmp_path / "empty", "layout")
    assert str(tmp_path / "empty") in str(info.value)
    with pytest.raises(InputFileError, match="not found"):
        discover_photos(tmp_path / "missing")
    with pytest.raises(ValueError, match="depth_from"):
        discover(tmp_path / "empty", "guess")  # type: ignore[arg-type]


def test_a_photograph_gets_its_own_layout_fixed_by_stem_and_seed(tmp_path: Path) -> None:
    folder = _photos(tmp_path / "p", ["one.png", "two.png"])
    a, b = discover(folder, "layout")[0]
    rgb, depth, valid = load_pair(a, DepthOptions(depth_from="layout"))
    assert rgb.shape == (30, 40, 3) and depth.shape == (30, 40) and valid.all()
    np.testing.assert_array_equal(depth, layout_depth("one", 30, 40, 0))
    assert not np.array_equal(depth, load_pair(b, DepthOptions(depth_from="layout"))[1])
    assert not np.array_equal(depth, load_pair(a, DepthOptions(depth_from="layout", layout_seed=1))[1])
