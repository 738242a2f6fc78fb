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
from typing import TYPE_CHECKING

import cv2
import numpy as np

from murk.physics.forward_scatter import gaussian_blur, gaussian_blur_torch, kernel_radius
from murk.rng import RngLike, as_generator
from murk.snow.bank import ParticleBank

if TYPE_CHECKING:
    import torch


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
    reference_area_px: int = 0
    """If > 0, ``n_particles`` is a count per this many pixels: an image of ``H * W`` pixels gets
    ``round(n_particles * H * W / reference_area_px)`` particles (the same density at every crop size)."""
    particle_luma: tuple[float, float] | None = None
    """If set, each drawn particle is relit: its pixels become neutral grey with their own luma pattern, scaled
    so that the particle's mean Rec. 709 luma is ``U[a, b]`` (0-255), clipped at 255: particles lit by the
    vehicle's lamp or the sun, whatever the brightness of the frame they were cut from (the hue of dark footage
    is sensor noise that scaling would turn into coloured specks). None: the original pixels (the paper)."""


def particle_count(params: SnowParams, width: int, height: int) -> int:
    """The number of particles drawn for an image of ``width`` x ``height`` (see ``reference_area_px``)."""
    if params.reference_area_px > 0:
        return round(params.n_particles * width * height / params.reference_area_px)
    return params.n_particles


@dataclass(frozen=True)
class SnowLayout:
    """The drawn particles of one image: bank indices, scales, centres (x, y in pixels)."""

    index: np.ndarray
    scale: np.ndarray
    centre_xy: np.ndarray
    target_luma: np.ndarray | None = None
    """Per drawn particle: the mean luma (0-255) its colour is rescaled to (``particle_luma``; None: original)."""


def sample_snow(
    rng: RngLike,
    bank: ParticleBank,
    *,
    n_particles: tuple[int, int] = (1000, 1600),
    scale: tuple[float, float] = (0.3, 0.6),
    rho_px: tuple[float, float] = (0.2, 1.0),
    reference_width_px: int = 0,
    reference_area_px: int = 0,
    particle_luma: tuple[float, float] | None = None,
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
        reference_area_px=int(reference_area_px),
        particle_luma=None if particle_luma is None else (float(particle_luma[0]), float(particle_luma[1])),
    )


def snow_layout(params: SnowParams, bank_size: int, width: int, height: int) -> SnowLayout:
    """The deterministic particle layout of ``params`` for an image of ``width`` x ``height``."""
    if bank_size < 1:
        raise ValueError("bank: expected at least one particle, got an empty bank")
    g = np.random.default_rng(params.layout_seed)
    n = particle_count(params, width, height)
    index = g.integers(0, bank_size, size=n)
    scale = g.uniform(params.scale_range[0], params.scale_range[1], size=n)
    if params.reference_width_px > 0:
        scale = scale * (width / params.reference_width_px)
    centre = g.uniform(0.0, 1.0, size=(n, 2)) * np.array([width, height], np.float64) - 0.5
    target = None
    if params.particle_luma is not None:  # drawn last: the other draws stay as they were
        target = g.uniform(params.particle_luma[0], params.particle_luma[1], size=n)
    return SnowLayout(index, scale, centre, target)


def particle_lumas(bank: ParticleBank) -> np.ndarray:
    """Mean Rec. 709 luma (0-255) of each particle of ``bank``."""
    lum = bank.pixel_rgb.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    return np.add.reduceat(lum, bank.offsets[:-1]) / np.maximum(bank.areas_px, 1)


def _colours(layout: SnowLayout, bank: ParticleBank, pix: np.ndarray, owner: np.ndarray) -> np.ndarray:
    """The colour (0-255) of each splatted point: its bank pixel's, or grey rescaled to the particle's target
    luma (``particle_luma``)."""
    rgb = bank.pixel_rgb[pix]
    if layout.target_luma is None or len(pix) == 0:
        return rgb
    gain = layout.target_luma / np.maximum(particle_lumas(bank)[layout.index], 1.0)
    return relit_grey(rgb, gain[owner])


