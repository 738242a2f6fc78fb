"""Sampled parameters of one synthetic variant, and the sampling step (randomness lives only here).

``params = sample_variant(rng, config)`` draws everything random; ``render(clean, depth, params)`` in
:mod:`murk.synth.render` is then deterministic. A variant's parameters are JSON-serialisable (they form its
``manifest.jsonl`` line) and :func:`variant_from_dict` rebuilds them, so any variant can be re-rendered
exactly from its manifest line.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from murk._config import from_dict, to_dict
from murk.physics.jerlov import beta_per_m, residual_ratio, visible_range_m
from murk.physics.medium import ambient_light
from murk.rng import RngLike, as_generator
from murk.snow.composite import SnowParams
from murk.synth.config import CameraConfig, ForwardScatterConfig, MediumConfig, SynthConfig


@dataclass(frozen=True)
class MediumParams:
    """Eq. (1) parameters of one variant."""

    water_type: str
    beta_per_m: tuple[float, float, float]
    b_inf: tuple[float, float, float]
    vertical_depth_m: float | None
    """D of B_inf = scale * N ** D (None when B_inf was fixed by ambient_override)."""
    distance_mode: str
    near_m: float
    far_m: float
    """H: the farthest line-of-sight distance of the scene (normalized mode) or the clip limit (metric)."""
    illuminant_rgb: tuple[float, float, float] | None = None
    """The light on the clean scene per channel (``medium.illuminant``), applied before Eq. (1); None: white."""


@dataclass(frozen=True)
class ForwardScatterParams:
    """Eqs. (2)-(6) parameters of one variant."""

    mode: str
    sigma0_px: float
    k_px_per_m: float
    gamma_per_m: float
    exact_step_px: float


@dataclass(frozen=True)
class CameraParams:
    """``camera`` stage parameters of one variant (:mod:`murk.physics.camera`)."""

    wb_gains: tuple[float, float, float]
    exposure: float
    read_noise: float
    shot_noise: float
    noise_seed: int
    jpeg_quality: int
    """0 = no JPEG round trip (8-bit quantisation only)."""


@dataclass(frozen=True)
class VariantParams:
    """Everything that defines one synthetic variant. ``stages`` lists what is applied; the medium is always
    present because its distance range also drives forward scattering."""

    stages: tuple[str, ...]
    medium: MediumParams | None
    forward_scatter: ForwardScatterParams | None
    snow: SnowParams | None = None
    camera: CameraParams | None = None


def sample_medium(rng: RngLike, config: MediumConfig) -> MediumParams:
    """Draw the water type (uniformly from the enabled ones), the far distance H and the ambient light."""
    g = as_generator(rng)
    wt = config.water_types[int(g.integers(len(config.water_types)))]
    beta = beta_per_m(wt)
    if config.distance_mode == "normalized":
        h_max = visible_range_m(wt, floor=config.visibility_floor, cap_m=config.max_range_m)
        h_lo = config.near_m + config.far_margin_m
        far = float(g.uniform(h_lo, max(h_lo, h_max)))
    else:
        far = float(config.max_range_m)
    if config.ambient_override is not None:
        depth_d, b_inf = None, np.asarray(config.ambient_override, np.float64)
    else:
        depth_d = float(g.uniform(*config.vertical_depth_m))
        b_inf = ambient_light(wt, depth_d, scale=config.ambient_scale)
    if config.ambient_gain != (1.0, 1.0):
        b_inf = b_inf * float(g.uniform(*config.ambient_gain))
    if config.ambient_tint > 0:
        tint = np.exp(g.normal(0.0, config.ambient_tint, 3))
        b_inf = b_inf * tint * (float(b_inf.mean()) / max(float((b_inf * tint).mean()), 1e-12))
    return MediumParams(
        water_type=wt,
        beta_per_m=(float(beta[0]), float(beta[1]), float(beta[2])),
        b_inf=(float(b_inf[0]), float(b_inf[1]), float(b_inf[2])),
        vertical_depth_m=depth_d,
        distance_mode=config.distance_mode,
        near_m=float(config.near_m),
        far_m=far,
    )


def forward_scatter_params(config: ForwardScatterConfig) -> ForwardScatterParams:
    """The forward-scattering parameters (fixed by the config; nothing random in the paper's setting)."""
    return ForwardScatterParams(
        mode=config.mode,
        sigma0_px=float(config.sigma0_px),
        k_px_per_m=float(config.k_px_per_m),
        gamma_per_m=float(config.gamma_per_m),
        exact_step_px=float(config.exact_step_px),
    )


def sample_illuminant(rng: RngLike, config: MediumConfig, medium: MediumParams) -> MediumParams:
    """``medium`` with the light on the scene (``config.illuminant``): ``(N_c ** D / max_c N_c ** D) ** k``,
    ``k ~ U[a, b]``; unchanged (and nothing drawn) when the option is off or ``B_inf`` was fixed (no depth ``D``).
    :func:`sample_variant` draws it after every other parameter, so switching it on moves no other draw."""
    if tuple(config.illuminant) == (0.0, 0.0) or medium.vertical_depth_m is None:
        return medium
    k = float(as_generator(rng).uniform(*config.illuminant))
    down = residual_ratio(medium.water_type) ** medium.vertical_depth_m
    light = (down / down.max()) ** k
    return dataclasses.replace(medium, illuminant_rgb=(float(light[0]), float(light[1]), float(light[2])))


def sample_camera(rng: RngLike, config: CameraConfig) -> CameraParams:
    """Draw white-balance gains (geometric mean 1), exposure, noise levels, the noise seed and JPEG quality."""
    g = as_generator(rng)
    logg = g.normal(0.0, config.wb_sigma, 3)
    gains = np.exp(logg - logg.mean())
    lo, hi = config.exposure
    exposure = float(np.exp(g.uniform(np.log(lo), np.log(hi))))
    read = float(g.uniform(*config.read_noise))
    shot = float(g.uniform(*config.shot_noise))
    seed = int(g.integers(0, 2**31 - 1))
    jpeg = g.uniform() < config.jpeg_probability
    quality = int(g.integers(config.jpeg_quality[0], config.jpeg_quality[1] + 1))
    return CameraParams(
        wb_gains=(float(gains[0]), float(gains[1]), float(gains[2])),
        exposure=exposure,
        read_noise=read,
        shot_noise=shot,
        noise_seed=seed,
        jpeg_quality=quality if jpeg else 0,
    )


def sample_variant(rng: RngLike, config: SynthConfig, *, snow_sampler: Any = None) -> VariantParams:
    """Draw the parameters of one variant for the enabled stages.

    The medium is always sampled (its distance range also drives forward scattering and is recorded), even
    when the ``basic`` stage is off, so that turning a stage on or off never changes the other stages' draws.
    ``snow_sampler(rng) -> SnowParams`` is supplied by the marine-snow stage when it is enabled.
    """
    g = as_generator(rng)
    medium = sample_medium(g, config.medium)
    fs = forward_scatter_params(config.forward_scatter) if "forward_scatter" in config.stages else None
    snow = None
    if "marine_snow" in config.stages:
        if snow_sampler is None:
            raise ValueError("stages: 'marine_snow' needs a particle bank (snow_sampler) to sample from")
        snow = snow_sampler(g)
    camera = sample_camera(g, config.camera) if "camera" in config.stages else None
    medium = sample_illuminant(g, config.medium, medium)  # last: switching it on moves no other draw
    return VariantParams(stages=tuple(config.stages), medium=medium, forward_scatter=fs, snow=snow, camera=camera)


def snow_sampler_for(config: SynthConfig, bank: Any) -> Any:
    """The ``snow_sampler`` for :func:`sample_variant`: draws Eqs. (7)-(8) parameters from ``bank`` with the
    ranges of ``config.marine_snow``."""
    from murk.snow.composite import sample_snow

    sc = config.marine_snow

    def sampler(g: np.random.Generator) -> SnowParams:
        return sample_snow(
            g,
            bank,
            n_particles=sc.n_particles,
            scale=sc.scale,
            rho_px=sc.rho_px,
            reference_width_px=sc.reference_width_px,
            reference_area_px=sc.reference_area_px,
            particle_luma=sc.particle_luma,
            volume_m=sc.volume_m,
            focus_m=sc.focus_m,
            defocus_px=sc.defocus_px,
            layers=sc.layers,
            lamp=sc.lamp,
            motion_px=sc.motion_px,
        )

    return sampler


def variant_to_dict(params: VariantParams) -> dict[str, Any]:
    """Plain-dict form of ``params`` (the parameter part of a manifest line)."""
    return to_dict(params)


def variant_from_dict(data: dict[str, Any]) -> VariantParams:
    """Rebuild :class:`VariantParams` from :func:`variant_to_dict` output (extra manifest keys are ignored)."""
    names = {f.name for f in dataclasses.fields(VariantParams)}
    return from_dict(VariantParams, {k: v for k, v in data.items() if k in names}, where="manifest")
