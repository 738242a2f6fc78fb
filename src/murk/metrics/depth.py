"""Depth-estimation errors with Joint-ID's evaluator conventions (the usual monocular-depth set).

For one image: the prediction is clipped to [min_depth_m, max_depth_m] (0.001-15 m; NaN -> min, +inf -> max),
ground-truth pixels are valid where min_depth_m < gt < max_depth_m, and over the valid pixels

- ``silog`` = 100 sqrt(mean(e^2) - mean(e)^2) with e = ln(pred) - ln(gt) (scale-invariant log error x 100),
- ``abs_rel`` = mean(|gt - pred| / gt), ``sq_rel`` = mean((gt - pred)^2 / gt),
- ``abs_rel_median`` = ``abs_rel`` after the prediction is scaled by median(gt) / median(pred) (then clipped
  again): the error in the map's shape once its overall scale is forgiven, as monocular-depth work scores
  scale-ambiguous predictions (medians are the lower median of the valid pixels, ``(n - 1) // 2``),
- ``rmse`` = sqrt(mean((gt - pred)^2)) in metres, ``log_rmse`` = sqrt(mean((ln gt - ln pred)^2)),
- ``log10`` = mean(|log10 gt - log10 pred|),
- ``d1``, ``d2``, ``d3`` = fraction of pixels with max(gt/pred, pred/gt) < 1.25, 1.25^2, 1.25^3.

A dataset score is the mean of the per-image values (:func:`mean_depth_errors`), as Joint-ID reports it.

References:
    D. Eigen, C. Puhrsch, R. Fergus, "Depth Map Prediction from a Single Image using a Multi-Scale Deep
    Network", NeurIPS 2014 (the error set and SILog).
    G. Yang, G. Kang, J. Lee, Y. Cho, "Joint-ID: Transformer-Based Joint Image Enhancement and Depth
    Estimation for Underwater Environments", IEEE Sensors J., 2023, doi:10.1109/JSEN.2023.3338730 (range and
    clipping conventions).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, fields
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from murk._checks import check_positive
from murk.errors import ShapeError
from murk.metrics._common import check_real_array

if TYPE_CHECKING:
    import torch

MIN_DEPTH_M = 1e-3
MAX_DEPTH_M = 15.0
DEPTH_ERROR_NAMES = ("silog", "abs_rel", "abs_rel_median", "sq_rel", "rmse", "log_rmse", "log10", "d1", "d2", "d3")


@dataclass(frozen=True)
class DepthErrors:
    """Depth errors of one image (or their mean over images); see the module docstring for definitions."""

    silog: float
    abs_rel: float
    abs_rel_median: float
    sq_rel: float
    rmse: float
    log_rmse: float
    log10: float
    d1: float
    d2: float
    d3: float

    def as_dict(self) -> dict[str, float]:
        """The fields as a plain dict (for tables and JSON)."""
        return asdict(self)


class DepthErrorsBatch(NamedTuple):
    """Per-image depth errors of a batch: float64 tensors (B,) on the input's device."""

    silog: torch.Tensor
    abs_rel: torch.Tensor
    abs_rel_median: torch.Tensor
    sq_rel: torch.Tensor
    rmse: torch.Tensor
    log_rmse: torch.Tensor
    log10: torch.Tensor
    d1: torch.Tensor
    d2: torch.Tensor
    d3: torch.Tensor


def valid_depth(gt_m: np.ndarray, min_depth_m: float = MIN_DEPTH_M, max_depth_m: float = MAX_DEPTH_M) -> np.ndarray:
    """The ground-truth pixels the depth errors count: finite and in (``min_depth_m``, ``max_depth_m``)."""
    return np.isfinite(gt_m) & (gt_m > min_depth_m) & (gt_m < max_depth_m)


def valid_depth_torch(
    gt_m: torch.Tensor, min_depth_m: float = MIN_DEPTH_M, max_depth_m: float = MAX_DEPTH_M
) -> torch.Tensor:
    """The twin of :func:`valid_depth` for tensors (a training batch: which images hold a depth target at all)."""
    import torch

    return torch.isfinite(gt_m) & (gt_m > min_depth_m) & (gt_m < max_depth_m)


