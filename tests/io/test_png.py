"""murk's fast PNG path (murk/io/png.py): standard files any reader decodes to the same pixels, deterministic
bytes, and OpenCV as the fallback (issue 29)."""

from __future__ import annotations

import io
from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

import murk.io.png as png
from murk.io.images import encode_png, write_uint

needs_isal = pytest.mark.skipif(not png.isal_available(), reason="isal is not installed (OpenCV writes the PNGs)")

SHAPES = [(1, 1), (1, 7), (9, 1), (13, 17), (48, 64)]


def _opencv_order(image: np.ndarray) -> np.ndarray:
    """What ``cv2.imread(..., IMREAD_UNCHANGED)`` returns for a PNG of ``image`` (RGB(A) -> BGR(A))."""
    if image.ndim == 3 and image.shape[2] in (3, 4):
        return image[:, :, [2, 1, 0, 3][: image.shape[2]]]
    return image


@needs_isal
@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("channels", [0, 1, 2, 3, 4])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_every_layout_decodes_to_the_same_pixels(shape: tuple[int, int], channels: int, dtype: type) -> None:
    rng = np.random.default_rng(channels * 7 + shape[0])
    full = shape if channels == 0 else (*shape, channels)
    image = rng.integers(0, np.iinfo(dtype).max + 1, full, dtype=dtype)
    image[: shape[0] // 2] //= 3  # some smooth area, some noise
    data = png.encode_png_isal(image, 3)
    assert data.startswith(png.SIGNATURE)
    pil = np.asarray(Image.open(io.BytesIO(data)))
    expected = image[:, :, 0] if channels == 1 else image
    if dtype == np.uint8 or channels in (0, 1):  # Pillow reads 16-bit colour PNGs as 8 bits: OpenCV checks those
        assert pil.dtype == dtype and np.array_equal(pil, expected)
    back = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if channels == 2:  # OpenCV expands grey + alpha to BGRA
        assert np.array_equal(back[:, :, 0], image[:, :, 0]) and np.array_equal(back[:, :, 3], image[:, :, 1])
    else:
        assert back.dtype == dtype and np.array_equal(back, _opencv_order(expected))


@needs_isal
def test_imageio_reads_the_files_too(tmp_path: Path) -> None:
    iio = pytest.importorskip("imageio.v3")  # scikit-image's dependency
    rgb = np.random.default_rng(3).integers(0, 256, (21, 34, 3), dtype=np.uint8)
    depth = np.random.default_rng(4).integers(0, 65536, (21, 34), dtype=np.uint16)
    for name, image in (("rgb.png", rgb), ("depth.png", depth)):
        (tmp_path / name).write_bytes(png.encode_png_isal(image, 3))
        back = iio.imread(tmp_path / name)
        assert back.dtype == image.dtype and np.array_equal(back, image)


@needs_isal
def test_the_same_pixels_give_the_same_bytes_and_levels_differ() -> None:
    image = (np.arange(64 * 80 * 3) % 251).astype(np.uint8).reshape(64, 80, 3)
    assert png.encode_png_isal(image, 3) == png.encode_png_isal(image.copy(), 3)
    sizes = {level: len(png.encode_png_isal(image, level)) for level in (1, 2, 3)}
    assert len(set(sizes.values())) > 1  # the levels map to different ISA-L levels


@needs_isal
def test_long_streams_are_split_into_idat_chunks(monkeypatch: pytest.MonkeyPatch) -> None:
    image = np.random.default_rng(0).integers(0, 256, (40, 50, 3), dtype=np.uint8)  # incompressible
    monkeypatch.setattr(png, "MAX_CHUNK", 1000)
    data = png.encode_png_isal(image, 3)
    assert data.count(b"IDAT") > 5
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(data))), image)


@needs_isal
@pytest.mark.parametrize(
    ("image", "level", "message"),
    [
        (np.zeros((4, 4), np.float32), 3, "uint8 or uint16"),
        (np.zeros((4, 4, 5), np.uint8), 3, r"\(H, W\) or \(H, W, 1-4\)"),
        (np.zeros((0, 4), np.uint8), 3, "H, W >= 1"),
        (np.zeros((4, 4), np.uint8), 4, "levels 1-3"),
    ],
)
def test_bad_input_is_refused(image: np.ndarray, level: int, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        png.encode_png_isal(image, level)


@needs_isal
def test_encode_png_takes_isal_at_levels_1_to_3_only() -> None:
    rgb = np.random.default_rng(1).integers(0, 256, (30, 40, 3), dtype=np.uint8)
    assert encode_png(rgb, 3) == png.encode_png_isal(rgb, 3)
    for level in (0, 6):  # stored, or libpng's adaptive filters: OpenCV
        data = encode_png(rgb, level)
        assert data != png.encode_png_isal(rgb, 3)
        assert np.array_equal(np.asarray(Image.open(io.BytesIO(data))), rgb)


@pytest.mark.parametrize("channels", [0, 3, 4])
@pytest.mark.parametrize("level", [0, 3, 6])
def test_the_opencv_path_writes_the_same_pixels_in_png_order(
    monkeypatch: pytest.MonkeyPatch, channels: int, level: int
) -> None:
    """Where isal is missing (the GPU machine) OpenCV writes every level; RGB(A) stays RGB(A) in the file."""
    monkeypatch.setattr(png, "isal_available", lambda: False)
    shape = (30, 40) if channels == 0 else (30, 40, channels)
    image = np.random.default_rng(channels).integers(0, 256, shape, dtype=np.uint8)
    data = encode_png(image, level)
    assert np.array_equal(np.asarray(Image.open(io.BytesIO(data))), image)


def test_encode_png_refuses_what_png_cannot_hold_losslessly() -> None:
    with pytest.raises(ValueError, match="png_compression"):
        encode_png(np.zeros((4, 4, 3), np.uint8), 10)
    for dtype in (np.float32, np.bool_, np.int16):  # OpenCV would write these as 8 bits, silently
        with pytest.raises(ValueError, match=r"out\.png: PNG takes uint8 or uint16 pixels, got"):
            encode_png(np.zeros((4, 4), dtype), 3, path="out.png")


@needs_isal
def test_write_uint_writes_the_isal_png(tmp_path: Path) -> None:
    rgb = np.random.default_rng(2).integers(0, 256, (20, 30, 3), dtype=np.uint8)
    path = write_uint(tmp_path / "x.png", rgb)
    assert path.read_bytes() == png.encode_png_isal(rgb, 3)
    assert np.array_equal(cv2.imread(str(path))[:, :, ::-1], rgb)
