"""Absorption and backscatter of the water medium, Eq. (1) of the paper, and the distance map it uses.

``I_c = J_c * T_c(d) + B_inf_c * (1 - T_c(d))`` with ``T_c(d) = exp(-beta_c d)`` (Beer-Lambert), ``J`` the
clean image, ``d`` the line-of-sight distance in metres and ``B_inf`` the homogeneous ambient (veiling) light.

Ambient light follows the scheme of Li et al. (Pattern Recognition 98, 2020, doi:10.1016/j.patcog.2019.107038):
``B_inf_c = 1.5 * N_c ** D`` for a vertical depth ``D`` below the surface (see :mod:`murk.physics.jerlov`).

References: Yun et al., "Robust Image Processing Techniques for Construction Environment Monitoring Using
Underwater Robots" (the source paper), Sec. III, Eq. (1); Akkaynak & Treibitz, "A revised underwater image
formation model", CVPR 2018, doi:10.1109/CVPR.2018.00703.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Literal

import cv2
import numpy as np

from murk.physics.jerlov import residual_ratio

if TYPE_CHECKING:
    import torch

DistanceMode = Literal["normalized", "metric"]


def ambient_light(water_type: str, vertical_depth_m: float, *, scale: float = 1.5) -> np.ndarray:
    """Ambient light ``B_inf_c = scale * N_c ** D`` (R, G, B) for water type and vertical depth ``D`` metres.

    Values can exceed 1 for clear water; the synthesis clips its output to [0, 1].
    """
    return (scale * residual_ratio(water_type) ** float(vertical_depth_m)).astype(np.float64)


def distance_map(
    depth_m: np.ndarray,
    *,
    mode: DistanceMode = "normalized",
    near_m: float = 0.3,
    far_m: float = 15.0,
    depth_max_m: float | None = None,
) -> np.ndarray:
    """Line-of-sight distance in metres used by Eq. (1), from a clean depth map.

    ``normalized``: ``dist = near_m + (depth / max(depth)) * (far_m - near_m)``: the scene is placed so that
    its farthest point is ``far_m`` away (relative or indoor depth becomes an underwater range).
    ``metric``: the true depth clipped to [near_m, far_m].

    ``depth_m`` must already be valid everywhere (see :func:`murk.io.resolve_invalid`). ``depth_max_m``: its
    maximum when the caller knows it (every variant of an image shares it), else it is computed.

    Every step is monotonic in the depth, also after float32 rounding, so the map's minimum and maximum are
    this function of the depth's minimum and maximum, exactly (:func:`distance_range`).
    """
    d = np.asarray(depth_m, dtype=np.float32)
    if mode == "metric":
        return np.clip(d, np.float32(near_m), np.float32(far_m))
    if mode != "normalized":
        raise ValueError(f"distance_mode: expected 'normalized' or 'metric', got {mode!r}")
    peak = float(d.max()) if depth_max_m is None else float(np.float32(depth_max_m))
    u = d * np.float32(1.0 / peak)
    return u * np.float32(far_m - near_m) + np.float32(near_m)


def distance_range(
    depth_min_m: float,
    depth_max_m: float,
    *,
    mode: DistanceMode = "normalized",
    near_m: float = 0.3,
    far_m: float = 15.0,
) -> tuple[float, float]:
    """(min, max) of :func:`distance_map` of a depth map with this minimum and maximum, without the map: the same
    float32 steps applied to the two values (exact, as every step is monotonic; decreasing if ``far_m < near_m``)."""
    ends = np.array([depth_min_m, depth_max_m], np.float32)
    dist = distance_map(ends, mode=mode, near_m=near_m, far_m=far_m, depth_max_m=depth_max_m)
    lo, hi = sorted((float(dist[0]), float(dist[1])))
    return lo, hi


def transmission(dist_m: np.ndarray, beta_per_m: np.ndarray) -> np.ndarray:
    """Per-channel transmission ``T_c = exp(-beta_c * d)``, float32 (H, W, 3). Implements T of Eq. (1)."""
    # Three interleaved copies of the map scaled per channel by OpenCV (a per-channel scalar), then one exp:
    # bit-identical to cv2.transform with a 3x1 matrix and 3.5x faster (its 1 -> 3 channel path is not vectorised),
    # and without numpy's slow length-3 inner loops.
    d = np.ascontiguousarray(dist_m, dtype=np.float32)
    scale = (*(float(v) for v in (-np.asarray(beta_per_m, np.float64)).astype(np.float32)), 0.0)
    t = cv2.merge([d, d, d])
    cv2.multiply(t, scale, t)  # type: ignore[call-overload]  # a 4-tuple is a per-channel scalar
    return cv2.exp(t, t)


def apply_medium(
    clean: np.ndarray, dist_m: np.ndarray, beta_per_m: np.ndarray, b_inf: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Implements Eq. (1): ``I = J * T + B_inf * (1 - T)``; returns ``(I_basic, T)``, float32 (H, W, 3).

    The result is not clipped (``B_inf`` may exceed 1); the pipeline clips once at the end.
    """
    t = transmission(dist_m, beta_per_m)
    b = (*(float(np.float32(v)) for v in b_inf), 0.0)  # per-channel scalar for OpenCV
    # (OpenCV takes a 4-tuple as a per-channel scalar; its type stubs do not say so.)
    out = cv2.subtract(np.ascontiguousarray(clean, dtype=np.float32), b)  # type: ignore[call-overload]
    cv2.multiply(out, t, out)
    cv2.add(out, b, out)  # type: ignore[call-overload]  # Eq. (1): (J - B) T + B
    return out, t


# ----------------------------------------------------------------------------------------------- torch twin


def distance_map_torch(
    depth_m: torch.Tensor, near_m: torch.Tensor, far_m: torch.Tensor, *, mode: DistanceMode = "normalized"
) -> torch.Tensor:
    """Torch twin of :func:`distance_map` for a batch: depth (B, 1, H, W); near/far (B,) metres."""
    import torch

    near = near_m.view(-1, 1, 1, 1).to(depth_m)
    far = far_m.view(-1, 1, 1, 1).to(depth_m)
    if mode == "metric":
        return torch.minimum(torch.maximum(depth_m, near), far)
    peak = depth_m.amax(dim=(1, 2, 3), keepdim=True)
    return depth_m / peak * (far - near) + near


def apply_medium_torch(
    clean: torch.Tensor, dist_m: torch.Tensor, beta_per_m: torch.Tensor, b_inf: torch.Tensor
) -> tuple[torch.Tensor, torch.Tensor]:
    """Torch twin of :func:`apply_medium`: clean (B, 3, H, W), dist (B, 1, H, W), beta and B_inf (B, 3).

    Implements Eq. (1). Returns ``(I_basic, T)``, both (B, 3, H, W), on the input's device and dtype.
    """
    import torch

    beta = beta_per_m.to(clean).view(-1, 3, 1, 1)
    b = b_inf.to(clean).view(-1, 3, 1, 1)
    t = torch.exp(-beta * dist_m)
    return (clean - b) * t + b, t  # Eq. (1)