def _check_limits(min_depth_m: float, max_depth_m: float) -> tuple[float, float]:
    lo = check_positive("min_depth_m", min_depth_m)
    hi = check_positive("max_depth_m", max_depth_m)
    if not lo < hi:
        raise ValueError(f"min_depth_m, max_depth_m: expected min_depth_m < max_depth_m, got ({lo:g}, {hi:g})")
    return lo, hi


def _drop_channel_axis(a: np.ndarray) -> np.ndarray:
    """(H, W, 1) or (1, H, W) -> (H, W); anything else unchanged."""
    if a.ndim == 3 and a.shape[2] == 1:
        return a[:, :, 0]
    if a.ndim == 3 and a.shape[0] == 1:
        return a[0]
    return a


def _check_depth_pair_numpy(pred_m: Any, gt_m: Any) -> tuple[np.ndarray, np.ndarray]:
    for name, a in (("pred_m", pred_m), ("gt_m", gt_m)):
        check_real_array(name, a, "(H, W) in metres")
    p, g = _drop_channel_axis(pred_m), _drop_channel_axis(gt_m)
    if g.ndim != 2:
        raise ShapeError(f"gt_m: expected shape (H, W), got {gt_m.shape}")
    if p.shape != g.shape:
        raise ShapeError(f"pred_m: expected the shape of gt_m {g.shape}, got {pred_m.shape}")
    return p.astype(np.float64), g.astype(np.float64)


def depth_errors(
    pred_m: np.ndarray, gt_m: np.ndarray, *, min_depth_m: float = MIN_DEPTH_M, max_depth_m: float = MAX_DEPTH_M
) -> DepthErrors:
    """Depth errors of one predicted depth map against ground truth (Joint-ID's conventions).

    Args:
        pred_m: predicted depth (H, W) in metres ((H, W, 1) and (1, H, W) are accepted).
        gt_m: ground-truth depth (H, W) in metres; pixels outside (min_depth_m, max_depth_m), NaN or inf are
            not evaluated.
        min_depth_m: lower clip of the prediction and exclusive lower bound of valid ground truth.
        max_depth_m: upper clip of the prediction and exclusive upper bound of valid ground truth.

    Returns:
        A frozen :class:`DepthErrors`.

    Raises:
        TypeError: not numpy arrays of a real dtype.
        ShapeError: ``gt_m`` not 2-D or ``pred_m`` of another shape.
        ValueError: bad limits, or no valid ground-truth pixel (nothing to evaluate).
    """
    lo, hi = _check_limits(min_depth_m, max_depth_m)
    pred, gt = _check_depth_pair_numpy(pred_m, gt_m)
    valid = valid_depth(gt, lo, hi)
    n = int(np.count_nonzero(valid))
    if n == 0:
        raise ValueError(f"gt_m: no valid pixel (finite and in ({lo:g}, {hi:g}) m); nothing to evaluate")
    pred = np.where(np.isnan(pred), lo, pred)
    p = np.clip(pred, lo, hi)[valid]
    g = gt[valid]
    thresh = np.maximum(g / p, p / g)
    diff = g - p
    e = np.log(p) - np.log(g)
    var = max(float(np.mean(e * e)) - float(np.mean(e)) ** 2, 0.0)  # >= 0 up to rounding
    k = (n - 1) // 2
    scaled = np.clip(p * (np.partition(g, k)[k] / np.partition(p, k)[k]), lo, hi)
    return DepthErrors(
        silog=100.0 * math.sqrt(var),
        abs_rel=float(np.mean(np.abs(diff) / g)),
        abs_rel_median=float(np.mean(np.abs(g - scaled) / g)),
        sq_rel=float(np.mean(diff * diff / g)),
        rmse=math.sqrt(float(np.mean(diff * diff))),
        log_rmse=math.sqrt(float(np.mean(e * e))),
        log10=float(np.mean(np.abs(np.log10(g) - np.log10(p)))),
        d1=float(np.mean(thresh < 1.25)),
        d2=float(np.mean(thresh < 1.25**2)),
        d3=float(np.mean(thresh < 1.25**3)),
    )


