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
from collections.abc import Callable, Sequence
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
    volume_m: tuple[float, float] | None = None
    """If set, the particles fill the water between these distances from the camera (metres, uniform in volume)
    instead of the paper's one flat layer: each is scaled by ``focus_m / z`` (near particles large), blurred by
    its defocus (near and far ones soft), hidden behind the scene where the scene is nearer than it, and seen
    through the water between it and the camera (Eq. 1 at its distance, when the variant has the ``basic``
    stage). None: the paper's Eqs. (7)-(8)."""
    focus_m: float = 1.0
    """Volume snow: the distance in focus, where a particle has the paper's scale ``s``."""
    defocus_px: float = 2.0
    """Volume snow: Gaussian blur (pixels) per dioptre of defocus, ``|1/z - 1/focus_m|``, added in quadrature to
    ``rho`` (multiplied by width / ``reference_width_px`` as the sizes are)."""
    layers: int = 4
    """Volume snow: the particles are binned into this many layers, evenly spaced in inverse distance, each
    blurred with its own defocus and composited far to near."""
    motion_px: float = 0.0
    """Motion streaks (video): each particle smeared along a line this many pixels long (volume snow: a particle at
    ``focus_m``; at ``z`` the streak is ``motion_px * focus_m / z``, near particles sweep farther), at
    ``motion_angle_rad`` from the image's x axis; below 1 px nothing is smeared. 0: off."""
    motion_angle_rad: float = 0.0
    lamp: float = 0.0
    """Volume snow: light of a lamp beside the camera scattered back by each particle, added to its colour:
    ``lamp * exp(-2 beta z) / z^2`` (0-1 of full scale; ``lamp`` is the light a particle at 1 m gets in clear
    water), so near particles glow white and far ones fade into the water. 0: no lamp."""


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
    distance_m: np.ndarray | None = None
    """Per drawn particle: its distance from the camera (``volume_m``; None: the paper's flat layer)."""

    def subset(self, keep: np.ndarray) -> SnowLayout:
        """The particles selected by ``keep`` (a boolean mask or indices)."""
        return SnowLayout(
            self.index[keep],
            self.scale[keep],
            self.centre_xy[keep],
            None if self.target_luma is None else self.target_luma[keep],
            None if self.distance_m is None else self.distance_m[keep],
        )


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
    volume_m: tuple[float, float] | None = None,
    focus_m: float = 1.0,
    defocus_px: float = 2.0,
    layers: int = 4,
    lamp: float = 0.0,
    motion_px: tuple[float, float] | None = None,
) -> SnowParams:
    """Draw N_p ~ U{a..b}, rho ~ U[a, b] and the layout seed of one image (volume options: :class:`SnowParams`);
    with ``motion_px`` also a streak length ~ U[a, b] and a direction ~ U[0, pi) (drawn after the others, so
    the paper's draws stay as they were)."""
    g = as_generator(rng)
    n_p = int(g.integers(n_particles[0], n_particles[1] + 1))
    rho = float(g.uniform(*rho_px))
    seed = int(g.integers(0, 2**63 - 1))
    motion, angle = 0.0, 0.0
    if motion_px is not None and motion_px[1] > 0:
        motion, angle = float(g.uniform(*motion_px)), float(g.uniform(0.0, math.pi))
    return SnowParams(
        n_particles=n_p,
        rho_px=rho,
        scale_range=(float(scale[0]), float(scale[1])),
        layout_seed=seed,
        bank_id=bank.bank_id,
        reference_width_px=int(reference_width_px),
        reference_area_px=int(reference_area_px),
        particle_luma=None if particle_luma is None else (float(particle_luma[0]), float(particle_luma[1])),
        volume_m=None if volume_m is None else (float(volume_m[0]), float(volume_m[1])),
        focus_m=float(focus_m),
        defocus_px=float(defocus_px),
        layers=int(layers),
        lamp=float(lamp),
        motion_px=motion,
        motion_angle_rad=angle,
    )


