"""The pixel limit of image reading (``murk --max-pixels N``, ``MURK_MAX_PIXELS``), in a module that imports
neither numpy nor OpenCV, so that the command line sets and checks it before any heavy import. Read by
:mod:`murk.io.images` (which re-exports these names) and every reader that checks headers."""

from __future__ import annotations

import os

DEFAULT_MAX_PIXELS = 100_000_000
"""Images declaring more pixels than this in their header are refused before decoding (decompression bombs;
a 100-megapixel frame is 1.2 GB as float32 RGB, and metrics hold several float64 planes of it: sized so that
one image stays well inside a 24 GiB machine). Change it with ``murk --max-pixels N`` (any command),
the ``MURK_MAX_PIXELS`` environment variable, or :func:`set_max_pixels`."""

_max_pixels: int | None = None


def set_max_pixels(limit: int | None) -> None:
    """Set the pixel limit of :func:`read_image` for this process (None = ``MURK_MAX_PIXELS`` or the default).

    Raises:
        ValueError: ``limit`` is not a positive integer.
    """
    global _max_pixels
    if limit is not None and (isinstance(limit, bool) or not isinstance(limit, int) or limit < 1):
        raise ValueError(f"max_pixels: expected a positive integer, got {limit!r}")
    _max_pixels = limit


def max_pixels() -> int:
    """The pixel limit in force (see :data:`DEFAULT_MAX_PIXELS`)."""
    if _max_pixels is not None:
        return _max_pixels
    env = os.environ.get("MURK_MAX_PIXELS")
    if env:
        try:
            value = int(env)
        except ValueError:
            raise ValueError(f"MURK_MAX_PIXELS: expected a positive integer, got {env!r}") from None
        if value < 1:
            raise ValueError(f"MURK_MAX_PIXELS: expected a positive integer, got {env!r}")
        return value
    return DEFAULT_MAX_PIXELS
