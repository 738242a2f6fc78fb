"""Reading and writing RGB images at the I/O edge.

Inside murk every image is float32 RGB in [0, 1] with shape (H, W, 3). This module is the only place where
uint8/uint16 and OpenCV's BGR order appear. Reading honours EXIF orientation, keeps 16-bit precision, and
converts grayscale or RGBA inputs to RGB, recording what it did in :class:`ImageInfo.notes`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from murk._checks import check_rgb
from murk._limits import DEFAULT_MAX_PIXELS as DEFAULT_MAX_PIXELS  # the pixel limit (re-exported)
from murk._limits import max_pixels
from murk._limits import set_max_pixels as set_max_pixels
from murk.errors import InputFileError
from murk.io.atomic import write_bytes_atomic
from murk.io.header import Header, read_header
from murk.io.listing import can_list, describe_unusable, glob_files, is_folder_loop, walk_files

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".ppm", ".webp")
"""File suffixes treated as images when scanning folders."""

BitDepth = Literal[8, 16]


def swap_red_blue(image: np.ndarray) -> np.ndarray:
    """An (H, W, 3) image with its first and last channels swapped (RGB <-> BGR, murk's order <-> OpenCV's), as a
    new C-contiguous array. OpenCV's cvtColor does it for uint8, uint16 and float32 about 40x faster than numpy's
    copy of a reversed-stride view (0.02 against 0.8 ms at 640x480); other dtypes take the numpy copy."""
    if image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"image: expected shape (H, W, 3), got {image.shape}")
    if image.dtype in (np.uint8, np.uint16, np.float32) and image.size:
        return cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_RGB2BGR)
    return np.ascontiguousarray(image[:, :, ::-1])


def to_opencv_order(image: np.ndarray) -> np.ndarray:
    """An image in OpenCV's channel order for its encoders: RGB -> BGR (:func:`swap_red_blue`), RGBA -> BGRA
    (alpha stays last), grey (and grey + alpha) unchanged."""
    if image.ndim == 3 and image.shape[2] == 3:
        return swap_red_blue(image)
    if image.ndim == 3 and image.shape[2] == 4:
        return np.ascontiguousarray(image[:, :, [2, 1, 0, 3]])
    return image


def _check_declared(path: Path, header: Header | None) -> None:
    limit = max_pixels()
    if header is not None and header.width * header.height > limit:
        w, h = header.width, header.height
        raise InputFileError(
            path,
            f"declares {w}x{h} = {w * h:,} pixels, over the limit of {limit:,} "
            "(a decompression bomb or a huge frame; raise it with 'murk --max-pixels N' or MURK_MAX_PIXELS)",
        )


def check_declared_size(path: str | Path, data: np.ndarray | bytes | None = None) -> None:
    """Refuse an image file whose header declares more than :func:`max_pixels` pixels (read without decoding).

    ``data``: the file's bytes when the caller has read them already (else the file is read here).

    Raises:
        InputFileError: the declared size is over the limit, or (``data`` not given) the file cannot be read.
    """
    path = Path(path)
    if data is None:
        data = read_input_bytes(path)
    _check_declared(
        path, read_header(np.ascontiguousarray(data, np.uint8).data if isinstance(data, np.ndarray) else data)
    )


@dataclass(frozen=True)
class ImageInfo:
    """What :func:`read_image` found in a file."""

    path: str
    bit_depth: BitDepth
    source_mode: str
    notes: tuple[str, ...] = field(default_factory=tuple)


def not_an_image(path: str | Path) -> str:
    """Why the existing file ``path`` cannot be an image murk wrote: ``"is empty"`` or ``"is not an image"``
    (no image format's signature: OpenCV's check, which reads the header only); ``""`` when it looks like one."""
    if Path(path).stat().st_size == 0:
        return "is empty"
    return "" if cv2.haveImageReader(str(path)) else "is not an image"


def read_image(path: str | Path) -> tuple[np.ndarray, ImageInfo]:
    """Decode an image file to an RGB array of dtype uint8 or uint16, shape (H, W, 3).

    EXIF orientation is applied. Grayscale is replicated to three channels and an alpha channel is dropped;
    both are recorded in the returned info's ``notes``.

    The header is checked first: an image declaring more than :func:`max_pixels` pixels is refused without
    being decoded.

    Raises:
        InputFileError: the file does not exist, cannot be read (permission denied, I/O error), declares too
            many pixels, cannot be decoded (or not in the memory available), or has an unsupported sample type.
    """
    path = Path(path)
    why = describe_unusable(path)
    if why is not None:
        raise InputFileError(path, why)
    data = read_input_bytes(path)
    header = read_header(data.data)
    _check_declared(path, header)
    limit = max_pixels()
    try:
        bgr = cv2.imdecode(data, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH) if data.size else None
    except cv2.error as exc:
        raise InputFileError(path, f"cannot decode image ({str(exc).strip().splitlines()[-1]})") from None
    except MemoryError:
        raise InputFileError(path, "not enough memory to decode this image") from None
    if bgr is not None and bgr.shape[0] * bgr.shape[1] > limit:
        raise InputFileError(path, f"{bgr.shape[1]}x{bgr.shape[0]} pixels, over the limit of {limit:,}")
    if bgr is None:
        raise InputFileError(path, "cannot decode image (unsupported format or corrupt file)")
    if bgr.dtype not in (np.uint8, np.uint16):
        raise InputFileError(path, f"unsupported sample type {bgr.dtype}; expected 8- or 16-bit integer samples")
    mode = header.mode if header is not None else "unknown"
    notes: list[str] = []
    if mode in ("L", "I;16", "I;16B", "I;16L", "I", "1"):
        notes.append(f"grayscale ({mode}) converted to RGB")
    elif mode in ("LA", "RGBA", "PA"):
        notes.append(f"alpha channel of {mode} image dropped")
    info = ImageInfo(str(path), 16 if bgr.dtype == np.uint16 else 8, mode, tuple(notes))
    return swap_red_blue(bgr), info


def read_input_bytes(path: str | Path, what: str = "input file") -> np.ndarray:
    """The bytes of an input file as a uint8 array (decoding from bytes makes non-ASCII paths work everywhere).

    Raises:
        InputFileError: ``path`` is not a readable regular file (it says what it is: missing, a broken link, a
            FIFO, a device), or reading it failed (permission denied, I/O error), naming ``what`` it was.
    """
    path = Path(path)
    why = describe_unusable(path)
    if why is not None:
        raise InputFileError(path, why)
    try:
        return np.fromfile(str(path), dtype=np.uint8)
    except OSError as exc:  # permission denied, I/O error: this file fails, a batch goes on
        raise InputFileError(path, f"cannot read this {what} ({_reason(exc)})") from None


def to_float(image: np.ndarray) -> np.ndarray:
    """Convert a uint8 or uint16 RGB array to float32 in [0, 1] (scale from the dtype, never from the data)."""
    if image.dtype == np.uint8:
        return image.astype(np.float32) / np.float32(255.0)
    if image.dtype == np.uint16:
        return image.astype(np.float32) / np.float32(65535.0)
    raise TypeError(f"image: expected dtype uint8 or uint16, got {image.dtype}")


def to_uint(image: np.ndarray, bits: BitDepth = 8) -> np.ndarray:
    """Convert a float image in [0, 1] to uint8 (bits=8) or uint16 (bits=16), clipping and rounding."""
    if bits not in (8, 16):
        raise ValueError(f"bits: expected 8 or 16, got {bits!r}")
    peak = 255.0 if bits == 8 else 65535.0
    out = np.clip(image, 0.0, 1.0) * np.float32(peak) + np.float32(0.5)
    return out.astype(np.uint8 if bits == 8 else np.uint16)


def read_rgb(path: str | Path) -> np.ndarray:
    """Read an image file as float32 RGB in [0, 1], shape (H, W, 3). See :func:`read_image`."""
    image, _ = read_image(path)
    return to_float(image)


def write_rgb(
    path: str | Path, image: np.ndarray, *, bits: BitDepth = 8, jpeg_quality: int = 95, png_compression: int = 3
) -> Path:
    """Write a float RGB image in [0, 1] atomically; the format follows the suffix (PNG, JPEG, TIFF, ...).

    ``bits=16`` is only possible for PNG and TIFF.
    """
    path = Path(path)
    image = check_rgb("image", image)
    suffix = path.suffix.lower()
    if bits == 16 and suffix not in (".png", ".tif", ".tiff"):
        raise ValueError(f"bits: 16-bit output needs a .png or .tif path, got {path.name}")
    write_uint(path, to_uint(image, bits), jpeg_quality=jpeg_quality, png_compression=png_compression)
    return path


def write_uint(path: str | Path, image: np.ndarray, *, jpeg_quality: int = 95, png_compression: int = 3) -> Path:
    """Write a uint8/uint16 RGB (H, W, 3) or single-channel (H, W) array atomically.

    ``jpeg_quality`` (0-100) applies to JPEG, ``png_compression`` (deflate level 0-9, :func:`encode_png`) to PNG.

    Raises:
        ValueError: the format cannot hold this array.
        OutputError: no space left on the device (nothing is left under ``path``).
    """
    path = Path(path)
    if path.suffix.lower() == ".png":
        write_bytes_atomic(path, encode_png(image, png_compression, path=path), fsync=False)
        return path
    image = to_opencv_order(image)
    params: list[int] = []
    if path.suffix.lower() in (".jpg", ".jpeg"):
        params = [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)]
    write_bytes_atomic(path, encode_image(path, image, params), fsync=False)
    return path


FAST_PNG_LEVELS = range(1, 4)
"""Levels written by murk's fast PNG path: ISA-L's deflate (:func:`encode_png`), or OpenCV's fast filters and
zlib's run-length strategy where ``isal`` is missing (:func:`png_params`)."""


