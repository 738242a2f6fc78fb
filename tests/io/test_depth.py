from __future__ import annotations

import contextlib
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.errors import InputFileError
from murk.io import read_depth, resolve_invalid, validity_mask, write_depth_png
from murk.io.depth import RELATIVE_FAR_M, RELATIVE_NEAR_M, read_nyu_mat

from ._bombs import npy_bomb, png_bomb


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


def test_fill_copies_a_nearest_valid_pixel_within_4_percent_of_the_exact_one() -> None:
    """``fill`` uses a chamfer distance transform (OpenCV): every hole copies a valid pixel at most 4 % farther
    than scipy's exact Euclidean nearest; valid pixels keep their values."""
    from scipy import ndimage

    rng = np.random.default_rng(0)
    worst = 0.0
    for trial in range(60):
        h, w = (int(n) for n in rng.integers(5, 90, 2))
        valid = rng.random((h, w)) < rng.uniform(0.002, 0.9)
        if trial % 3 == 0:  # holes in blobs, as a sensor leaves them
            valid = ndimage.binary_opening(valid) | (rng.random((h, w)) < 0.01)
        if valid.all() or not valid.any():
            continue
        depth = np.arange(1, h * w + 1, dtype=np.float32).reshape(h, w)  # a value names its pixel
        filled, _ = resolve_invalid(np.where(valid, depth, 0.0).astype(np.float32), "fill")
        assert np.array_equal(filled[valid], depth[valid])
        src_y, src_x = np.divmod(filled.astype(np.int64) - 1, w)
        assert valid[src_y, src_x].all()
        yy, xx = np.mgrid[:h, :w]
        copied = np.hypot(yy - src_y, xx - src_x)[~valid]
        exact = ndimage.distance_transform_edt(~valid)[~valid]
        worst = max(worst, float((copied / exact).max()))
    assert 1.0 <= worst <= 1.04


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


# --- .npy depth: the header is checked before any data is read (issue 13) -----------------------------------


def _peak_bytes(fn: Callable[[], object]) -> int:
    """Peak memory traced while ``fn`` runs (numpy reports its buffers to tracemalloc)."""
    tracemalloc.start()
    try:
        with contextlib.suppress(InputFileError):
            fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def test_npy_header_bomb_is_refused_without_allocating(tmp_path: Path) -> None:
    bomb = npy_bomb(tmp_path / "bomb.npy")  # 10^10 float64 = 80 GB declared, 128 bytes on disk
    with pytest.raises(InputFileError, match=r"bomb\.npy: declares float64 \(100000, 100000\) = 10,000,000,000 "):
        read_depth(bomb)
    assert _peak_bytes(lambda: read_depth(bomb)) < 1_000_000


def test_npy_over_the_pixel_limit_follows_murk_max_pixels(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    np.save(tmp_path / "d.npy", np.full((10, 10), 2.0, np.float32))
    monkeypatch.setenv("MURK_MAX_PIXELS", "99")
    with pytest.raises(InputFileError, match=r"d\.npy: declares .* = 100 elements, over the pixel limit of 99"):
        read_depth(tmp_path / "d.npy")
    monkeypatch.setenv("MURK_MAX_PIXELS", "100")
    assert read_depth(tmp_path / "d.npy").shape == (10, 10)


def test_truncated_npy_is_refused_before_reading(tmp_path: Path) -> None:
    # under the pixel limit (25 M elements) but only 12 bytes of its 100 MB of data are there
    short = npy_bomb(tmp_path / "short.npy", (5000, 5000), "<f4", data=b"\x00" * 12)
    with pytest.raises(InputFileError, match=r"short\.npy: truncated: the header declares .* 100,000,000 bytes, "):
        read_depth(short)
    assert _peak_bytes(lambda: read_depth(short)) < 1_000_000
    np.save(tmp_path / "cut.npy", np.ones((40, 50), np.float32))
    data = (tmp_path / "cut.npy").read_bytes()
    (tmp_path / "cut.npy").write_bytes(data[:-1])
    with pytest.raises(InputFileError, match=r"cut\.npy: truncated: .* 8,000 bytes, the file holds 7,999"):
        read_depth(tmp_path / "cut.npy")


@pytest.mark.parametrize(
    ("shape", "descr", "expected"),
    [
        ((100_000, 100_000, 100_000), "<f4", r"expected a 2-D numeric array in metres, got float32 \(100000, "),
        ((10**12,), "<f4", r"expected a 2-D numeric array in metres, got float32 \(1000000000000,\)"),
        ((100_000, 100_000), "|O", r"expected a 2-D numeric array in metres \(integer or float\), got object"),
        ((4, 4), "<c8", r"\(integer or float\), got complex64 \(4, 4\)"),
        ((4, 4), [("d", "<f4")], r"\(integer or float\), got \[\('d', '<f4'\)\]"),
        ((4, 4), "<U4", r"\(integer or float\), got <U4"),
        ((0, 5), "<f4", r"empty depth array \(float32 \(0, 5\)\)"),
    ],
)
def test_npy_wrong_shape_or_dtype_is_refused_from_the_header(
    tmp_path: Path, shape: tuple[int, ...], descr: object, expected: str
) -> None:
    path = npy_bomb(tmp_path / "x.npy", shape, descr)
    with pytest.raises(InputFileError, match=r"x\.npy: .*" + expected):
        read_depth(path)
    assert _peak_bytes(lambda: read_depth(path)) < 1_000_000


def test_npy_that_is_not_npy(tmp_path: Path) -> None:
    (tmp_path / "junk.npy").write_bytes(b"PK\x03\x04 not an array")
    with pytest.raises(InputFileError, match=r"junk\.npy: not a valid \.npy file"):
        read_depth(tmp_path / "junk.npy")
    (tmp_path / "v9.npy").write_bytes(b"\x93NUMPY\x09\x00" + b"\x00" * 16)
    with pytest.raises(InputFileError, match=r"v9\.npy: \.npy format version 9\.0 is not supported"):
        read_depth(tmp_path / "v9.npy")


def test_npy_layouts_and_dtypes_still_read_exactly(tmp_path: Path) -> None:
    ref = np.arange(12, dtype=np.float64).reshape(3, 4) / 4 + 0.5
    cases = {
        "c.npy": ref,
        "fortran.npy": np.asfortranarray(ref),
        "bigendian.npy": ref.astype(">f8"),
        "int16.npy": (ref * 4).astype(np.int16),
        "channel.npy": ref[:, :, None].astype(np.float32),
    }
    for name, arr in cases.items():
        np.save(tmp_path / name, arr)
        got = read_depth(tmp_path / name)
        assert got.dtype == np.float32 and got.shape == (3, 4), name
        np.testing.assert_array_equal(got, np.asarray(arr, np.float64).reshape(3, 4).astype(np.float32), name)
    big = tmp_path / "v2.npy"  # format 2.0 (np.save picks it only for huge headers): written by hand
    with open(big, "wb") as f:
        np.lib.format.write_array(f, ref, version=(2, 0))
    np.testing.assert_array_equal(read_depth(big), ref.astype(np.float32))


def test_depth_image_bomb_is_refused_before_decoding(tmp_path: Path) -> None:
    bomb = png_bomb(tmp_path / "d.png", 60000, 60000)
    with pytest.raises(InputFileError, match=r"d\.png: declares 60000x60000 = 3,600,000,000 pixels, over the limit"):
        read_depth(bomb)
    assert _peak_bytes(lambda: read_depth(bomb)) < 1_000_000
