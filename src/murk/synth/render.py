"""The staged synthesis of one variant (deterministic given its parameters), numpy and batched torch.

Stages, in order (Fig. 2 of the paper):

1. ``basic``: absorption + backscatter, Eq. (1) (:mod:`murk.physics.medium`);
2. ``forward_scatter``: depth-dependent blur, Eqs. (2)-(6) (:mod:`murk.physics.forward_scatter`);
3. ``marine_snow``: real particles composited as a foreground layer, Eqs. (7)-(8) (:mod:`murk.snow`).

The result is clipped to [0, 1] once, at the end.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from murk._checks import check_map, check_rgb
from murk.errors import ShapeError
from murk.physics.forward_scatter import forward_scatter, forward_scatter_torch
from murk.physics.medium import apply_medium, apply_medium_torch, distance_map, distance_map_torch, distance_range
from murk.rng import RngLike
from murk.synth.config import SynthConfig
from murk.synth.params import VariantParams, sample_variant, snow_sampler_for

if TYPE_CHECKING:
    import torch


@dataclass(frozen=True)
class SynthResult:
    """One rendered variant. Optional fields are None unless asked for (or unless the stage ran)."""

    degraded: np.ndarray
    """Final image, float32 (H, W, 3) in [0, 1]."""
    dist_m: np.ndarray
    """Line-of-sight distance used, float32 (H, W) metres."""
    sigma_max_px: float | None
    """Largest PSF sigma of this image (forward scattering on), pixels."""
    basic: np.ndarray | None = None
    """Eq. (1) result, clipped to [0, 1] (``keep_intermediate``)."""
    transmission: np.ndarray | None = None
    """T of Eq. (1), (H, W, 3) (``keep_intermediate``)."""
    snow_alpha: np.ndarray | None = None
    """a_ms of Eq. (8), (H, W) in [0, 1] (marine snow on)."""
    params: VariantParams | None = None
    """The parameters this variant was rendered with."""
    dist_range_m: tuple[float, float] | None = None
    """(min, max) of ``dist_m``, exact (:func:`murk.physics.medium.distance_range`)."""


def synthesize(
    clean: np.ndarray,
    depth_m: np.ndarray,
    *,
    rng: RngLike = None,
    config: SynthConfig | None = None,
    bank: Any = None,
    keep_intermediate: bool = False,
) -> SynthResult:
    """Sample the parameters of one variant and render it: the one-call API.

    Args:
        clean: float32 RGB in [0, 1], (H, W, 3).
        depth_m: depth in metres, (H, W), valid everywhere.
        rng: a numpy Generator, an int seed, or None.
        config: stages and parameter ranges (default: the paper's, stages basic + forward_scatter).
        bank: particle bank for the marine_snow stage (default: the one shipped with murk).
        keep_intermediate: also return the Eq. (1) image and the transmission.

    Example:
        >>> res = murk.synthesize(clean, depth_m, rng=0)
        >>> res.degraded, res.params.medium.water_type
    """
    config = SynthConfig() if config is None else config
    sampler = None
    if "marine_snow" in config.stages:
        if bank is None:
            from murk.data import default_snow_bank
            from murk.snow.bank import load_bank

            bank = load_bank(config.marine_snow.bank or default_snow_bank())
        sampler = snow_sampler_for(config, bank)
    params = sample_variant(rng, config, snow_sampler=sampler)
    return render(clean, depth_m, params, bank=bank, keep_intermediate=keep_intermediate)


def render(
    clean: np.ndarray,
    depth_m: np.ndarray,
    params: VariantParams,
    *,
    bank: Any = None,
    keep_intermediate: bool = False,
    depth_range_m: tuple[float, float] | None = None,
) -> SynthResult:
    """Render one synthetic underwater variant of a clean RGB-D pair.

    Args:
        clean: float32 RGB in [0, 1], (H, W, 3).
        depth_m: depth in metres, (H, W), valid everywhere (see :func:`murk.io.resolve_invalid`).
        params: from :func:`murk.synth.params.sample_variant` (or a manifest line).
        bank: the particle bank (:class:`murk.snow.bank.ParticleBank`) when ``params.snow`` is set.
        keep_intermediate: also return the Eq. (1) image and the transmission.
        depth_range_m: :func:`depth_range` of ``depth_m`` when the caller renders several variants of one image:
            the depth is then checked once, by that call, instead of at every variant. It is trusted, not compared
            with the map (a range from another map gives wrong distances).

    Raises:
        ShapeError: ``clean`` and ``depth_m`` sizes differ.
        ValueError: depth not positive and finite everywhere (checked here unless ``depth_range_m`` is given; then
            only the range is checked), or snow requested without a bank.
    """
    clean = check_rgb("clean", clean)
    depth_m = check_map("depth_m", depth_m, clean.shape[:2])
    lo, hi = depth_range(depth_m) if depth_range_m is None else depth_range_m
    if not (0 < lo <= hi < np.inf):
        raise ValueError(f"depth_range_m: expected 0 < min <= max < inf metres, got ({lo}, {hi})")
    m = params.medium
    if m is None:
        raise ValueError("params.medium: the distance range is always needed, got None")
    mode = m.distance_mode
    dist = distance_map(depth_m, mode=mode, near_m=m.near_m, far_m=m.far_m, depth_max_m=hi)  # type: ignore[arg-type]
    dist_range = distance_range(lo, hi, mode=mode, near_m=m.near_m, far_m=m.far_m)  # type: ignore[arg-type]
    trans = None
    if "basic" in params.stages:
        lit = clean if m.illuminant_rgb is None else clean * np.asarray(m.illuminant_rgb, np.float32)
        image, trans = apply_medium(lit, dist, np.asarray(m.beta_per_m), np.asarray(m.b_inf))
    else:
        image = clean.copy()
    basic = np.clip(image, 0.0, 1.0) if keep_intermediate else None
    sigma_max = None
    fs = params.forward_scatter
    if fs is not None:
        image, sigma_max = forward_scatter(
            image,
            dist,
            mode=fs.mode,  # type: ignore[arg-type]
            sigma0_px=fs.sigma0_px,
            k_px_per_m=fs.k_px_per_m,
            gamma_per_m=fs.gamma_per_m,
            step_px=fs.exact_step_px,
        )
    alpha = None
    if params.snow is not None:
        from murk.snow.composite import composite_snow

        if bank is None:
            raise ValueError("bank: marine snow parameters given but no particle bank")
        np.clip(image, 0.0, 1.0, out=image)
        water = (np.asarray(m.beta_per_m), np.asarray(m.b_inf)) if "basic" in params.stages else None
        scatter = None if fs is None else (fs.sigma0_px, fs.k_px_per_m, fs.gamma_per_m)
        image, alpha = composite_snow(image, params.snow, bank, dist_m=dist, water=water, scatter=scatter)
    np.clip(image, 0.0, 1.0, out=image)
    if params.camera is not None:
        from murk.physics.camera import apply_camera

        image = apply_camera(image, params.camera)
    return SynthResult(
        degraded=image,
        dist_m=dist,
        sigma_max_px=sigma_max,
        basic=basic,
        transmission=trans if keep_intermediate else None,
        snow_alpha=alpha,
        params=params,
        dist_range_m=dist_range,
    )


def depth_range(depth_m: np.ndarray) -> tuple[float, float]:
    """(min, max) of a depth map in metres, checked to be finite and > 0 everywhere.

    Raises:
        ValueError: a pixel is not finite or not > 0.
    """
    if not np.isfinite(depth_m).all() or not depth_m.size:
        raise ValueError("depth_m: expected finite depth > 0 everywhere (resolve invalid pixels first)")
    lo, hi = float(depth_m.min()), float(depth_m.max())
    if not lo > 0:
        raise ValueError("depth_m: expected finite depth > 0 everywhere (resolve invalid pixels first)")
    return lo, hi


# ----------------------------------------------------------------------------------------------- torch twin


@dataclass(frozen=True)
class BatchResult:
    """A rendered torch batch: ``degraded`` (B, 3, H, W) in [0, 1], ``dist_m`` (B, 1, H, W),
    ``sigma_max_px`` (B,) or None, ``snow_alpha`` (B, 1, H, W) or None."""

    degraded: torch.Tensor
    dist_m: torch.Tensor
    sigma_max_px: torch.Tensor | None
    snow_alpha: torch.Tensor | None = None


def render_batch_torch(
    clean: torch.Tensor, depth_m: torch.Tensor, params: Sequence[VariantParams], *, bank: Any = None
) -> BatchResult:
    """Torch twin of :func:`render` for a batch on any device (equal to it within 1/255, pinned by a test).

    Args:
        clean: (B, 3, H, W) in [0, 1].
        depth_m: (B, 1, H, W) metres, valid everywhere.
        params: one :class:`VariantParams` per sample; all must enable the same stages.
        bank: a :class:`murk.snow.bank.ParticleBank` when the variants have marine snow.
    """
    import torch

    if clean.ndim != 4 or clean.shape[1] != 3:
        raise ShapeError(f"clean: expected (B, 3, H, W), got {tuple(clean.shape)}")
    b, _, h, w = clean.shape
    if tuple(depth_m.shape) != (b, 1, h, w):
        raise ShapeError(f"depth_m: expected {(b, 1, h, w)} to match clean, got {tuple(depth_m.shape)}")
    if len(params) != b:
        raise ValueError(f"params: expected {b} variants (one per sample), got {len(params)}")
    kinds = {(p.forward_scatter is not None, p.snow is not None, p.camera is not None, p.stages) for p in params}
    if len(kinds) != 1:
        raise ValueError("params: all variants of a batch must enable the same stages")
    meds = [p.medium for p in params]
    if any(m is None for m in meds):
        raise ValueError("params.medium: the distance range is always needed, got None")
    dev, dt = clean.device, clean.dtype
    modes = {m.distance_mode for m in meds}  # type: ignore[union-attr]
    if len(modes) != 1:
        raise ValueError("params: all variants of a batch must use the same distance_mode")
    near = torch.tensor([m.near_m for m in meds], dtype=dt, device=dev)  # type: ignore[union-attr]
    far = torch.tensor([m.far_m for m in meds], dtype=dt, device=dev)  # type: ignore[union-attr]
    dist = distance_map_torch(depth_m.to(dt), near, far, mode=modes.pop())  # type: ignore[arg-type]
    if "basic" in params[0].stages:
        beta = torch.tensor([m.beta_per_m for m in meds], dtype=dt, device=dev)  # type: ignore[union-attr]
        b_inf = torch.tensor([m.b_inf for m in meds], dtype=dt, device=dev)  # type: ignore[union-attr]
        lit = clean
        if any(m.illuminant_rgb is not None for m in meds):  # type: ignore[union-attr]
            light = [m.illuminant_rgb or (1.0, 1.0, 1.0) for m in meds]  # type: ignore[union-attr]
            lit = clean * torch.tensor(light, dtype=dt, device=dev).view(b, 3, 1, 1)
        image, _ = apply_medium_torch(lit, dist, beta, b_inf)
    else:
        image = clean.clone()
    sigma_max = None
    if params[0].forward_scatter is not None:
        fss = [p.forward_scatter for p in params]
        fs_modes = {f.mode for f in fss}  # type: ignore[union-attr]
        if len(fs_modes) != 1:
            raise ValueError("params: all variants of a batch must use the same forward_scatter.mode")
        image, sigma_max = forward_scatter_torch(
            image,
            dist,
            mode=fs_modes.pop(),  # type: ignore[arg-type]
            sigma0_px=torch.tensor([f.sigma0_px for f in fss]),  # type: ignore[union-attr]
            k_px_per_m=torch.tensor([f.k_px_per_m for f in fss]),  # type: ignore[union-attr]
            gamma_per_m=torch.tensor([f.gamma_per_m for f in fss]),  # type: ignore[union-attr]
            step_px=fss[0].exact_step_px,  # type: ignore[union-attr]
        )
    alpha = None
    if params[0].snow is not None:
        from murk.snow.composite import composite_snow_torch

        if bank is None:
            raise ValueError("bank: marine snow parameters given but no particle bank")
        waters = None
        if "basic" in params[0].stages:
            waters = [(np.asarray(m.beta_per_m), np.asarray(m.b_inf)) for m in meds]  # type: ignore[union-attr]
        scatters = None
        if params[0].forward_scatter is not None:
            scatters = [(f.sigma0_px, f.k_px_per_m, f.gamma_per_m) for f in (p.forward_scatter for p in params)]  # type: ignore[union-attr]
        snows = [p.snow for p in params if p.snow is not None]  # (all of them: the stages agree)
        image, alpha = composite_snow_torch(
            image.clamp(0.0, 1.0), snows, bank, dist_m=dist, water=waters, scatter=scatters
        )
    image = image.clamp(0.0, 1.0)
    if params[0].camera is not None:
        from murk.physics.camera import apply_camera_torch

        image = apply_camera_torch(image, [p.camera for p in params])
    return BatchResult(image, dist, sigma_max, alpha)
