"""The resize some published UIQM/UCIQE scripts apply before scoring, reproduced exactly.

FUnIE-GAN's ``measure_uiqm.py`` resizes every image to 256x256 with Pillow's bicubic filter before calling
its UIQM code; UIQM depends strongly on the image size (its block terms), so reproducing such numbers needs
the same resize. Pillow (a scikit-image dependency) is used because its bicubic differs from OpenCV's.
"""

from __future__ import annotations

import numpy as np

from murk._checks import int_pair
from murk.errors import ShapeError


def pil_bicubic_resize(image: np.ndarray, size_wh: tuple[int, int]) -> np.ndarray:
    """Resize a uint8 RGB image (H, W, 3) to ``size_wh`` = (width, height) with Pillow's bicubic filter.

    Equals ``Image.fromarray(image).resize(size_wh, Image.BICUBIC)``; the aspect ratio is not preserved.

    Raises:
        TypeError: ``image`` is not a uint8 numpy array.
        ShapeError: ``image`` is not (H, W, 3).
        ValueError: ``size_wh`` is not two integers >= 1.
    """
    from PIL import Image

    if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
        got = image.dtype if isinstance(image, np.ndarray) else type(image).__name__
        raise TypeError(f"image: expected a uint8 numpy array (Pillow's 8-bit resize), got {got}")
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] < 1 or image.shape[1] < 1:
        raise ShapeError(f"image: expected shape (H, W, 3), got {image.shape}")
    pair = int_pair(size_wh)
    if pair is None or min(pair) < 1:
        raise ValueError(f"size_wh: expected (width, height) integers >= 1, got {size_wh!r}")
    w, h = pair
    return np.asarray(Image.fromarray(np.ascontiguousarray(image), mode="RGB").resize((w, h), Image.Resampling.BICUBIC))
