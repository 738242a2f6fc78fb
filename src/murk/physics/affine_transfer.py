"""Locally affine transfer of a restoration onto its input: the restoration's colours with the input's structure.

Under the image formation model (Eq. 1 of the paper), ``I_c = J_c t_c + B_c (1 - t_c)``. The clean image is then
``J_c = a_c I_c + b_c`` per channel, with ``a_c = 1 / t_c`` and ``b_c = -B_c (1 - t_c) / t_c``. Both vary only with
distance, smoothly except at depth edges. This module fits exactly that form to a restoration ``R`` of ``I``.

In every window of ``(2 r + 1)^2`` pixels each channel of ``R`` is fitted by least squares as ``a_c I_c + b_c``:
``a = cov(I, R) / (var(I) + eps)``, ``b = mean(R) - a mean(I)``. The coefficients are box-averaged and applied to
the input: ``out_c = mean(a_c) I_c + mean(b_c)``. This is He, Sun and Tang's guided filter, with the input as the
guide of each channel and the restoration as the filtered image.

The output keeps the input's edges and texture and takes the restoration's colour, level and haze removal. It
drops whatever the restoration does that is not locally affine in the input:
- network artefacts;
- deblurring (forward scattering stays);
- particles taken out (marine snow stays).

A large radius approaches one global affine map per channel. A small one approaches the restoration itself.

Reference: K. He, J. Sun, X. Tang, "Guided Image Filtering", IEEE TPAMI 35(6), 2013, doi:10.1109/TPAMI.2012.213.
"""

from __future__ import annotations

import cv2
import numpy as np


def guided_filter(guide: np.ndarray, src: np.ndarray, radius: int, eps: float) -> np.ndarray:
    """Guided filter (He et al. 2013, Alg. 1) with box means of side ``2 radius + 1`` (OpenCV's running-sum box
    filter: the cost does not grow with the radius; reflected borders). Element-wise: a grey ``guide`` with a
    grey ``src`` (UDCP's transmission refinement), or (H, W, 3) with (H, W, 3), each channel its own guide."""
    k = (2 * radius + 1, 2 * radius + 1)

    def mean(a: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(a, cv2.CV_32F, k, borderType=cv2.BORDER_REFLECT)

    mi, mp = mean(guide), mean(src)
    var = mean(guide * guide) - mi * mi
    a = (mean(guide * src) - mi * mp) / (var + np.float32(eps))
    b = mp - a * mi
    return (mean(a) * guide + mean(b)).astype(np.float32)


def transfer_radius_px(height: int, width: int, radius: float) -> int:
    """The window radius in pixels for ``radius`` given as a fraction of the image's long side, at least 1 and
    smaller than the short side."""
    r = round(float(radius) * max(height, width))
    return int(max(1, min(r, min(height, width) - 1)))


def affine_transfer(image: np.ndarray, restored: np.ndarray, radius_px: int, eps: float = 1e-4) -> np.ndarray:
    """The locally affine transfer (module doc) of ``restored`` onto ``image``, both float (H, W, 3) in [0, 1]:
    :func:`guided_filter` with ``image`` as the guide of each channel; float32 (H, W, 3), not clipped.

    Raises:
        ValueError: shapes differ or are not (H, W, 3), ``radius_px`` < 1, or ``eps`` <= 0.
    """
    img = np.asarray(image, np.float32)
    res = np.asarray(restored, np.float32)
    if img.ndim != 3 or img.shape[-1] != 3 or img.shape != res.shape:
        raise ValueError(f"image/restored: expected two (H, W, 3) arrays of one shape, got {img.shape}, {res.shape}")
    if isinstance(radius_px, bool) or int(radius_px) != radius_px or radius_px < 1:
        raise ValueError(f"radius_px: expected an integer >= 1, got {radius_px!r}")
    if not eps > 0:
        raise ValueError(f"eps: expected > 0, got {eps!r}")
    return guided_filter(img, res, int(radius_px), float(eps))
