"""Joint-ID's training loss, kept exactly (the paper retrains with the original loss).

``loss = 2.0 * (L2 + 0.1 * Lap)(enhanced, clean) + 1.8 * SILog(depth, gt_depth)``

- ``L2`` is a row-wise Euclidean distance, not an MSE: for every (b, c, h) row,
  ``sqrt(sum_w (pred - gt + 1e-6)^2)``, averaged over the B*C*H rows.
- ``Lap``: the same distance between depthwise 3x3 Laplacian-filtered images (kernel
  [0,-1,0; -1,4,-1; 0,-1,0], zero padding 1).
- ``SILog``: on pixels with gt > 0.001, ``d = log(pred) - log(gt)``, ``10 sqrt(mean(d^2) - 0.85 mean(d)^2)``.
- An SSIM loss (window 11, sigma 1.5, weight 2.5) exists in the original but is disabled; it is available here
  with ``ssim_weight`` > 0.
- murk's addition, off by default: ``L2_snow`` (:func:`snow_l2`), the error on the pixels the training input's
  marine snow covers, weighted by ``loss.snow`` inside the enhancement term, so that particles left in the
  output cost more than their share of the pixels (the real-snow issue); and ``L2_teacher``, the same row-wise
  distance to a teacher's restoration of the input, weighted by ``loss.distill`` (distillation); and ``L2_local``
  (:func:`local_l2`), the row-wise distance that is left after the output's best gain and offset per image and
  channel onto the clean scene, weighted by ``loss.local``: the part of the error no global colour correction
  can remove (haze that grows with distance, blur, snow), so that a network cannot lower the loss by colour alone.

Reference: Yang, Kang, Lee, Cho, "Transformer-Based Joint Image Enhancement and Depth Estimation for Underwater
Environments", IEEE Sensors Journal 2023, doi:10.1109/JSEN.2023.3338730 (facts from docs/spec/jointid.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import Tensor

from murk.train.config import LossWeights

_LAPLACE = torch.tensor([[0.0, -1.0, 0.0], [-1.0, 4.0, -1.0], [0.0, -1.0, 0.0]])


def row_l2(pred: Tensor, target: Tensor) -> Tensor:
    """Row-wise Euclidean distance averaged over all (b, c, h) rows (Joint-ID's "L2")."""
    return torch.sqrt(((pred - target + 1e-6) ** 2).sum(dim=-1)).mean()


def snow_l2(pred: Tensor, target: Tensor, alpha: Tensor) -> Tensor:
    """The restoration error on the marine snow of the input, on the scale of :func:`row_l2`: with ``m`` the
    alpha-weighted mean squared error per channel over the particles (alpha (B, 1, H, W), Eq. 8), ``sqrt(W m)``,
    which is what :func:`row_l2` gives when every pixel of a row has that error. 0 when no particle is present."""
    w = alpha.to(pred.dtype)
    m = (w * (pred - target) ** 2).sum() / (w.sum() * pred.shape[1]).clamp(min=1e-8)
    return torch.sqrt(pred.shape[-1] * m + 1e-12)


def affine_fit_torch(pred: Tensor, target: Tensor) -> Tensor:
    """``pred`` (B, C, H, W) after the least-squares gain and offset per image and channel that map it onto
    ``target`` (the closed form of :func:`murk.metrics.affine_fit`, differentiable; the variance gets 1e-6 so that a
    flat channel has a gradient)."""
    p = pred.flatten(2)
    t = target.flatten(2)
    pm, tm = p.mean(dim=2, keepdim=True), t.mean(dim=2, keepdim=True)
    pc = p - pm
    gain = (pc * (t - tm)).mean(dim=2, keepdim=True) / ((pc * pc).mean(dim=2, keepdim=True) + 1e-6)
    return (pc * gain + tm).view_as(pred)


def local_l2(pred: Tensor, target: Tensor) -> Tensor:
    """:func:`row_l2` between ``target`` and ``pred`` after :func:`affine_fit_torch`: the error that no global colour
    map can undo."""
    return row_l2(affine_fit_torch(pred, target), target)


def local_mse(pred: Tensor, target: Tensor) -> Tensor:
    """Mean squared error between ``target`` and ``pred`` after :func:`affine_fit_torch` (the water estimator's
    loss, :mod:`murk.train.water`)."""
    return ((affine_fit_torch(pred, target) - target) ** 2).mean()


def laplacian(x: Tensor) -> Tensor:
    """Depthwise 3x3 Laplacian with zero padding."""
    c = x.shape[1]
    k = _LAPLACE.to(x).view(1, 1, 3, 3).repeat(c, 1, 1, 1)
    return F.conv2d(x, k, padding=1, groups=c)


def laplacian_l2(pred: Tensor, target: Tensor) -> Tensor:
    """Row-wise distance between Laplacian-filtered images."""
    return row_l2(laplacian(pred), laplacian(target))


def silog(pred_m: Tensor, gt_m: Tensor, *, lam: float = 0.85, min_m: float = 0.001) -> Tensor:
    """Scale-invariant log error (x10) over pixels with gt > ``min_m`` (invalid ground truth is 0)."""
    mask = gt_m > min_m
    if not bool(mask.any()):
        return pred_m.sum() * 0.0  # keeps the graph; no valid depth in this batch
    d = torch.log(pred_m[mask]) - torch.log(gt_m[mask])
    return 10.0 * torch.sqrt((d**2).mean() - lam * d.mean() ** 2)


def _gauss_window(size: int, sigma: float, channels: int, like: Tensor) -> Tensor:
    x = torch.arange(size, dtype=torch.float64) - (size - 1) / 2
    g = torch.exp(-(x**2) / (2 * sigma**2))
    g = g / g.sum()
    w = torch.outer(g, g).to(like)
    return w.expand(channels, 1, size, size).contiguous()


def ssim_index(x: Tensor, y: Tensor, *, window: int = 11, sigma: float = 1.5, data_range: float = 1.0) -> Tensor:
    """Mean SSIM (Gaussian window, valid region) of two (B, C, H, W) batches, differentiable."""
    c = x.shape[1]
    w = _gauss_window(window, sigma, c, x)
    mu_x, mu_y = F.conv2d(x, w, groups=c), F.conv2d(y, w, groups=c)
    sxx = F.conv2d(x * x, w, groups=c) - mu_x**2
    syy = F.conv2d(y * y, w, groups=c) - mu_y**2
    sxy = F.conv2d(x * y, w, groups=c) - mu_x * mu_y
    c1, c2 = (0.01 * data_range) ** 2, (0.03 * data_range) ** 2
    s = ((2 * mu_x * mu_y + c1) * (2 * sxy + c2)) / ((mu_x**2 + mu_y**2 + c1) * (sxx + syy + c2))
    return s.mean()


@dataclass(frozen=True)
class LossTerms:
    """The total loss and its parts (detached parts for logging)."""

    total: Tensor
    l2: Tensor
    lap: Tensor
    silog: Tensor
    ssim: Tensor
    snow: Tensor | None = None
    """``L2_snow`` when ``loss.snow`` > 0 and the inputs' snow alpha was given, else None."""
    distill: Tensor | None = None
    """``L2_teacher`` when ``loss.distill`` > 0 and the teacher's output was given, else None."""
    local: Tensor | None = None
    """``L2_local`` when ``loss.local`` > 0, else None."""


def jointid_loss(
    enhanced: Tensor,
    clean: Tensor,
    depth_m: Tensor | None,
    gt_depth_m: Tensor,
    weights: LossWeights = LossWeights(),
    snow_alpha: Tensor | None = None,
    teacher: Tensor | None = None,
) -> LossTerms:
    """The full training loss: ``2.0 * (L2 + 0.1 Lap) + 1.8 SILog`` (+ ``ssim * (1 - SSIM)`` when enabled; +
    ``enhance * snow * L2_snow`` when ``weights.snow`` > 0 and the inputs' marine-snow alpha ``snow_alpha``
    (B, 1, H, W) is given; + ``enhance * distill * L2(enhanced, teacher)`` when ``weights.distill`` > 0 and a
    teacher's restoration ``teacher`` of the same inputs is given; + ``enhance * local * L2_local`` when
    ``weights.local`` > 0).

    ``depth_m`` None (a network without a depth head, e.g. ``lite``): the SILog term is left out (0)."""
    l2 = row_l2(enhanced, clean)
    lap = laplacian_l2(enhanced, clean)
    enhance = l2 + weights.laplacian * lap
    snow = None
    if weights.snow > 0 and snow_alpha is not None:
        snow = snow_l2(enhanced, clean, snow_alpha)
        enhance = enhance + weights.snow * snow
    distill = None
    if weights.distill > 0 and teacher is not None:
        distill = row_l2(enhanced, teacher)
        enhance = enhance + weights.distill * distill
    local = None
    if weights.local > 0:
        local = local_l2(enhanced, clean)
        enhance = enhance + weights.local * local
    total = weights.enhance * enhance
    if depth_m is None:
        si = torch.zeros((), device=enhanced.device)
    else:
        si = silog(depth_m, gt_depth_m, lam=weights.silog_lambda, min_m=weights.depth_min_m)
        total = total + weights.depth * si
    ssim_term = torch.zeros((), device=enhanced.device)
    if weights.ssim > 0:
        ssim_term = 1.0 - ssim_index(enhanced, clean)
        total = total + weights.ssim * ssim_term
    return LossTerms(
        total,
        l2.detach(),
        lap.detach(),
        si.detach(),
        ssim_term.detach(),
        None if snow is None else snow.detach(),
        None if distill is None else distill.detach(),
        None if local is None else local.detach(),
    )
