"""Marine snow as a foreground layer, Eqs. (7)-(8) of the paper, vectorised (numpy) with a torch twin.

Per image, ``N_p`` particles are drawn with replacement from a bank, placed uniformly, each resized by its own
``s ~ U[0.3, 0.6]``; ``rho ~ U[0.2, 1.0]`` px smooths the mask (paper, Sec. 5.1).

Rendering without a per-particle loop: every mask pixel of every drawn particle is a point of mass ``s^2``
(its area after resizing) placed at ``centre + s * offset`` and splatted bilinearly onto the pixel grid (for
``s > 1`` each source pixel is split into ``ceil(s)^2`` sub-points first, so enlarged particles have no holes).
One ``bincount`` gives the coverage ``C`` and one per channel the colour mass ``Q = sum(mass * M)``. Then

- ``B = min(C, 1)``: the (antialiased) binary mask; overlapping particles average their colours
  (``B M = Q * B / C``);
- Eq. (8): ``a_ms = G_rho * B`` (normalised Gaussian, so ``a_ms`` stays in [0, 1]);
- Eq. (7): ``I_ms = (1 - a_ms) I_fs + a_ms M'`` where ``a_ms M' = G_rho * (B M)``: the particle colour is
  spread by the same Gaussian (normalised convolution), so particle edges fade to the particle's own colour
  instead of to black.

``a_ms`` is returned: it is the label a snow-removal model needs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import torch

from murk.physics.forward_scatter import gaussian_blur, gaussian_blur_torch
from murk.rng import RngLike, as_generator
from murk.snow.bank import ParticleBank


@dataclass(frozen=True)
class SnowParams:
    """Eqs. (7)-(8) parameters of one image: counts and ranges plus the seed of the particle layout (which
    particles, where, at which scale), so the layout need not be stored to re-render."""

    n_particles: int
    rho_px: float
    scale_range: tuple[float, float]
    layout_seed: int
    bank_id: str
    reference_width_px: int = 0
    """If > 0, scales are multiplied by (image width / reference_width_px)."""


@dataclass(frozen=True)
class SnowLayout:
    """The drawn particles of one image: bank indices, scales, centres (x, y in pixels)."""

    index: np.ndarray
    scale: np.ndarray
    centre_xy: np.ndarray


def sample_snow(
    rng: RngLike,
    bank: ParticleBank,
    *,
    n_particles: tuple[int, int] = (1000, 1600),
    scale: tuple[float, float] = (0.3, 0.6),
    rho_px: tuple[float, float] = (0.2, 1.0),
    reference_width_px: int = 0,
) -> SnowParams:
    """Draw N_p ~ U{a..b}, rho ~ U[a, b] and the layout seed of one image."""
    g = as_generator(rng)
    return SnowParams(
        n_particles=int(g.integers(n_particles[0], n_particles[1] + 1)),
        rho_px=float(g.uniform(*rho_px)),
        scale_range=(float(scale[0]), float(scale[1])),
        layout_seed=int(g.integers(0, 2**63 - 1)),
        bank_id=bank.bank_id,
        reference_width_px=int(reference_width_px),
    )


def snow_layout(params: SnowParams, bank_size: int, width: int, height: int) -> SnowLayout:
    """The deterministic particle layout of ``params`` for an image of ``width`` x ``height``."""
    if bank_size < 1:
        raise ValueError("bank: expected at least one particle, got an empty bank")
    g = np.random.default_rng(params.layout_seed)
    n = params.n_particles
    index = g.integers(0, bank_size, size=n)
    scale = g.uniform(params.scale_range[0], params.scale_range[1], size=n)
    if params.reference_width_px > 0:
        scale = scale * (width / params.reference_width_px)
    centre = g.uniform(0.0, 1.0, size=(n, 2)) * np.array([width, height], np.float64) - 0.5
    return SnowLayout(index, scale, centre)


def _splat_points(layout: SnowLayout, bank: ParticleBank) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sub-points of all drawn particles: (y, x) float64, mass, and bank pixel index of each."""
    idx = layout.index
    counts = bank.areas_px[idx]
    total = int(counts.sum())
    if total == 0:
        z = np.zeros(0)
        return z, z, z, np.zeros(0, np.int64)
    owner = np.repeat(np.arange(len(idx)), counts)
    starts = bank.offsets[idx]
    pix = np.arange(total) - np.repeat(np.cumsum(counts) - counts, counts) + np.repeat(starts, counts)
    s = layout.scale[owner]
    m = max(1, math.ceil(float(layout.scale.max()))) if len(layout.scale) else 1
    off = bank.pixel_yx[pix].astype(np.float64)
    ys = layout.centre_xy[owner, 1] + s * off[:, 0]
    xs = layout.centre_xy[owner, 0] + s * off[:, 1]
    mass = s * s
    if m > 1:  # split each source pixel into m x m sub-points so enlarged particles stay solid
        sub = (np.arange(m) + 0.5) / m - 0.5
        dy, dx = np.meshgrid(sub, sub, indexing="ij")
        ys = (ys[:, None] + s[:, None] * dy.ravel()).ravel()
        xs = (xs[:, None] + s[:, None] * dx.ravel()).ravel()
        mass = np.repeat(mass / (m * m), m * m)
        pix = np.repeat(pix, m * m)
    return ys, xs, mass, pix


