"""Eq. (1) of the paper run backwards: the clean scene from a degraded image, its distance map and the water.

Eq. (1) degrades a clean scene ``J`` seen at distance ``d`` (metres) through water with a veil (ambient light)
``B_c`` and an attenuation ``a_c`` (1/m) per channel:

    I_c = J_c t_c + B_c (1 - t_c),    t_c = exp(-a_c d).

Given ``I``, ``d`` and an estimate of ``(B, a)`` (:mod:`murk.models.water`), :func:`invert_eq1` solves for ``J``
per pixel, with the transmission floored at ``t_min`` so that far, noisy pixels are not amplified without
bound. :func:`water_features` turns an image and its distance map into the fixed-length vector the water estimator
reads: image statistics in eight distance bins (what the veil adds grows with distance).

numpy and torch twins side by side (the torch one is training's loss path); ``tests/restore_ops/test_water.py``
pins them equal.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import cv2
import numpy as np

from murk.errors import ShapeError

if TYPE_CHECKING:
    from torch import Tensor

FEATURE_HW = (60, 80)
"""The size (height, width) image and distance are area-resampled to before :func:`water_features`."""

DISTANCE_BINS = 8
"""Quantile bins of the distance map in :func:`water_features`."""

FEATURES = DISTANCE_BINS * 10 + 6
"""Length of the feature vector: per bin the log median distance and 5/50/95th percentiles per channel; then the
mean and standard deviation per channel over the image."""

CONTRAST_LEFT = 0.05
"""The share of an object's contrast left at the visibility distance (:func:`visibility_m`): 5 %."""


def _check_pair(image: np.ndarray, distance_m: np.ndarray) -> None:
    if image.ndim != 3 or image.shape[2] != 3:
        raise ShapeError(f"image: expected (H, W, 3), got {image.shape}")
    if distance_m.shape != image.shape[:2]:
        raise ShapeError(
            f"distance_m: expected {image.shape[:2]} (the image's height and width), got {distance_m.shape}"
        )


def water_features(image: np.ndarray, distance_m: np.ndarray) -> np.ndarray:
    """The estimator's input: ``image`` (H, W, 3) in [0, 1] and ``distance_m`` (H, W), both area-resampled to
    :data:`FEATURE_HW`, then :data:`FEATURES` float32 numbers (see :data:`FEATURES`).

    Raises:
        ShapeError: ``image`` is not (H, W, 3) or ``distance_m`` not (H, W).
    """
    _check_pair(image, distance_m)
    h, w = FEATURE_HW
    small = cv2.resize(np.ascontiguousarray(image, np.float32), (w, h), interpolation=cv2.INTER_AREA)
    dist = cv2.resize(np.ascontiguousarray(distance_m, np.float32), (w, h), interpolation=cv2.INTER_AREA)
    d = dist.ravel().astype(np.float64)
    px = small.reshape(-1, 3).astype(np.float64)
    order = np.argsort(d, kind="stable")
    n = d.size
    out: list[float] = []
    for k in range(DISTANCE_BINS):
        sel = order[k * n // DISTANCE_BINS : (k + 1) * n // DISTANCE_BINS]
        out.append(math.log(max(float(np.median(d[sel])), 1e-2)))
        out.extend(np.percentile(px[sel], [5, 50, 95], axis=0).ravel().tolist())
    out.extend(px.mean(0).tolist())
    out.extend(px.std(0).tolist())
    return np.asarray(out, np.float32)


def transmission(distance_m: np.ndarray, attenuation_per_m: np.ndarray, t_min: float) -> np.ndarray:
    """``max(exp(-a_c d), t_min)`` per pixel and channel: (H, W, 3) float32."""
    a = np.asarray(attenuation_per_m, np.float32).reshape(1, 1, 3)
    t = np.exp(-a * distance_m[..., None].astype(np.float32))
    return np.maximum(t, np.float32(t_min))


def invert_eq1(
    image: np.ndarray, distance_m: np.ndarray, veil: np.ndarray, attenuation_per_m: np.ndarray, t_min: float = 0.1
) -> np.ndarray:
    """``J = (I - B (1 - t)) / t`` clipped to [0, 1], with ``t`` from :func:`transmission`.

    ``image`` (H, W, 3) in [0, 1]; ``distance_m`` (H, W); ``veil`` and ``attenuation_per_m`` three numbers each (RGB);
    ``t_min`` in (0, 1]. Returns float32 (H, W, 3).

    Raises:
        ShapeError: the shapes above do not hold.
        ValueError: ``t_min`` outside (0, 1].
    """
    _check_pair(image, distance_m)
    if not 0.0 < t_min <= 1.0:
        raise ValueError(f"t_min: expected a transmission floor in (0, 1], got {t_min!r}")
    t = transmission(distance_m, attenuation_per_m, t_min)
    b = np.asarray(veil, np.float32).reshape(1, 1, 3)
    return np.clip((image.astype(np.float32) - b * (1.0 - t)) / t, 0.0, 1.0)


def invert_eq1_torch(
    images: Tensor, distance_m: Tensor, veil: Tensor, attenuation_per_m: Tensor, t_min: float = 0.1
) -> Tensor:
    """Torch twin of :func:`invert_eq1` for a batch: ``images`` (N, H, W, 3), ``distance_m`` (N, H, W), ``veil`` and
    ``attenuation_per_m`` (N, 3). Differentiable in the water (training's loss path)."""
    import torch

    t = torch.exp(-attenuation_per_m[:, None, None, :] * distance_m[..., None]).clamp(min=t_min)
    return ((images - veil[:, None, None, :] * (1.0 - t)) / t).clamp(0.0, 1.0)


def visibility_m(attenuation_per_m: np.ndarray) -> float:
    """The distance at which the clearest channel keeps :data:`CONTRAST_LEFT` of an object's contrast:
    ``ln(1 / 0.05) / min_c a_c`` metres (3.0 / a)."""
    a = float(np.min(np.asarray(attenuation_per_m, np.float64)))
    return math.log(1.0 / CONTRAST_LEFT) / max(a, 1e-6)
