from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.errors import InputFileError
from murk.io import list_images, read_image, read_rgb, to_float, to_uint, write_rgb
from murk.io.atomic import TMP_PREFIX, atomic_path, remove_stale_temporaries


def test_png_roundtrip_8_and_16_bit(tmp_path: Path, rng: np.random.Generator) -> None:
    img = rng.random((7, 9, 3)).astype(np.float32)
    write_rgb(tmp_path / "a.png", img)
    back8 = read_rgb(tmp_path / "a.png")
    assert back8.shape == (7, 9, 3) and back8.dtype == np.float32
    assert np.abs(back8 - img).max() <= 0.5 / 255 + 1e-6
    write_rgb(tmp_path / "b.png", img, bits=16)
    raw, info = read_image(tmp_path / "b.png")
    assert raw.dtype == np.uint16 and info.bit_depth == 16
    assert np.abs(to_float(raw) - img).max() <= 0.5 / 65535 + 1e-7


def test_rgb_order_is_preserved(tmp_path: Path) -> None:
    img = np.zeros((2, 2, 3), np.float32)
    img[..., 0] = 1.0  # pure red
    write_rgb(tmp_path / "r.png", img)
    bgr = cv2.imread(str(tmp_path / "r.png"))
    assert bgr[0, 0].tolist() == [0, 0, 255]  # OpenCV sees BGR
    assert read_rgb(tmp_path / "r.png")[0, 0].tolist() == [1.0, 0.0, 0.0]


def test_grayscale_and_rgba_are_converted_with_a_note(tmp_path: Path) -> None:
    gray = np.arange(12, dtype=np.uint8).reshape(3, 4) * 20
    cv2.imwrite(str(tmp_path / "g.png"), gray)
    raw, info = read_image(tmp_path / "g.png")
    assert raw.shape == (3, 4, 3) and np.array_equal(raw[..., 1], gray)
    assert any("grayscale" in n for n in info.notes)
    rgba = np.dstack([np.full((3, 4, 3), 50, np.uint8), np.full((3, 4), 7, np.uint8)])
    cv2.imwrite(str(tmp_path / "a.png"), rgba)
    raw, info = read_image(tmp_path / "a.png")
    assert raw.shape == (3, 4, 3) and (raw == 50).all()
    assert any("alpha" in n for n in info.notes)


def test_exif_orientation_is_honoured(tmp_path: Path) -> None:
    from PIL import Image

    arr = np.zeros((4, 6, 3), np.uint8)
    arr[0, 0] = 255
    im = Image.fromarray(arr)
    exif = im.getexif()
    exif[0x0112] = 6  # rotate 90 degrees clockwise for display
    im.save(tmp_path / "o.jpg", exif=exif.tobytes(), quality=100)
    raw, _ = read_image(tmp_path / "o.jpg")
    assert raw.shape == (6, 4, 3)
    assert raw[0, -1].mean() > 200  # the top-left corner moved to the top-right


def test_tiff_16_bit(tmp_path: Path) -> None:
    arr = np.arange(24, dtype=np.uint16).reshape(2, 4, 3) * 2000
    cv2.imwrite(str(tmp_path / "t.tif"), arr[..., ::-1])
    raw, info = read_image(tmp_path / "t.tif")
    assert info.bit_depth == 16 and np.array_equal(raw, arr)


def test_errors_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match=r"missing\.png: file not found"):
        read_image(tmp_path / "missing.png")
    (tmp_path / "bad.png").write_bytes(b"not an image at all")
    with pytest.raises(InputFileError, match=r"bad\.png: cannot decode image"):
        read_image(tmp_path / "bad.png")
    (tmp_path / "empty.jpg").write_bytes(b"")
    with pytest.raises(InputFileError, match=r"empty\.jpg: cannot decode"):
        read_image(tmp_path / "empty.jpg")
    with pytest.raises(ValueError, match="16-bit output needs"):
        write_rgb(tmp_path / "x.jpg", np.zeros((2, 2, 3), np.float32), bits=16)
    with pytest.raises(TypeError, match="expected a float image"):
        write_rgb(tmp_path / "x.png", np.zeros((2, 2, 3), np.uint8))