def png_params(level: int = 3) -> list[int]:
    """OpenCV PNG parameters for zlib ``level`` (0-9; ``output.png_compression``, default 3).

    Levels 1-3 use the fast path: libpng's fast filters (none/sub/up chosen per row, not all five) and zlib's
    run-length strategy. On murk's 640x480 images that encodes 3-4x faster than libpng's defaults at level 3
    with files within +-6 % of their size (BENCHMARKS.md, "Writing PNG"). Level 0 stores without compression;
    levels 4-9 use libpng's adaptive filters and zlib's default strategy (smaller, slower). Every path is
    lossless and deterministic (the same pixels give the same bytes with a given libpng/zlib).

    Raises:
        ValueError: ``level`` is not an integer in 0-9.
    """
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or not 0 <= int(level) <= 9:
        raise ValueError(f"png_compression: expected an integer 0-9, got {level!r}")
    params = [cv2.IMWRITE_PNG_COMPRESSION, int(level)]
    if int(level) in FAST_PNG_LEVELS:
        params += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FAST_FILTERS]
        params += [cv2.IMWRITE_PNG_STRATEGY, cv2.IMWRITE_PNG_STRATEGY_RLE]
    return params


def encode_png(image: np.ndarray, level: int = 3, *, path: str | Path = "image.png") -> bytes:
    """PNG bytes of a uint8/uint16 image in PNG's channel order ((H, W) grey, (H, W, 3) RGB, (H, W, 4) RGBA) at
    ``output.png_compression`` ``level`` (0-9): levels 1-3 with ISA-L's deflate (:mod:`murk.io.png`, about 4.8x
    faster than OpenCV's fast path) when ``isal`` is installed, otherwise and at levels 0 and 4-9 with OpenCV
    (:func:`png_params`). Lossless either way. The bytes depend on which path wrote them (and on the ``isal`` or
    OpenCV version), the pixels never. ``path`` only names the file in errors.

    Raises:
        ValueError: ``level`` is not an integer in 0-9; pixels other than uint8/uint16; a shape OpenCV cannot
            write on its path (e.g. grey + alpha (H, W, 2), which only the ISA-L path writes).
    """
    from murk.io.png import encode_png_isal, isal_available

    params = png_params(level)  # checks the level
    if image.dtype not in (np.uint8, np.uint16):  # OpenCV would write other dtypes as 8 bits, silently
        raise ValueError(f"{path}: PNG takes uint8 or uint16 pixels, got {image.dtype}")
    if int(level) in FAST_PNG_LEVELS and isal_available():
        return encode_png_isal(image, int(level))
    return encode_image(path, to_opencv_order(image), params)