def snow_layout(
    params: SnowParams, bank_size: int, width: int, height: int, scene_far_m: float | None = None
) -> SnowLayout:
    """The deterministic particle layout of ``params`` for an image of ``width`` x ``height``. Volume snow: the
    particles' distances stop at ``scene_far_m`` (the scene's farthest point) when it is nearer than
    ``volume_m[1]``, so the water in front of a near scene gets the whole count."""
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
    if params.particle_luma is not None:  # drawn after the paper's draws: those stay as they were
        target = g.uniform(params.particle_luma[0], params.particle_luma[1], size=n)
    dist = None
    if params.volume_m is not None:  # drawn last: uniform in the volume of the view's frustum (density ~ z^2)
        a, b = params.volume_m
        if scene_far_m is not None:
            b = max(a, min(b, float(scene_far_m)))
        dist = np.cbrt(a**3 + g.uniform(0.0, 1.0, size=n) * (b**3 - a**3))
        scale = scale * (params.focus_m / dist)
    return SnowLayout(index, scale, centre, target, dist)


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


Water = tuple[np.ndarray, np.ndarray]
"""The water a volume particle is seen through: ``beta`` (3,) per metre and ``B_inf`` (3,) in [0, 1] of Eq. (1)."""


def _attenuated(rgb: np.ndarray, distance_m: np.ndarray, water: Water | None, lamp: float) -> np.ndarray:
    """Particle colours (N, 3) 0-255 at ``distance_m`` (N,): seen through the water (Eq. 1, ``M t + 255 B (1 - t)``,
    when ``water`` is given) plus the light of a lamp at the camera scattered back (``255 lamp t^2 / z^2``),
    clipped at 255."""
    z = distance_m[:, None]
    if water is None:
        t = np.ones((len(z), 3))
        out = rgb.astype(np.float64)
    else:
        beta, b_inf = (np.asarray(v, np.float64).reshape(1, 3) for v in water)
        t = np.exp(-beta * z)
        out = rgb * t + 255.0 * b_inf * (1.0 - t)
    if lamp > 0:
        out = out + 255.0 * lamp * t * t / (z * z)
    return np.minimum(out, 255.0).astype(np.float32)


