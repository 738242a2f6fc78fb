"""Joint-ID's training augmentations, batched on the training device.

Per sample (the original recipe): rotation by U(-3.5, 3.5) degrees (bicubic for images, nearest for depth,
corners become 0), horizontal flip with p = 0.5 (input, target and depth together; murk adds an up-down flip,
``augment.vflip_p``, 0 by default), and on the INPUT only,
with p = 0.7, brightness x U(0.5, 1.1) then per-channel x U(0.9, 1.1), clipped to [0, 1]. Depth above
600 m is marked invalid (0). The centre crop to the training size happens when samples are loaded
(:func:`centre_crop`).

Randomness is explicit: :func:`sample_augment` draws the parameters from a ``torch.Generator`` (seeded per
training step by the trainer, so a resumed run draws the same values); :func:`apply_augment` is deterministic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from murk.train.config import AugmentConfig


@dataclass(frozen=True)
class AugmentParams:
    """Per-sample augmentation parameters, (B,) or (B, 3) CPU tensors."""

    angle_deg: Tensor
    flip: Tensor
    color: Tensor
    brightness: Tensor
    gain: Tensor
    vflip: Tensor | None = None
    """Per-sample up-down flip; None: none."""


def sample_augment(batch: int, config: AugmentConfig, generator: torch.Generator) -> AugmentParams:
    """Draw the augmentation parameters of a batch from ``generator`` (CPU)."""

    def u(lo: float, hi: float, *shape: int) -> Tensor:
        return lo + (hi - lo) * torch.rand(*shape, generator=generator, dtype=torch.float64)

    return AugmentParams(
        angle_deg=u(-config.rotate_deg, config.rotate_deg, batch),
        flip=torch.rand(batch, generator=generator, dtype=torch.float64) < config.flip_p,
        color=torch.rand(batch, generator=generator, dtype=torch.float64) < config.color_p,
        brightness=u(*config.brightness, batch),
        gain=u(*config.channel_gain, batch, 3),
        vflip=torch.rand(batch, generator=generator, dtype=torch.float64) < config.vflip_p,
    )


def _rotate(x: Tensor, angle_deg: Tensor, mode: str) -> Tensor:
    b, _, h, w = x.shape
    a = angle_deg.to(x.device, torch.float64) * (math.pi / 180.0)
    cos, sin = torch.cos(a), torch.sin(a)
    # normalised coordinates: keep pixels square for non-square images
    theta = torch.zeros(b, 2, 3, dtype=torch.float64, device=x.device)
    theta[:, 0, 0] = cos
    theta[:, 0, 1] = -sin * h / w
    theta[:, 1, 0] = sin * w / h
    theta[:, 1, 1] = cos
    grid = F.affine_grid(theta.to(x.dtype), list(x.shape), align_corners=False)
    return F.grid_sample(x, grid, mode=mode, padding_mode="zeros", align_corners=False)


def apply_augment(
    inputs: Tensor, targets: Tensor, depth_m: Tensor, params: AugmentParams, config: AugmentConfig
) -> tuple[Tensor, Tensor, Tensor]:
    """Apply ``params`` to a batch: inputs and targets (B, 3, H, W) in [0, 1], depth (B, 1, H, W) metres."""
    if not config.enabled:
        return inputs, targets, depth_m
    inputs = _geometric(inputs, params, "bicubic").clamp(0.0, 1.0)
    targets = _geometric(targets, params, "bicubic").clamp(0.0, 1.0)
    depth_m = _geometric(depth_m, params, "nearest")
    colour = params.color.to(inputs.device).view(-1, 1, 1, 1)
    scale = (params.brightness.view(-1, 1) * params.gain).to(inputs).view(-1, 3, 1, 1)
    inputs = torch.where(colour, (inputs * scale).clamp(0.0, 1.0), inputs)
    depth_m = torch.where(depth_m > config.max_depth_m, torch.zeros_like(depth_m), depth_m)
    return inputs, targets, depth_m


def augment_map(values: Tensor, params: AugmentParams, config: AugmentConfig) -> Tensor:
    """The geometric part of :func:`apply_augment` (rotation, bilinear; flip) for a per-pixel map (B, 1, H, W) that
    must stay aligned with the inputs and targets, e.g. the marine-snow alpha that weights ``loss.snow``."""
    return _geometric(values, params, "bilinear") if config.enabled else values


def _geometric(x: Tensor, params: AugmentParams, mode: str) -> Tensor:
    """Rotation (interpolated with ``mode``), then the horizontal and the up-down flip, of a batch (B, C, H, W)."""
    x = _rotate(x, params.angle_deg, mode)
    flip = params.flip.to(x.device).view(-1, 1, 1, 1)
    x = torch.where(flip, x.flip(-1), x)
    if params.vflip is None or not bool(params.vflip.any()):
        return x
    return torch.where(params.vflip.to(x.device).view(-1, 1, 1, 1), x.flip(-2), x)


def centre_crop(arrays: list[np.ndarray], size_hw: tuple[int, int], *, source: str = "sample") -> list[np.ndarray]:
    """Centre-crop (H, W, ...) arrays to ``size_hw``. Raises ValueError naming ``source`` if one is smaller."""
    th, tw = size_hw
    out = []
    for a in arrays:
        h, w = a.shape[:2]
        if h < th or w < tw:
            raise ValueError(f"{source}: image {w}x{h} is smaller than the training size {tw}x{th}")
        y0, x0 = (h - th) // 2, (w - tw) // 2
        out.append(np.ascontiguousarray(a[y0 : y0 + th, x0 : x0 + tw]))
    return out