def encode_image(path: str | Path, image: np.ndarray, params: Sequence[int] = ()) -> bytes:
    """Encode a BGR(A)/grey array in the format of ``path``'s suffix, in memory (see :mod:`murk.io.atomic`).

    Raises:
        ValueError: OpenCV cannot encode this format/dtype/shape (the message names ``path``).
    """
    try:
        ok, buf = cv2.imencode(Path(path).suffix.lower(), image, list(params))
    except cv2.error:
        ok, buf = False, None
    if not ok or buf is None:
        raise ValueError(f"{path}: OpenCV could not write this format/dtype ({image.dtype}, {image.shape})")
    return buf.tobytes()


def list_images(folder: str | Path, *, recursive: bool = False, unusable: bool = False) -> list[Path]:
    """Image files in ``folder`` (sorted), by suffix; hidden files and murk temporaries are skipped.

    ``recursive=True`` follows directory symlinks but enters each real folder once, never follows a link back to
    its own folder or an ancestor, and lists each real file once (see :func:`murk.io.listing.walk_files`), so a
    symlink loop neither hangs nor repeats files.

    ``unusable=True`` (batch commands that record one error per input) also lists the entries with an image
    suffix that cannot be read as files (broken symlinks, symlink loops, FIFOs, devices), and the folder loops
    and subfolders a recursive walk did not enter: :func:`read_image` refuses each with a message saying what it
    is and what to do.

    Raises:
        InputFileError: ``folder`` is not a folder or cannot be listed.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputFileError(folder, "not a folder")
    try:
        files = walk_files(folder, recursive=recursive, unusable=unusable)
    except OSError as exc:
        raise InputFileError(folder, f"cannot list this input folder ({_reason(exc)})") from None
    return [p for p in files if _is_image_entry(p, unusable)]


def glob_images(pattern: str, *, unusable: bool = False) -> list[Path]:
    """Image files matching a glob pattern (sorted, each real file once; ``**`` walks never follow a loop), by
    suffix, hidden files skipped; ``unusable`` as in :func:`list_images` (see
    :func:`murk.io.listing.glob_files`)."""
    return [p for p in glob_files(pattern, unusable=unusable) if _is_image_entry(p, unusable)]


def _is_image_entry(path: Path, unusable: bool) -> bool:
    """An entry of a listing that a batch command takes: a non-hidden image by suffix or, with ``unusable``, a
    folder the walk did not enter (kept so that it is reported, not silently skipped)."""
    if path.name.startswith("."):
        return False
    if path.suffix.lower() in IMAGE_SUFFIXES:
        return True
    return unusable and path.is_dir() and (is_folder_loop(path) or not can_list(path))


def _reason(exc: OSError) -> str:
    """An OSError's reason in lower case without the path ('permission denied')."""
    text = exc.strerror or str(exc)
    return text[:1].lower() + text[1:]
