from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.errors import InputFileError
from murk.io import read_depth, resolve_invalid, validity_mask, write_depth_png
from murk.io.depth import RELATIVE_FAR_M, RELATIVE_NEAR_M, read_nyu_mat


def test_uint16_png_scales(tmp_path: Path) -> None:
    raw = np.array([[0, 1000, 2500], [65535, 300, 1]], np.uint16)
    cv2.imwrite(str(tmp_path / "d.png"), raw)
    d = read_depth(tmp_path / "d.png")
    assert d.dtype == np.float32
    np.testing.assert_allclose(d, raw / 1000.0, rtol=1e-6)
    np.testing.assert_allclose(read_depth(tmp_path / "d.png", depth_scale=5000), raw / 5000.0, rtol=1e-6)


def test_tum_fixture_depth_range(tests_data: Path) -> None:
    # TUM RGB-D: metres = value / 5000; the committed frame spans 1.46-9.33 m (data MANIFEST).
    d = read_depth(tests_data / "rgbd_raw" / "TUM_depth.png", depth_scale=5000)
    v = d[validity_mask(d)]
    assert 1.4 < v.min() < 1.5 and 9.3 < v.max() < 9.4


def test_npy_metres_and_bad_shapes(tmp_path: Path) -> None:
    np.save(tmp_path / "d.npy", np.full((3, 4, 1), 2.5, np.float64))
    assert read_depth(tmp_path / "d.npy").shape == (3, 4)
    np.save(tmp_path / "bad.npy", np.zeros((2, 3, 4)))
    with pytest.raises(InputFileError, match=r"bad\.npy: expected a 2-D numeric array"):
        read_depth(tmp_path / "bad.npy")


def test_8bit_depth_needs_relative_flag(tmp_path: Path) -> None:
    cv2.imwrite(str(tmp_path / "r.png"), np.array([[0, 255]], np.uint8))
    with pytest.raises(InputFileError, match=r"8-bit depth cannot be metric.*--depth-relative"):
        read_depth(tmp_path / "r.png")
    d = read_depth(tmp_path / "r.png", relative=True)
    np.testing.assert_allclose(d, [[RELATIVE_NEAR_M, RELATIVE_FAR_M]], rtol=1e-6)


def test_colour_depth_is_rejected(tmp_path: Path) -> None:
    img = np.zeros((2, 2, 3), np.uint16)
    img[..., 2] = 9
    cv2.imwrite(str(tmp_path / "c.png"), img)
    with pytest.raises(InputFileError, match="single-channel"):
        read_depth(tmp_path / "c.png")


def test_validity_mask() -> None:
    d = np.array([[0, np.nan, np.inf, -1, 0.5]], np.float32)
    assert validity_mask(d).tolist() == [[False, False, False, False, True]]


def test_resolve_invalid_modes() -> None:
    d = np.array([[1.0, 0.0, 3.0], [1.0, np.nan, 3.0]], np.float32)
    filled, valid = resolve_invalid(d, "fill")
    assert valid.sum() == 4 and np.isfinite(filled).all()
    assert filled[0, 1] in (1.0, 3.0)  # copied from a nearest valid neighbour
    far, _ = resolve_invalid(d, "far")
    assert far[0, 1] == 3.0 and far[1, 1] == 3.0
    with pytest.raises(InputFileError, match=r"d\.png: 2 invalid depth pixels \(33\.3 %"):
        resolve_invalid(d, "fail", source="d.png")
    with pytest.raises(InputFileError, match="no valid pixel"):
        resolve_invalid(np.zeros((2, 2), np.float32), "fill")
    with pytest.raises(ValueError, match="invalid_depth: expected"):
        resolve_invalid(d, "median")  # type: ignore[arg-type]


def test_write_depth_png_roundtrip(tmp_path: Path) -> None:
    d = np.array([[0.3, 15.0], [np.nan, 1.2345]], np.float32)
    write_depth_png(tmp_path / "d.png", d)
    back = read_depth(tmp_path / "d.png")
    assert back[1, 0] == 0  # invalid stays invalid
    np.testing.assert_allclose(back[[0, 0, 1], [0, 1, 1]], [0.3, 15.0, 1.235], atol=5e-4)


def test_nyu_mat_transposed_layout(tmp_path: Path) -> None:
    h5py = pytest.importorskip("h5py")
    rgb = np.zeros((2, 5, 7, 3), np.uint8)  # N, H, W, C
    rgb[1, 0, 6] = [10, 20, 30]
    depth = np.full((2, 5, 7), 2.0, np.float32)
    depth[1, 4, 0] = 7.5
    with h5py.File(tmp_path / "nyu.mat", "w") as f:
        f["images"] = rgb.transpose(0, 3, 2, 1)  # N, C, W, H as stored by MATLAB v7.3
        f["depths"] = depth.transpose(0, 2, 1)
    r, d = read_nyu_mat(tmp_path / "nyu.mat", 1)
    assert r.shape == (5, 7, 3) and r[0, 6].tolist() == [10, 20, 30]
    assert d.shape == (5, 7) and d[4, 0] == 7.5
    (tmp_path / "x.mat").write_bytes(b"MATLAB 5.0 MAT-file")
    with pytest.raises(InputFileError, match="not an HDF5"):
        read_nyu_mat(tmp_path / "x.mat", 0)


def test_sun_and_kinect_encodings(tmp_path: Path) -> None:
    # SUN RGB-D stores mm rotated right by 3 bits; 1234 mm -> stored as ((1234 << 3) | (1234 >> 13)) & 0xFFFF
    stored = np.array([[(1234 << 3) & 0xFFFF, 0]], np.uint16)
    cv2.imwrite(str(tmp_path / "sun.png"), stored)
    d = read_depth(tmp_path / "sun.png", encoding="sun")
    assert d[0, 0] == pytest.approx(1.234) and d[0, 1] == 0
    # raw Kinect disparity 800 -> 351.3 / (1092.5 - 800) m; 2047 = invalid; PGM samples are little-endian
    raw = np.array([[800, 2047]], np.uint16)
    cv2.imwrite(str(tmp_path / "k.pgm"), raw.byteswap())  # what NYU's dumps look like to a big-endian reader
    d = read_depth(tmp_path / "k.pgm", encoding="kinect-disparity")
    assert d[0, 0] == pytest.approx(351.3 / 292.5, rel=1e-6) and d[0, 1] == 0
    cv2.imwrite(str(tmp_path / "k.png"), raw)
    assert read_depth(tmp_path / "k.png", encoding="kinect-disparity")[0, 0] == pytest.approx(351.3 / 292.5, rel=1e-6)
    with pytest.raises(ValueError, match="depth_encoding: expected one of linear, sun, kinect-disparity"):
        read_depth(tmp_path / "k.png", encoding="kinect")  # type: ignore[arg-type]
