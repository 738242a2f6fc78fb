"""PSNR after the best global colour correction: what a restoration leaves that no global map can explain.

Each channel of the output is fitted to the same channel of the reference by least squares,
``a_c * pred_c + b_c`` (one gain and one offset per image and channel), clipped to ``[0, data_range]``, and
scored with PSNR against the reference. Any error a per-channel gain and offset can undo (a colour cast, a
level or contrast error, a white balance) is forgiven; what is left is local: haze that grows with distance,
forward-scattering blur, marine snow, texture. On synthetic water the reference is the TRUE clean scene, and
the score of the degraded input itself is the baseline: an oracle global map applied to the input.

The fit is the closed form of simple linear regression per channel, ``a = cov(pred, ref) / var(pred)``,
``b = mean(ref) - a mean(pred)`` (population moments in float64); a flat output channel (``var = 0``) gets
``a = 0``, ``b = mean(ref)``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from murk.errors import ShapeError
from murk.metrics._common import check_data_range, check_real_array

if TYPE_CHECKING:
    import torch


def affine_fit(pred: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """``pred`` (H, W, C) with each channel mapped by its least-squares gain and offset onto ``ref``'s, float64,
    not clipped.

    Raises:
        TypeError: not float or integer numpy arrays.
        ShapeError: shapes differ or are not (H, W, C).
    """
    for name, a in (("pred", pred), ("ref", ref)):
        check_real_array(name, a, "(H, W, C)")
        if a.ndim != 3 or a.size == 0:
            raise ShapeError(f"{name}: expected shape (H, W, C), got {a.shape}")
    if pred.shape != ref.shape:
        raise ShapeError(f"pred: expected the shape of ref {ref.shape}, got {pred.shape}")
    p = pred.astype(np.float64).reshape(-1, pred.shape[2])
    r = ref.astype(np.float64).reshape(-1, ref.shape[2])
    pm, rm = p.mean(axis=0), r.mean(axis=0)
    var = ((p - pm) ** 2).mean(axis=0)
    cov = ((p - pm) * (r - rm)).mean(axis=0)
    gain = np.where(var > 0, cov / np.where(var > 0, var, 1.0), 0.0)
    offset = rm - gain * pm
    return (p * gain + offset).reshape(pred.shape)


def affine_fit_psnr(pred: np.ndarray, ref: np.ndarray, *, data_range: float) -> float:
    """PSNR (dB) of ``pred`` after :func:`affine_fit` onto ``ref`` and clipping to ``[0, data_range]``.

    Args:
        pred: image (H, W, C), integer or float.
        ref: reference image of the same shape (the true clean scene, never a corrected copy of it).
        data_range: the value of full white (1.0 for [0, 1] images); required.

    Returns:
        PSNR in dB; ``inf`` when the fitted image equals ``ref``.
    """
    data_range = check_data_range(data_range)
    fitted = np.clip(affine_fit(pred, ref), 0.0, data_range)
    mse = float(np.mean((fitted - ref.astype(np.float64)) ** 2))
    return math.inf if mse == 0.0 else 10.0 * math.log10(data_range**2 / mse)


def affine_fit_psnr_torch(pred: torch.Tensor, ref: torch.Tensor, *, data_range: float) -> torch.Tensor:
    """Per-image :func:`affine_fit_psnr` of (B, C, H, W) batches: float64 tensor (B,); twin of the numpy function.

    Raises:
        TypeError: not tensors of a real dtype.
        ShapeError: shapes differ or are not (B, C, H, W).
    """
    import torch

    from murk.metrics.reference import _check_pair_torch  # the same batch contract as psnr_torch

    data_range = check_data_range(data_range)
    x, y = _check_pair_torch(pred, ref)
    p, r = x.flatten(2), y.flatten(2)
    pm, rm = p.mean(dim=2, keepdim=True), r.mean(dim=2, keepdim=True)
    var = ((p - pm) ** 2).mean(dim=2, keepdim=True)
    cov = ((p - pm) * (r - rm)).mean(dim=2, keepdim=True)
    gain = torch.where(var > 0, cov / torch.where(var > 0, var, 1.0), 0.0)
    fitted = (p * gain + (rm - gain * pm)).clamp(0.0, data_range)
    mse = ((fitted - r) ** 2).flatten(1).mean(dim=1)
    safe = torch.where(mse > 0, mse, 1.0)
    return torch.where(mse > 0, 10.0 * torch.log10(data_range**2 / safe), math.inf)