def _splat_points(
    layout: SnowLayout, bank: ParticleBank, water: Water | None = None, lamp: float = 0.0
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
    rgb = _colours(layout, bank, pix, owner)
    if layout.distance_m is not None and (water is not None or lamp > 0):
        rgb = _attenuated(rgb, layout.distance_m[owner], water, lamp)
    return ys, xs, mass, rgb, pix


def _canvas_pad(layout: SnowLayout, bank: ParticleBank, rho_px: float, extra_px: int = 0) -> int:
    """Margin around the image so every tap of every drawn particle, and the blur around it (plus ``extra_px``, a
    streak's reach), lands inside."""
    if len(layout.index) == 0:
        return 1
    reach = float(np.abs(bank.pixel_yx).max()) if len(bank.pixel_yx) else 0.0
    return math.ceil(reach * float(layout.scale.max())) + 2 + kernel_radius(rho_px) + extra_px


def _scatter_reach(layer: SnowLayer) -> int:
    """Extra canvas margin for a layer's forward-scattering blur."""
    return kernel_radius(layer.scatter_px) if layer.scatter_weight > 0 else 0


def streak_kernel(length_px: float, angle_rad: float) -> np.ndarray | None:
    """A motion streak: a line ``length_px`` long through the centre at ``angle_rad`` (from +x, rows down),
    antialiased (points every 1/8 px, bilinear) and normalised to sum 1; float32 (2r+1, 2r+1). None below 1 px."""
    if length_px < 1.0:
        return None
    r = math.ceil(length_px / 2) + 1
    t = np.linspace(-length_px / 2, length_px / 2, max(2, math.ceil(length_px * 8) + 1))
    xs, ys = r + t * math.cos(angle_rad), r + t * math.sin(angle_rad)
    x0, y0 = np.floor(xs).astype(np.int64), np.floor(ys).astype(np.int64)
    fx, fy = xs - x0, ys - y0
    k = np.zeros((2 * r + 1, 2 * r + 1), np.float64)
    for dy, dx, wt in ((0, 0, (1 - fy) * (1 - fx)), (0, 1, (1 - fy) * fx), (1, 0, fy * (1 - fx)), (1, 1, fy * fx)):
        np.add.at(k, (y0 + dy, x0 + dx), wt)
    return (k / k.sum()).astype(np.float32)


@dataclass(frozen=True)
class SnowLayer:
    """One layer of the layered compositing (volume snow, motion streaks): its particles, Gaussian blur and
    streak length (pixels)."""

    layout: SnowLayout
    rho_px: float
    streak_px: float = 0.0
    scatter_px: float = 0.0
    """Forward scattering of the water in front of the layer (Eqs. 3, 5-6 at its distance): the blurred share
    ``scatter_weight`` is blurred by a further ``scatter_px`` (0: none)."""
    scatter_weight: float = 0.0


Scatter = tuple[float, float, float]
"""The variant's forward scattering, ``(sigma0_px, k_px_per_m, gamma_per_m)`` of Eqs. (3) and (6)."""


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
    return _canvases_np(snow_layout(params, len(bank), width, height), bank, height, width, params.rho_px)


def _canvases_np(
    layout: SnowLayout,
    bank: ParticleBank,
    height: int,
    width: int,
    rho_px: float,
    water: Water | None = None,
    lamp: float = 0.0,
    extra_px: int = 0,
) -> tuple[np.ndarray, np.ndarray, int]:
    pad = _canvas_pad(layout, bank, rho_px, extra_px)
    hp, wp = height + 2 * pad, width + 2 * pad
    ys, xs, mass, rgb, _ = _splat_points(layout, bank, water, lamp)
    idx, wts = _taps(ys, xs, pad, wp)
    b, q = _accumulate_np(idx, wts * np.tile(mass, 4), np.tile(rgb, (4, 1)), hp * wp)
    return b.reshape(hp, wp), q.reshape(hp, wp, 3), pad


DistanceAt = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""The scene's distance (metres) at integer pixel rows and columns (occlusion of volume snow)."""


def layer_plan(
    params: SnowParams,
    layout: SnowLayout,
    width: int,
    height: int,
    distance_at: DistanceAt | None = None,
    scatter: Scatter | None = None,
) -> list[SnowLayer]:
    """The layers of the layered compositing, far to near. Without volume snow: one layer, all particles, blur
    ``rho`` and the streak ``motion_px``. Volume snow (``params.volume_m``): the particles in front of the scene
    (``distance_at`` of the pixel under each particle's centre; None: all), binned into ``params.layers`` layers
    evenly spaced in inverse distance, each with its blur ``hypot(rho, defocus_px * |1/z_layer - 1/focus_m|)``
    and streak ``motion_px * focus_m / z_layer`` (pixels; ``z_layer`` at the middle of the layer in 1/z), and with
    ``scatter`` the forward scattering of the water in front of it, as Eqs. (3), (5)-(6) treat the scene:
    a share ``1 - exp(-gamma z_layer)`` blurred by ``sigma0 + k z_layer`` more."""
    if params.volume_m is None:
        return [SnowLayer(layout, params.rho_px, params.motion_px)]
    if layout.distance_m is None:
        raise ValueError("layout: volume snow needs the particles' distances, got None")
    if distance_at is not None and len(layout.index):
        xi = np.clip(np.rint(layout.centre_xy[:, 0]), 0, width - 1).astype(np.int64)
        yi = np.clip(np.rint(layout.centre_xy[:, 1]), 0, height - 1).astype(np.int64)
        layout = layout.subset(layout.distance_m < np.asarray(distance_at(yi, xi), np.float64))
    assert layout.distance_m is not None
    near, far = params.volume_m
    edges = np.linspace(1.0 / far, 1.0 / near, params.layers + 1)
    k = np.clip(np.searchsorted(edges, 1.0 / layout.distance_m, side="right") - 1, 0, params.layers - 1)
    factor = width / params.reference_width_px if params.reference_width_px > 0 else 1.0
    plan = []
    for j in range(params.layers):  # j = 0: the farthest layer
        sel = k == j
        if sel.any():
            inv = 0.5 * (edges[j] + edges[j + 1])
            defocus = params.defocus_px * factor * abs(inv - 1.0 / params.focus_m)
            rho = math.hypot(params.rho_px, defocus)
            fs_px, fs_w = 0.0, 0.0
            if scatter is not None:
                sigma0, k_px, gamma = scatter
                fs_px, fs_w = sigma0 + k_px / inv, 1.0 - math.exp(-gamma / inv)  # Eqs. (3), (6) at z = 1 / inv
            streak = params.motion_px * params.focus_m * inv
            plan.append(SnowLayer(layout.subset(sel), rho, streak, fs_px, fs_w))
    return plan


def composite_snow(
    image: np.ndarray,
    params: SnowParams,
    bank: ParticleBank,
    *,
    dist_m: np.ndarray | None = None,
    water: Water | None = None,
    scatter: Scatter | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Implements Eqs. (7)-(8) on one float32 RGB image (H, W, 3) in [0, 1]. Returns ``(I_ms, a_ms)``.

    With ``params.volume_m`` (volume snow), ``dist_m`` (H, W) hides the particles behind the scene, ``water``
    (the variant's Eq. (1) coefficients) tints each particle by the water in front of it and ``scatter`` (its
    forward scattering) blurs each layer as Eqs. (3), (5)-(6) blur the scene at that distance; all three are
    ignored otherwise."""
    h, w, _ = image.shape
    if params.bank_id and bank.bank_id and params.bank_id != bank.bank_id:
        raise ValueError(f"bank: the parameters were drawn from bank {params.bank_id}, got bank {bank.bank_id}")
    if params.volume_m is not None or params.motion_px >= 1.0:
        return _composite_layered(image, params, bank, dist_m, water, scatter)
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


def _composite_layered(
    image: np.ndarray,
    params: SnowParams,
    bank: ParticleBank,
    dist_m: np.ndarray | None,
    water: Water | None,
    scatter: Scatter | None,
) -> tuple[np.ndarray, np.ndarray]:
    """Volume snow or motion streaks: Eqs. (7)-(8) once per layer of :func:`layer_plan`, far to near, each layer's
    canvases blurred by its Gaussian, then smeared by its streak; ``a_ms = 1 - prod(1 - a_k)``."""
    h, w, _ = image.shape
    far = None if dist_m is None or params.volume_m is None else float(dist_m.max())
    layout = snow_layout(params, len(bank), w, h, far)
    at = None if dist_m is None else (lambda y, x: dist_m[y, x])
    out = np.array(image, dtype=np.float32)
    clear = np.ones((h, w), np.float32)
    for layer in layer_plan(params, layout, w, h, at, scatter):
        kernel = streak_kernel(layer.streak_px, params.motion_angle_rad)
        extra = (0 if kernel is None else kernel.shape[0] // 2) + _scatter_reach(layer)
        b, bm, pad = _canvases_np(layer.layout, bank, h, w, layer.rho_px, water, params.lamp, extra)
        b, bm = gaussian_blur(b, layer.rho_px), gaussian_blur(bm, layer.rho_px)
        if layer.scatter_weight > 0:  # Eq. (5) on the layer: (1 - a) C + a G_sigma * C
            wt = np.float32(layer.scatter_weight)
            b = (1 - wt) * b + wt * gaussian_blur(b, layer.scatter_px)
            bm = (1 - wt) * bm + wt * gaussian_blur(bm, layer.scatter_px)
        if kernel is not None:  # correlation with zeros outside the padded canvas, as torch's conv2d
            b = cv2.filter2D(b, -1, kernel, borderType=cv2.BORDER_CONSTANT)
            bm = cv2.filter2D(bm, -1, kernel, borderType=cv2.BORDER_CONSTANT)
        alpha = np.minimum(b[pad : pad + h, pad : pad + w], np.float32(1.0))
        out = out * (1.0 - alpha)[..., None] + bm[pad : pad + h, pad : pad + w]
        clear *= 1.0 - alpha
    return out.astype(np.float32), (1.0 - clear).astype(np.float32)


def composite_snow_torch(
    images: torch.Tensor,
    params: Sequence[SnowParams],
    bank: ParticleBank,
    *,
    dist_m: torch.Tensor | None = None,
    water: Sequence[Water] | None = None,
    scatter: Sequence[Scatter] | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Torch twin of :func:`composite_snow` for a batch (B, 3, H, W) on any device.

    Layouts are drawn on the CPU (they are tiny); each image is splatted with ``index_add_`` on the device
    onto the same padded canvas as the numpy path, and smoothed by a grouped convolution. Volume snow:
    ``dist_m`` (B, 1, H, W) and one ``water`` and ``scatter`` per image, as :func:`composite_snow`.
    Returns ``(I_ms (B, 3, H, W), a_ms (B, 1, H, W))``.
    """
    import torch

    bsz, _, h, w = images.shape
    if len(params) != bsz:
        raise ValueError(f"params: expected {bsz} snow parameter sets (one per image), got {len(params)}")
    if any(p.volume_m is not None or p.motion_px >= 1.0 for p in params):
        return _composite_layered_torch(images, params, bank, dist_m, water, scatter)
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


def _composite_layered_torch(
    images: torch.Tensor,
    params: Sequence[SnowParams],
    bank: ParticleBank,
    dist_m: torch.Tensor | None,
    water: Sequence[Water] | None,
    scatter: Sequence[Scatter] | None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """The twin of :func:`_composite_layered` for a batch (images without volume snow or streaks get one plain
    layer, the same result as the paper's path)."""
    import torch
    import torch.nn.functional as F

    _, _, h, w = images.shape
    dev = images.device
    outs, alphas = [], []
    for i, p in enumerate(params):
        far = None if dist_m is None or p.volume_m is None else float(dist_m[i].max())
        layout = snow_layout(p, len(bank), w, h, far)
        at = None
        if dist_m is not None:
            d = dist_m[i, 0]

            def at(y: np.ndarray, x: np.ndarray, d: torch.Tensor = d) -> np.ndarray:
                return d[torch.from_numpy(y).to(d.device), torch.from_numpy(x).to(d.device)].cpu().numpy()

        out = images[i].to(torch.float32)
        clear = torch.ones((1, h, w), dtype=torch.float32, device=dev)
        for layer in layer_plan(p, layout, w, h, at, None if scatter is None else scatter[i]):
            kernel = streak_kernel(layer.streak_px, p.motion_angle_rad)
            extra = 0 if kernel is None else kernel.shape[0] // 2
            pad = _canvas_pad(layer.layout, bank, layer.rho_px, extra + _scatter_reach(layer))
            hp, wp = h + 2 * pad, w + 2 * pad
            ys, xs, mass, rgb, _ = _splat_points(layer.layout, bank, None if water is None else water[i], p.lamp)
            idx, wts = _taps(ys, xs, pad, wp)
            b, q = _accumulate(idx, wts * np.tile(mass, 4), np.tile(rgb, (4, 1)), hp * wp, dev)
            canv = torch.cat([b.view(1, hp, wp), q.view(hp, wp, 3).permute(2, 0, 1)], dim=0)[None]
            blurred = gaussian_blur_torch(canv, torch.tensor([layer.rho_px], dtype=torch.float64))
            if layer.scatter_weight > 0:
                more = gaussian_blur_torch(blurred, torch.tensor([layer.scatter_px], dtype=torch.float64))
                blurred = (1 - layer.scatter_weight) * blurred + layer.scatter_weight * more
            if kernel is not None:
                k = torch.from_numpy(kernel).to(dev)[None, None].expand(4, 1, -1, -1)
                blurred = F.conv2d(blurred, k, padding=extra, groups=4)
            alpha = blurred[0, 0:1, pad : pad + h, pad : pad + w].clamp(max=1.0)
            out = out * (1.0 - alpha) + blurred[0, 1:4, pad : pad + h, pad : pad + w]
            clear = clear * (1.0 - alpha)
        outs.append(out)
        alphas.append(1.0 - clear)
    return torch.stack(outs).to(images.dtype), torch.stack(alphas).to(images.dtype)