def relit_grey(rgb: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """Pixels (N, 3) 0-255 relit: neutral grey with their own Rec. 709 luma times ``gain`` (N,), clipped at 255;
    float32 (N, 3)."""
    lum = rgb.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    grey = np.minimum(lum * gain, 255.0).astype(np.float32)
    return np.repeat(grey[:, None], 3, axis=1)


def _splat_points(
    layout: SnowLayout, bank: ParticleBank
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sub-points of all drawn particles: (y, x) float64, mass, the colour of each (0-255, (N, 3))."""
    idx = layout.index
    counts = bank.areas_px[idx]
    total = int(counts.sum())
    if total == 0:
        z = np.zeros(0)
        return z, z, z, np.zeros((0, 3), np.float32), np.zeros(0, np.int64)
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
        owner = np.repeat(owner, m * m)
    return ys, xs, mass, _colours(layout, bank, pix, owner), pix


def _canvas_pad(layout: SnowLayout, bank: ParticleBank, rho_px: float) -> int:
    """Margin around the image so every tap of every drawn particle, and the blur around it, lands inside."""
    if len(layout.index) == 0:
        return 1
    reach = float(np.abs(bank.pixel_yx).max()) if len(bank.pixel_yx) else 0.0
    return math.ceil(reach * float(layout.scale.max())) + 2 + kernel_radius(rho_px)


def _taps(ys: np.ndarray, xs: np.ndarray, pad: int, wp: int) -> tuple[np.ndarray, np.ndarray]:
    """Flat canvas index and bilinear weight of the 4 taps of each point, tap-major ((4N,) each)."""
    y0, x0 = np.floor(ys), np.floor(xs)
    fy, fx = ys - y0, xs - x0
    base = (y0.astype(np.int64) + pad) * wp + (x0.astype(np.int64) + pad)
    idx = np.concatenate([base, base + 1, base + wp, base + wp + 1])
    gy, gx = 1.0 - fy, 1.0 - fx
    wts = np.concatenate([gy * gx, gy * fx, fy * gx, fy * fx])
    return idx, wts


def _accumulate(
    idx: np.ndarray, wts: np.ndarray, rgb: np.ndarray, n: int, device: torch.device
) -> tuple[torch.Tensor, torch.Tensor]:
    """Scatter-add the taps into a coverage canvas C and a colour canvas Q = sum(w * M / max(C, 1)).

    Uses torch's ``index_add_`` (also on the CPU: it accumulates in float32 without the full-size float64
    arrays that ``numpy.bincount`` returns). Colour weights are divided by max(C, 1) at their own pixel, so
    where particles overlap their colours are averaged.
    """
    import torch

    it = torch.from_numpy(idx).to(device)
    wt = torch.from_numpy(wts).to(device, torch.float32)
    cover = torch.zeros(n, device=device, dtype=torch.float32)
    cover.index_add_(0, it, wt)
    wc = wt / cover[it].clamp(min=1.0) * (1.0 / 255.0)
    q = torch.zeros(n, 3, device=device, dtype=torch.float32)
    q.index_add_(0, it, torch.from_numpy(rgb).to(device, torch.float32) * wc[:, None])
    return cover.clamp_(max=1.0), q


def _accumulate_np(idx: np.ndarray, wts: np.ndarray, rgb: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The numpy twin of :func:`_accumulate` (``numpy.bincount``; no torch import on the numpy path: a
    synthesis worker that imports torch for this pays about 1.5 s once). Returns float32 (n,) and (n, 3)."""
    w32 = wts.astype(np.float32)
    cover = np.bincount(idx, weights=w32, minlength=n).astype(np.float32)
    wc = w32 / np.maximum(cover[idx], np.float32(1.0)) * np.float32(1.0 / 255.0)
    q = np.empty((n, 3), np.float32)
    for c in range(3):
        q[:, c] = np.bincount(idx, weights=rgb[:, c].astype(np.float32) * wc, minlength=n)
    return np.minimum(cover, np.float32(1.0)), q


def snow_layers(params: SnowParams, bank: ParticleBank, height: int, width: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The unsmoothed mask ``B`` and ``B M`` of one image on a canvas padded by ``pad`` pixels on each side:
    float32 (H + 2 pad, W + 2 pad) and (..., 3), and ``pad``."""
    layout = snow_layout(params, len(bank), width, height)
    pad = _canvas_pad(layout, bank, params.rho_px)
    hp, wp = height + 2 * pad, width + 2 * pad
    ys, xs, mass, rgb, _ = _splat_points(layout, bank)
    idx, wts = _taps(ys, xs, pad, wp)
    b, q = _accumulate_np(idx, wts * np.tile(mass, 4), np.tile(rgb, (4, 1)), hp * wp)
    return b.reshape(hp, wp), q.reshape(hp, wp, 3), pad


def composite_snow(image: np.ndarray, params: SnowParams, bank: ParticleBank) -> tuple[np.ndarray, np.ndarray]:
    """Implements Eqs. (7)-(8) on one float32 RGB image (H, W, 3) in [0, 1]. Returns ``(I_ms, a_ms)``."""
    h, w, _ = image.shape
    if params.bank_id and bank.bank_id and params.bank_id != bank.bank_id:
        raise ValueError(f"bank: the parameters were drawn from bank {params.bank_id}, got bank {bank.bank_id}")
    b, bm, pad = snow_layers(params, bank, h, w)
    alpha_c = gaussian_blur(b, params.rho_px)  # Eq. (8): a_ms = G_rho * B (padded canvas)
    spread_c = gaussian_blur(bm, params.rho_px)  # a_ms M' = G_rho * (B M)
    # OpenCV reads the strided interior views directly (no copies)
    # (OpenCV takes a float as a scalar operand; its type stubs do not say so.)
    alpha = cv2.min(alpha_c[pad : pad + h, pad : pad + w], 1.0)  # type: ignore[call-overload]
    one_minus = cv2.cvtColor(cv2.subtract(1.0, alpha), cv2.COLOR_GRAY2BGR)  # type: ignore[call-overload]
    out = cv2.multiply(np.ascontiguousarray(image, dtype=np.float32), one_minus)
    cv2.add(out, spread_c[pad : pad + h, pad : pad + w], out)  # Eq. (7): (1 - a) I_fs + a M'
    return out, alpha


def composite_snow_torch(
    images: torch.Tensor, params: Sequence[SnowParams], bank: ParticleBank
) -> tuple[torch.Tensor, torch.Tensor]:
    """Torch twin of :func:`composite_snow` for a batch (B, 3, H, W) on any device.

    Layouts are drawn on the CPU (they are tiny); each image is splatted with ``index_add_`` on the device
    onto the same padded canvas as the numpy path, and smoothed by a grouped convolution.
    Returns ``(I_ms (B, 3, H, W), a_ms (B, 1, H, W))``.
    """
    import torch

    bsz, _, h, w = images.shape
    if len(params) != bsz:
        raise ValueError(f"params: expected {bsz} snow parameter sets (one per image), got {len(params)}")
    dev = images.device
    alphas, spreads = [], []
    for p in params:
        layout = snow_layout(p, len(bank), w, h)
        pad = _canvas_pad(layout, bank, p.rho_px)
        hp, wp = h + 2 * pad, w + 2 * pad
        ys, xs, mass, rgb, _ = _splat_points(layout, bank)
        idx, wts = _taps(ys, xs, pad, wp)
        b, q = _accumulate(idx, wts * np.tile(mass, 4), np.tile(rgb, (4, 1)), hp * wp, dev)
        layers = torch.cat([b.view(1, hp, wp), q.view(hp, wp, 3).permute(2, 0, 1)], dim=0)[None]
        blurred = gaussian_blur_torch(layers, torch.tensor([p.rho_px], dtype=torch.float64))[0]
        alphas.append(blurred[0:1, pad : pad + h, pad : pad + w].clamp(max=1.0))  # Eq. (8)
        spreads.append(blurred[1:4, pad : pad + h, pad : pad + w])
    alpha = torch.stack(alphas)
    out = images.to(torch.float32) * (1.0 - alpha) + torch.stack(spreads)  # Eq. (7)
    return out.to(images.dtype), alpha.to(images.dtype)