def mean_depth_errors(items: Sequence[DepthErrors]) -> DepthErrors:
    """The per-field mean over images (how Joint-ID reports a dataset).

    Raises:
        ValueError: ``items`` is empty.
    """
    if len(items) == 0:
        raise ValueError("items: expected at least one DepthErrors, got an empty sequence")
    return DepthErrors(**{f.name: float(np.mean([getattr(i, f.name) for i in items])) for f in fields(DepthErrors)})


def depth_errors_torch(
    pred_m: torch.Tensor,
    gt_m: torch.Tensor,
    *,
    min_depth_m: float = MIN_DEPTH_M,
    max_depth_m: float = MAX_DEPTH_M,
) -> DepthErrorsBatch:
    """Per-image depth errors of batches (B, H, W) or (B, 1, H, W) in metres; twin of :func:`depth_errors`.

    Returns:
        :class:`DepthErrorsBatch` of float64 tensors (B,). Take ``.mean()`` of a field for the dataset score.

    Raises:
        TypeError: not tensors of a real dtype.
        ShapeError: shapes differ or are not (B, H, W) / (B, 1, H, W).
        ValueError: bad limits, or an image without any valid ground-truth pixel (costs one synchronisation).
    """
    import torch

    lo, hi = _check_limits(min_depth_m, max_depth_m)
    for name, a in (("pred_m", pred_m), ("gt_m", gt_m)):
        if not isinstance(a, torch.Tensor):
            raise TypeError(f"{name}: expected a torch.Tensor of shape (B, H, W) in metres, got {type(a).__name__}")
        if a.dtype == torch.bool or a.is_complex():
            raise TypeError(f"{name}: expected an integer or float tensor, got dtype {a.dtype}")
    if gt_m.ndim == 4 and gt_m.shape[1] == 1:
        gt_m = gt_m[:, 0]
    if pred_m.ndim == 4 and pred_m.shape[1] == 1:
        pred_m = pred_m[:, 0]
    if gt_m.ndim != 3:
        raise ShapeError(f"gt_m: expected shape (B, H, W) or (B, 1, H, W), got {tuple(gt_m.shape)}")
    if pred_m.shape != gt_m.shape:
        raise ShapeError(f"pred_m: expected the shape of gt_m {tuple(gt_m.shape)}, got {tuple(pred_m.shape)}")
    pred = pred_m.detach().double().flatten(1)
    gt = gt_m.detach().double().flatten(1)
    valid = valid_depth_torch(gt, lo, hi)
    n = valid.sum(dim=1)
    if bool((n == 0).any()):
        bad = torch.nonzero(n == 0).flatten().tolist()
        raise ValueError(f"gt_m: images {bad} have no valid pixel (finite and in ({lo:g}, {hi:g}) m)")
    nf = n.double()
    p = torch.nan_to_num(pred, nan=lo).clamp(lo, hi)
    g = torch.where(valid, gt, 1.0)
    p = torch.where(valid, p, 1.0)  # invalid pixels: p = g = 1, masked out of every sum below

    def vmean(v: torch.Tensor) -> torch.Tensor:
        return torch.where(valid, v, 0.0).sum(dim=1) / nf

    thresh = torch.maximum(g / p, p / g)
    diff = g - p
    e = torch.log(p) - torch.log(g)
    var = (vmean(e * e) - vmean(e) ** 2).clamp_min(0.0)
    nan = torch.tensor(math.nan, dtype=p.dtype, device=p.device)
    scale = torch.where(valid, g, nan).nanmedian(dim=1).values / torch.where(valid, p, nan).nanmedian(dim=1).values
    scaled = (p * scale[:, None]).clamp(lo, hi)
    return DepthErrorsBatch(
        silog=100.0 * torch.sqrt(var),
        abs_rel=vmean(diff.abs() / g),
        abs_rel_median=vmean((g - scaled).abs() / g),
        sq_rel=vmean(diff * diff / g),
        rmse=torch.sqrt(vmean(diff * diff)),
        log_rmse=torch.sqrt(vmean(e * e)),
        log10=vmean((torch.log10(g) - torch.log10(p)).abs()),
        d1=vmean((thresh < 1.25).double()),
        d2=vmean((thresh < 1.25**2).double()),
        d3=vmean((thresh < 1.25**3).double()),
    )
