"""Size and colour mode an image file declares in its header, read from its bytes without decoding.

PNG and JPEG, the formats murk reads most, are parsed here (PNG: the IHDR chunk, ISO/IEC 15948 sec. 11.2.2;
JPEG: the first start-of-frame marker, ITU-T T.81 sec. B.2.2), so reading them needs neither Pillow's import
(about 12 ms) nor a second and third open of the file. Every other format, and any header these parsers do not
understand, goes to Pillow, which reads the header only. The mode uses Pillow's names (``L``, ``I;16``, ``RGB``,
``RGBA``, ...), as Pillow reports them for the same file.
"""

from __future__ import annotations

import io
import struct
from typing import NamedTuple

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

# (bit depth, colour type) -> Pillow's mode, for every combination PNG allows (ISO/IEC 15948 table 11.1).
_PNG_MODES = {
    (1, 0): "1",
    **{(bits, 0): "L" for bits in (2, 4, 8)},
    (16, 0): "I;16",
    (8, 2): "RGB",
    (16, 2): "RGB",
    **{(bits, 3): "P" for bits in (1, 2, 4, 8)},
    (8, 4): "LA",
    (16, 4): "RGBA",  # Pillow widens 16-bit grey + alpha
    (8, 6): "RGBA",
    (16, 6): "RGBA",
}
_JPEG_MODES = {1: "L", 3: "RGB", 4: "CMYK"}
# Start-of-frame markers: 0xC0-0xCF except DHT (C4), JPG (C8) and DAC (CC).
_JPEG_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# Markers without a length field: TEM and RST0-7 (SOI and EOI are handled where they can appear).
_JPEG_STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})


class Header(NamedTuple):
    """What a file's header declares."""

    width: int
    height: int
    mode: str


def _png(data: bytes | memoryview) -> Header | None:
    if len(data) < 33 or bytes(data[8:16]) != b"\x00\x00\x00\x0dIHDR":  # the first chunk: IHDR, 13 bytes
        return None
    width, height, bits, colour = struct.unpack(">IIBB", data[16:26])
    mode = _PNG_MODES.get((bits, colour))
    if mode is None or width == 0 or height == 0:  # a combination PNG does not allow: Pillow decides
        return None
    return Header(width, height, mode)


def _jpeg(data: bytes | memoryview) -> Header | None:
    pos, n = 2, len(data)
    while pos + 4 <= n:
        if data[pos] != 0xFF:
            return None  # not at a marker: a layout this parser does not follow
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte
            pos += 1
            continue
        if marker in _JPEG_STANDALONE:
            pos += 2
            continue
        if marker in (0xD8, 0xD9, 0xDA):  # a second SOI, EOI, or the scan before any frame header
            return None
        (length,) = struct.unpack(">H", data[pos + 2 : pos + 4])
        if length < 2:
            return None
        if marker in _JPEG_SOF:
            if pos + 10 > n or length < 8:
                return None
            height, width, components = struct.unpack(">HHB", data[pos + 5 : pos + 10])
            mode = _JPEG_MODES.get(components)
            if mode is None or width == 0 or height == 0:  # height 0: defined later by a DNL marker
                return None
            return Header(width, height, mode)
        pos += 2 + length
    return None


def parse_header(data: bytes | memoryview) -> Header | None:
    """The header of a PNG or JPEG file given its bytes (or the first of them), or None for any other format
    or a header these parsers do not follow."""
    if bytes(data[:8]) == PNG_SIGNATURE:
        return _png(data)
    if bytes(data[:3]) == b"\xff\xd8\xff":
        return _jpeg(data)
    return None


def read_header(data: bytes | memoryview) -> Header | None:
    """The header of an image file given its bytes: :func:`parse_header`, else Pillow's reading of the header
    (no decoding), else None (not a format Pillow knows, or Pillow missing)."""
    found = parse_header(data)
    if found is not None:
        return found
    try:
        import warnings

        from PIL import Image

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # Pillow's own bomb warning: murk applies its limit, naming the file
            saved, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
            try:
                with Image.open(io.BytesIO(data)) as im:
                    return Header(int(im.size[0]), int(im.size[1]), str(im.mode))
            finally:
                Image.MAX_IMAGE_PIXELS = saved
    except Exception:  # not a format Pillow knows (or no Pillow): OpenCV decides
        return None
