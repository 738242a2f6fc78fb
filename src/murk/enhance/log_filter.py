"""The Laplacian of Gaussian of Eq. (9)'s edge term, in numpy/OpenCV and torch twins (pinned equal by
``tests/twins.py``).

Per channel, border reflect-101: ``LoG = g'' (x) g (y) + g (x) g'' (y)`` with the sampled Gaussian ``g`` (radius
``ceil(4 sigma)``, sum 1) and its second derivative ``g''`` made exactly zero-sum, so the LoG of a constant image
is 0. :mod:`murk.enhance.post` folds it into Eq. (9).

Reference: S. Yun, G. Yang, J. Lee, C. Park, J. Choi, Y. Cho, "Robust Image Processing Techniques for
Construction Environment Monitoring Using Underwater Robots" (no DOI in the source text), Sec. 4.3, Eq. (9):
``I_out = I_HE - lambda * (LoG_sigma * I_HE)`` with sigma = 1.0 px and lambda = 0.3.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import cv2
import numpy as np

from murk._checks import check_positive
from murk.enhance.torch_twins import check_image_batch, pad_reflect101
from murk.errors import ShapeError

if TYPE_CHECKING:  # the torch twin imports it when called
    import torch

SIGMA_PX = 1.0
"""LoG standard deviation of the paper (Sec. 5.1)."""


def log_kernels(sigma_px: float) -> tuple[np.ndarray, np.ndarray]:
    """1-D kernels ``(g, g2)`` of the separable LoG: sampled Gaussian (sum 1) and its second derivative
    (made zero-sum), radius ``ceil(4 sigma)``, float32. ``LoG = g2 (x) g + g (x) g2``."""
    sigma_px = check_positive("sigma_px", sigma_px)
    r = max(1, math.ceil(4.0 * sigma_px))
    x = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-(x**2) / (2.0 * sigma_px**2))
    g /= g.sum()
    g2 = g * (x**2 - sigma_px**2) / sigma_px**4  # d^2/dx^2 of the Gaussian
    g2 -= g * g2.sum()  # exact zero sum: LoG of a constant is 0
    return g.astype(np.float32), g2.astype(np.float32)


def laplacian_of_gaussian(image: np.ndarray, sigma_px: float = SIGMA_PX) -> np.ndarray:
    """``LoG_sigma * image``, the edge term of Eq. (9), per channel (OpenCV, border reflect-101); (H, W) or
    (H, W, C) float32."""
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image: expected a numpy array, got {type(image).__name__}")
    if image.ndim not in (2, 3):
        raise ShapeError(f"image: expected shape (H, W) or (H, W, C), got {image.shape}")
    g, g2 = log_kernels(sigma_px)
    src = np.ascontiguousarray(image, dtype=np.float32)
    a = cv2.sepFilter2D(src, cv2.CV_32F, g2, g, borderType=cv2.BORDER_REFLECT_101)  # d2/dx2
    b = cv2.sepFilter2D(src, cv2.CV_32F, g, g2, borderType=cv2.BORDER_REFLECT_101)  # d2/dy2
    return cv2.add(a, b, dst=a).reshape(image.shape)


def laplacian_of_gaussian_torch(images: torch.Tensor, sigma_px: float = SIGMA_PX) -> torch.Tensor:
    """Torch twin of :func:`laplacian_of_gaussian` on (B, C, H, W), on the input's device (float32)."""
    check_image_batch(images, channels=None)
    g_np, g2_np = log_kernels(sigma_px)
    r = (g_np.size - 1) // 2
    x = images.float()
    b, c, h, w = x.shape
    x = pad_reflect101(x.reshape(b * c, h, w), r)
    g, g2 = [float(v) for v in g_np], [float(v) for v in g2_np]
    # Row filter first, then column filter, as cv2.sepFilter2D does; taps as shifted slices (fast on CPU and GPU).
    a = _filter_axis(_filter_axis(x, g2, axis=2, n=w), g, axis=1, n=h)  # d2/dx2
    bb = _filter_axis(_filter_axis(x, g, axis=2, n=w), g2, axis=1, n=h)  # d2/dy2
    return (a + bb).reshape(b, c, h, w)


def _filter_axis(x: torch.Tensor, taps: list[float], axis: int, n: int) -> torch.Tensor:
    """Correlate ``x`` with ``taps`` along ``axis`` (valid part, output length ``n``)."""
    out = x.narrow(axis, 0, n) * taps[0]
    for k in range(1, len(taps)):
        out.add_(x.narrow(axis, k, n), alpha=taps[k])
    return out