def _bilinear_taps(ys: np.ndarray, xs: np.ndarray, h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat pixel index and bilinear weight of the 4 taps of each point, tap-major ((4N,) each);
    out-of-image taps get weight 0 (and index 0)."""
    y0, x0 = np.floor(ys), np.floor(xs)
    fy, fx = ys - y0, xs - x0
    yy = y0.astype(np.int64)[None, :] + np.array([0, 0, 1, 1])[:, None]
    xx = x0.astype(np.int64)[None, :] + np.array([0, 1, 0, 1])[:, None]
    wy = np.stack([1.0 - fy, 1.0 - fy, fy, fy])
    wx = np.stack([1.0 - fx, fx, 1.0 - fx, fx])
    inside = (yy >= 0) & (yy < h) & (xx >= 0) & (xx < w)
    idx = np.where(inside, yy * w + xx, 0).ravel()
    wts = np.where(inside, wy * wx, 0.0).ravel()
    return idx, wts


def snow_layers(params: SnowParams, bank: ParticleBank, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """The unsmoothed mask ``B`` (H, W) and ``B M`` (H, W, 3), float32, of one image."""
    layout = snow_layout(params, len(bank), width, height)
    ys, xs, mass, pix = _splat_points(layout, bank)
    flat, wt = _bilinear_taps(ys, xs, height, width)
    wt = wt * np.tile(mass, 4)
    cols = np.tile(pix, 4)
    n = height * width
    cover = np.bincount(flat, weights=wt, minlength=n)
    # Where particles overlap (cover > 1) their colours are averaged: scale each tap by 1 / max(cover, 1) at its
    # own pixel (done on the taps, not on the whole image). One bincount over interleaved (pixel, channel)
    # indices yields B*M directly in (H, W, 3) order.
    wt_c = wt * ((1.0 / 255.0) / np.maximum(cover[flat], 1.0))
    qw = (bank.pixel_rgb[cols] * wt_c[:, None]).ravel()
    qi = (flat[:, None] * 3 + np.arange(3)).ravel()
    bm = np.bincount(qi, weights=qw, minlength=3 * n).astype(np.float32).reshape(height, width, 3)
    b = np.minimum(cover, 1.0).astype(np.float32).reshape(height, width)
    return b, bm


def composite_snow(image: np.ndarray, params: SnowParams, bank: ParticleBank) -> tuple[np.ndarray, np.ndarray]:
    """Implements Eqs. (7)-(8) on one float32 RGB image (H, W, 3) in [0, 1]. Returns ``(I_ms, a_ms)``."""
    h, w, _ = image.shape
    if params.bank_id and bank.bank_id and params.bank_id != bank.bank_id:
        raise ValueError(f"bank: the parameters were drawn from bank {params.bank_id}, got bank {bank.bank_id}")
    b, bm = snow_layers(params, bank, h, w)
    alpha = gaussian_blur(b, params.rho_px)  # Eq. (8): a_ms = G_rho * B
    spread = gaussian_blur(bm, params.rho_px)  # a_ms M' = G_rho * (B M)
    one_minus = cv2.cvtColor(np.float32(1.0) - alpha, cv2.COLOR_GRAY2BGR)
    out = cv2.multiply(np.ascontiguousarray(image, dtype=np.float32), one_minus)
    cv2.add(out, spread, out)  # Eq. (7): (1 - a) I_fs + a M'
    return out, np.clip(alpha, 0.0, 1.0)


def composite_snow_torch(
    images: torch.Tensor, params: Sequence[SnowParams], bank: ParticleBank
) -> tuple[torch.Tensor, torch.Tensor]:
    """Torch twin of :func:`composite_snow` for a batch (B, 3, H, W) on any device.

    Layouts are drawn on the CPU (they are tiny); splatting is one ``index_add_`` over the whole batch and the
    smoothing one grouped convolution. Returns ``(I_ms (B, 3, H, W), a_ms (B, 1, H, W))``.
    """
    bsz, _, h, w = images.shape
    if len(params) != bsz:
        raise ValueError(f"params: expected {bsz} snow parameter sets (one per image), got {len(params)}")
    dev = images.device
    flats, wts, cols = [], [], []
    for i, p in enumerate(params):
        layout = snow_layout(p, len(bank), w, h)
        ys, xs, mass, pix = _splat_points(layout, bank)
        flat, wt = _bilinear_taps(ys, xs, h, w)
        flats.append(flat + i * h * w)
        wts.append(wt * np.tile(mass, 4))
        cols.append(np.tile(pix, 4))
    flat_t = torch.from_numpy(np.concatenate(flats)).to(dev)
    wt_t = torch.from_numpy(np.concatenate(wts)).to(dev, torch.float32)
    colour = torch.from_numpy(bank.pixel_rgb).to(dev, torch.float32) / 255.0
    col_t = colour[torch.from_numpy(np.concatenate(cols)).to(dev)]
    acc = torch.zeros(bsz * h * w, 4, device=dev, dtype=torch.float32)
    acc.index_add_(0, flat_t, torch.cat([wt_t[:, None], wt_t[:, None] * col_t], dim=1))
    cover, q = acc[:, 0], acc[:, 1:]
    b = cover.clamp(max=1.0)
    bm = q * torch.where(cover > 1.0, 1.0 / cover.clamp(min=1e-12), torch.ones_like(cover))[:, None]
    b = b.view(bsz, 1, h, w)
    bm = bm.view(bsz, h, w, 3).permute(0, 3, 1, 2)
    rho = torch.tensor([p.rho_px for p in params], dtype=torch.float64)
    alpha = gaussian_blur_torch(b, rho)  # Eq. (8)
    spread = gaussian_blur_torch(bm.contiguous(), rho)
    out = images.to(torch.float32) * (1.0 - alpha) + spread  # Eq. (7)
    return out.to(images.dtype), alpha.clamp(0.0, 1.0).to(images.dtype)