def test_to_uint_clips_and_rounds() -> None:
    x = np.array([[[-0.5, 0.5 / 255 - 1e-4, 2.0]]], np.float32)
    assert to_uint(x).tolist() == [[[0, 0, 255]]]
    assert to_uint(np.full((1, 1, 3), 1.0, np.float32), 16).max() == 65535


def test_atomic_path_leaves_nothing_on_failure(tmp_path: Path) -> None:
    target = tmp_path / "out.txt"
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        tmp.write_text("half")
        raise RuntimeError("killed")
    assert not target.exists() and list(tmp_path.iterdir()) == []
    (tmp_path / f"{TMP_PREFIX}abc-x.png").write_bytes(b"x")
    assert remove_stale_temporaries(tmp_path) == 1


def test_list_images_skips_hidden_and_non_images(tmp_path: Path) -> None:
    for name in ("b.png", "a.JPG", ".hidden.png", "notes.txt", f"{TMP_PREFIX}1-c.png"):
        (tmp_path / name).write_bytes(b"")
    assert [p.name for p in list_images(tmp_path)] == ["a.JPG", "b.png"]
    with pytest.raises(InputFileError, match="not a folder"):
        list_images(tmp_path / "nope")


def test_decompression_bombs_are_refused_from_the_header(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A header declaring 60000x60000 (PNG) or 65000x65000 (JPEG) is refused before decoding, naming the file."""
    from murk.io import max_pixels, set_max_pixels

    from ._bombs import jpeg_bomb, png_bomb

    for bomb, size in ((png_bomb(tmp_path / "b.png"), "60000x60000"), (jpeg_bomb(tmp_path / "b.jpg"), "65000x65000")):
        with pytest.raises(InputFileError, match=f"{bomb.name}: declares {size} .* over the limit of 100,000,000"):
            read_image(bomb)
    small = tmp_path / "small.png"
    write_rgb(small, np.zeros((40, 50, 3), np.float32))
    try:
        set_max_pixels(1999)
        with pytest.raises(InputFileError, match="declares 50x40 = 2,000 pixels, over the limit of 1,999"):
            read_image(small)
        set_max_pixels(None)
        monkeypatch.setenv("MURK_MAX_PIXELS", "2000")
        assert max_pixels() == 2000 and read_image(small)[0].shape == (40, 50, 3)
        monkeypatch.setenv("MURK_MAX_PIXELS", "lots")
        with pytest.raises(ValueError, match="MURK_MAX_PIXELS: expected a positive integer, got 'lots'"):
            max_pixels()
        with pytest.raises(ValueError, match="max_pixels: expected a positive integer"):
            set_max_pixels(0)
    finally:
        set_max_pixels(None)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64, np.int32])
def test_swap_red_blue_equals_the_reversed_channels(dtype: type) -> None:
    from murk.io.images import swap_red_blue

    rng = np.random.default_rng(3)
    for h, w in ((1, 1), (5, 7), (480, 640)):
        image = (rng.random((h, w, 3)) * 1000).astype(dtype)
        got = swap_red_blue(image)
        np.testing.assert_array_equal(got, image[:, :, ::-1])
        assert got.dtype == image.dtype and got.flags.c_contiguous and not np.shares_memory(got, image)
    view = (rng.random((9, 8, 3)) * 255).astype(dtype)[::2, 1::3]  # a strided view
    np.testing.assert_array_equal(swap_red_blue(view), view[:, :, ::-1])
    assert swap_red_blue(np.zeros((0, 4, 3), dtype)).shape == (0, 4, 3)
    with pytest.raises(ValueError, match=r"expected shape \(H, W, 3\)"):
        swap_red_blue(np.zeros((4, 4, 4), dtype))


def test_rgba_written_to_tiff_keeps_its_alpha_last(tmp_path: Path) -> None:
    from murk.io.images import write_uint

    rgba = np.dstack([np.full((3, 4), v, np.uint8) for v in (10, 20, 30, 200)])
    write_uint(tmp_path / "a.tif", rgba)
    bgra = cv2.imread(str(tmp_path / "a.tif"), cv2.IMREAD_UNCHANGED)
    np.testing.assert_array_equal(bgra, rgba[:, :, [2, 1, 0, 3]])
