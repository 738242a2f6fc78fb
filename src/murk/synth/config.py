"""Configuration of a synthesis run: frozen dataclasses whose defaults are the paper's settings.

Every field can be set in a YAML file (``murk synth --config FILE.yaml``) and most from the command line.
The resolved configuration is written back into every output folder with the seed and the murk version.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from murk._checks import check_interval, check_positive, check_range
from murk.io.depth import DEPTH_ENCODINGS, DepthEncoding, InvalidDepthMode
from murk.io.pairs import DEPTH_FROM, DepthFrom
from murk.physics.forward_scatter import FsMode
from murk.physics.jerlov import WATER_TYPES, parse_water_types
from murk.physics.medium import DistanceMode

Stage = Literal["basic", "forward_scatter", "marine_snow", "camera"]
STAGES: tuple[str, ...] = ("basic", "forward_scatter", "marine_snow", "camera")
"""All stages in the order they are applied."""


def parse_stages(spec: str | tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """Parse ``"basic,forward_scatter"`` (any order) into stage names in application order."""
    items = spec.split(",") if isinstance(spec, str) else list(spec)
    names = [s.strip() for s in items if s.strip()]
    unknown = [n for n in names if n not in STAGES]
    if unknown or not names:
        what = f"unknown stage(s) {', '.join(map(repr, unknown))}" if unknown else f"no stage in {spec!r}"
        raise ValueError(f"stages: {what}; expected a comma list of {','.join(STAGES)}")
    return tuple(s for s in STAGES if s in names)


@dataclass(frozen=True)
class MediumConfig:
    """Eq. (1): water types, line-of-sight distances and ambient light (spec: docs/spec/synthesis.md)."""

    water_types: tuple[str, ...] = WATER_TYPES
    """Types drawn uniformly per variant (default: all ten Jerlov types)."""
    distance_mode: DistanceMode = "normalized"
    """``normalized``: depth / max(depth) mapped to [near_m, H]; ``metric``: true depth clipped to
    [near_m, max_range_m]."""
    near_m: float = 0.3
    max_range_m: float = 15.0
    far_margin_m: float = 0.5
    """The far distance H is drawn from U[near_m + far_margin_m, H_max(type)]."""
    visibility_floor: float = 0.02
    """H_max(type) = min(max_range_m, -ln(floor) / min_c beta_c): beyond it the scene is gone."""
    vertical_depth_m: tuple[float, float] = (3.0, 5.0)
    """D ~ U[a, b]: depth below the surface that sets the ambient light B_inf = scale * N ** D."""
    ambient_scale: float = 1.5
    ambient_override: tuple[float, float, float] | None = None
    """A fixed B_inf (R, G, B) instead of the sampled one."""
    ambient_gain: tuple[float, float] = (1.0, 1.0)
    """B_inf is multiplied by a ~ U[a, b] (brighter or darker veils than the Jerlov table at depth D gives);
    (1, 1) = off, the paper's (no draw is made, so the other draws stay as they were)."""
    ambient_tint: float = 0.0
    """B_inf_c is multiplied by exp(t_c), t_c ~ N(0, ambient_tint^2) per channel, then rescaled to keep its mean:
    water colours between the Jerlov types (greener, bluer, yellow-brown); 0 = off, the paper's."""
    illuminant: tuple[float, float] = (0.0, 0.0)
    """Daylight that came down through the water lights the scene (the direct signal's illuminant of Akkaynak &
    Treibitz's revised model, CVPR 2018): before Eq. (1) the clean scene is multiplied per channel by
    ``(N_c ** D / max_c N_c ** D) ** k``, ``k ~ U[a, b]``, with ``N`` the water type's residual ratio and ``D`` the
    vertical depth of the ambient light (the brightest channel keeps its level). 0: white light, the paper's; 1: the
    downwelling light at depth ``D`` in full. (0, 0) = off (no draw is made). ``k`` is drawn after every other
    parameter of a variant, so switching it on moves no other draw; refused with ``ambient_override``."""

    def __post_init__(self) -> None:
        object.__setattr__(self, "water_types", parse_water_types(self.water_types))
        if self.distance_mode not in ("normalized", "metric"):
            raise ValueError(f"distance_mode: expected 'normalized' or 'metric', got {self.distance_mode!r}")
        check_positive("near_m", self.near_m)
        check_range("max_range_m", self.max_range_m, self.near_m, 1e4)
        check_positive("far_margin_m", self.far_margin_m)
        if self.near_m + self.far_margin_m > self.max_range_m:
            raise ValueError(
                f"far_margin_m: near_m + far_margin_m must be <= max_range_m, got "
                f"{self.near_m} + {self.far_margin_m} > {self.max_range_m}"
            )
        check_range("visibility_floor", self.visibility_floor, 1e-9, 1 - 1e-9)
        check_interval("vertical_depth_m", self.vertical_depth_m, 0.0, 1e4)
        check_positive("ambient_scale", self.ambient_scale)
        if self.ambient_override is not None:
            for c in self.ambient_override:
                check_range("ambient_override", c, 0.0, 10.0)
        check_interval("ambient_gain", self.ambient_gain, 0.0, 10.0)
        check_range("ambient_tint", self.ambient_tint, 0.0, 2.0)
        object.__setattr__(self, "illuminant", check_interval("illuminant", self.illuminant, 0.0, 1.0))
        if self.illuminant != (0.0, 0.0) and self.ambient_override is not None:
            raise ValueError("illuminant: the light comes from the ambient light's depth; ambient_override has none")


@dataclass(frozen=True)
class ForwardScatterConfig:
    """Eqs. (2)-(6): PSF width sigma(d) = sigma0 + k d and the approximation's blend weight."""

    mode: FsMode = "approx"
    """``approx``: the paper's Eqs. (5)-(6); ``exact``: the spatially varying blur of Eq. (4)."""
    sigma0_px: float = 0.5
    k_px_per_m: float = 0.15
    gamma_per_m: float = 0.2
    exact_step_px: float = 0.1
    """Spacing of the sigma grid of the exact mode (smaller = closer to Eq. (4), slower)."""

    def __post_init__(self) -> None:
        if self.mode not in ("approx", "exact"):
            raise ValueError(f"mode: expected 'approx' or 'exact', got {self.mode!r}")
        check_positive("sigma0_px", self.sigma0_px)
        check_positive("k_px_per_m", self.k_px_per_m, allow_zero=True)
        check_positive("gamma_per_m", self.gamma_per_m)
        check_range("exact_step_px", self.exact_step_px, 1e-3, 10.0)


@dataclass(frozen=True)
class SnowConfig:
    """Eqs. (7)-(8): marine snow composited from a bank of particles cut from real footage."""

    bank: str | None = None
    """Path of a particle bank (``murk snow extract``); None = the default bank shipped with murk."""
    n_particles: tuple[int, int] = (1000, 1600)
    """N_p ~ U{a..b} particles per image (drawn with replacement from the bank)."""
    scale: tuple[float, float] = (0.3, 0.6)
    """Each particle is resized by s ~ U[a, b]."""
    rho_px: tuple[float, float] = (0.2, 1.0)
    """Gaussian smoothing of the particle mask, rho ~ U[a, b] pixels (Eq. 8)."""
    reference_width_px: int = 0
    """If > 0, particle sizes are multiplied by (image width / this), so snow keeps its look across
    resolutions; 0 = sizes in the bank's pixels, as in the paper."""
    reference_area_px: int = 0
    """If > 0, ``n_particles`` counts particles per this many pixels (e.g. 307200 = the paper's counts on a
    640x480 frame), so a small training crop gets the same snow density as a full frame; 0 = per image, as in
    the paper."""
    particle_luma: tuple[float, float] | None = None
    """If set, each particle is relit: neutral grey with its own luma pattern, rescaled to a mean luma ~ U[a, b]
    (0-255): particles lit by a lamp or the sun, whatever the brightness of the footage they were cut from.
    None: the original pixels, the paper's Eq. (7)."""
    volume_m: tuple[float, float] | None = None
    """Volume snow: if set, the particles fill the water between these distances from the camera (metres, uniform
    in volume) instead of the paper's one flat layer: scaled by ``focus_m / z`` (near ones large), blurred by their
    defocus, hidden behind nearer scene surfaces and tinted by the water in front of them (docs/snow.md).
    None: the paper's Eqs. (7)-(8)."""
    focus_m: float = 1.0
    """Volume snow: the distance in focus, where a particle has the paper's size (``scale``)."""
    defocus_px: float = 2.0
    """Volume snow: blur (Gaussian sigma, pixels) per dioptre of defocus ``|1/z - 1/focus_m|``, added in
    quadrature to ``rho_px``."""
    layers: int = 4
    """Volume snow: depth layers (even in inverse distance), each blurred with its own defocus."""
    motion_px: tuple[float, float] | None = None
    """Motion streaks (video): each image's particles are smeared along a line ~ U[a, b] pixels long in a direction
    ~ U[0, pi) (volume snow: for a particle at ``focus_m``; nearer ones sweep farther, ``* focus_m / z``).
    None: still particles, the paper."""
    lamp: float = 0.0
    """Volume snow: a lamp beside the camera lights the particles, ``lamp * exp(-2 beta z) / z^2`` added to each
    particle's colour (0-1 of full scale at 1 m in clear water): near particles glow, far ones fade. 0: off."""

    def __post_init__(self) -> None:
        if self.particle_luma is not None:
            check_interval("particle_luma", self.particle_luma, 1.0, 255.0)
        if self.volume_m is not None:
            check_interval("volume_m", self.volume_m, 0.01, 1000.0)
        check_range("focus_m", self.focus_m, 0.01, 1000.0)
        check_range("defocus_px", self.defocus_px, 0.0, 100.0)
        check_range("lamp", self.lamp, 0.0, 100.0)
        if self.lamp > 0 and self.volume_m is None:
            raise ValueError("lamp: a lamp lights particles by their distance; set volume_m (volume snow) too")
        if self.motion_px is not None:
            check_interval("motion_px", self.motion_px, 0.0, 1000.0)
        if isinstance(self.layers, bool) or not (1 <= self.layers <= 64):
            raise ValueError(f"layers: expected an integer in [1, 64], got {self.layers!r}")
        lo, hi = self.n_particles
        if isinstance(lo, bool) or isinstance(hi, bool) or not (0 <= lo <= hi <= 1_000_000):
            raise ValueError(f"n_particles: expected 0 <= min <= max <= 1e6, got {self.n_particles}")
        check_interval("scale", self.scale, 1e-3, 100.0)
        check_interval("rho_px", self.rho_px, 1e-3, 100.0)
        if self.reference_width_px < 0:
            raise ValueError(f"reference_width_px: expected >= 0, got {self.reference_width_px}")
        if self.reference_area_px < 0:
            raise ValueError(f"reference_area_px: expected >= 0, got {self.reference_area_px}")


@dataclass(frozen=True)
class CameraConfig:
    """The ``camera`` stage (after the water and the snow; :mod:`murk.physics.camera`): white-balance error,
    exposure, heteroscedastic sensor noise and JPEG, each drawn per variant."""

    wb_sigma: float = 0.08
    """log g_c ~ N(0, wb_sigma^2) per channel, recentred so the gains' geometric mean is 1."""
    exposure: tuple[float, float] = (0.8, 1.25)
    """Exposure e, log-uniform in [a, b]."""
    read_noise: tuple[float, float] = (0.0, 0.01)
    """Signal-independent noise standard deviation ~ U[a, b] (fraction of full scale)."""
    shot_noise: tuple[float, float] = (0.0, 0.0004)
    """Signal-dependent noise variance per unit signal ~ U[a, b] (variance = read^2 + shot * x)."""
    jpeg_quality: tuple[int, int] = (60, 95)
    """JPEG quality ~ U{a..b} when a JPEG round trip is drawn."""
    jpeg_probability: float = 0.5
    """Probability of the JPEG round trip (otherwise the image is only quantised to 8 bits)."""

    def __post_init__(self) -> None:
        check_range("wb_sigma", self.wb_sigma, 0.0, 2.0)
        check_interval("exposure", self.exposure, 1e-3, 100.0)
        check_interval("read_noise", self.read_noise, 0.0, 1.0)
        check_interval("shot_noise", self.shot_noise, 0.0, 1.0)
        lo, hi = self.jpeg_quality
        if isinstance(lo, bool) or isinstance(hi, bool) or not (1 <= lo <= hi <= 100):
            raise ValueError(f"jpeg_quality: expected 1 <= min <= max <= 100, got {self.jpeg_quality}")
        check_range("jpeg_probability", self.jpeg_probability, 0.0, 1.0)


@dataclass(frozen=True)
class InputConfig:
    """How clean RGB-D inputs are read and prepared."""

    depth_scale: float = 1000.0
    """Raw units per metre of integer depth images (1000 = mm; TUM 5000; KITTI 256)."""
    depth_encoding: DepthEncoding = "linear"
    """How integer depth maps to metres: linear (value / depth_scale), sun (SUN RGB-D), kinect-disparity (raw NYU)."""
    depth_relative: bool = False
    """Accept 8-bit relative depth (larger = farther); needs distance_mode 'normalized'."""
    depth_from: DepthFrom = "file"
    """``file``: RGBD_DIR's depth/ files. ``layout``: RGBD_DIR holds clean photographs without depth (in rgb/, or
    the folder itself), each given the distance of the ground-plane layout prior (:mod:`murk.io.distance_prior`),
    drawn from ``seed`` and the photograph's stem."""
    invalid_depth: InvalidDepthMode = "fill"
    crop_px: int = 0
    """Pixels trimmed from every border (NYU-v2's white frame: 8-10)."""
    size: tuple[int, int] | None = None
    """Output (width, height): centre-crop to that aspect ratio, then resize."""

    def __post_init__(self) -> None:
        check_positive("depth_scale", self.depth_scale)
        if self.depth_encoding not in DEPTH_ENCODINGS:
            raise ValueError(
                f"depth_encoding: expected one of {', '.join(DEPTH_ENCODINGS)}, got {self.depth_encoding!r}"
            )
        if self.depth_from not in DEPTH_FROM:
            raise ValueError(f"depth_from: expected one of {', '.join(DEPTH_FROM)}, got {self.depth_from!r}")
        if self.invalid_depth not in ("fill", "far", "fail"):
            raise ValueError(f"invalid_depth: expected 'fill', 'far' or 'fail', got {self.invalid_depth!r}")
        if self.crop_px < 0:
            raise ValueError(f"crop_px: expected >= 0, got {self.crop_px}")
        if self.size is not None and (len(self.size) != 2 or min(self.size) < 8 or max(self.size) > 16384):
            raise ValueError(f"size: expected (width, height) with 8 <= each <= 16384, got {self.size}")


@dataclass(frozen=True)
class OutputConfig:
    """What is written besides the degraded images."""

    save_intermediate: bool = False
    """Also write basic/ (Eq. 1 result) and transmission/ (T as an RGB image)."""
    png_compression: int = 3
    """Deflate level 0-9 of the image PNG files (0 stores; 1-3 murk's fast path, ISA-L's deflate when ``isal`` is
    installed; 4-9 libpng's adaptive filters and zlib, smaller and slower; see :func:`murk.io.images.encode_png`).
    Depth maps are always written at level 3."""

    def __post_init__(self) -> None:
        if not 0 <= self.png_compression <= 9:
            raise ValueError(f"png_compression: expected 0-9, got {self.png_compression}")


@dataclass(frozen=True)
class SynthConfig:
    """A whole synthesis run. Defaults reproduce the paper (8 variants, all ten water types)."""

    stages: tuple[str, ...] = ("basic", "forward_scatter")
    variants: int = 8
    seed: int = 0
    workers: int = 1
    medium: MediumConfig = field(default_factory=MediumConfig)
    forward_scatter: ForwardScatterConfig = field(default_factory=ForwardScatterConfig)
    marine_snow: SnowConfig = field(default_factory=SnowConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    input: InputConfig = field(default_factory=InputConfig)
    output: OutputConfig = field(default_factory=OutputConfig)

    def __post_init__(self) -> None:
        object.__setattr__(self, "stages", parse_stages(self.stages))
        if self.variants < 1:
            raise ValueError(f"variants: expected >= 1, got {self.variants}")
        if self.workers < 1:
            raise ValueError(f"workers: expected >= 1, got {self.workers}")
        if self.input.depth_relative and self.medium.distance_mode == "metric":
            raise ValueError("depth_relative: relative depth has no metric scale; use distance_mode 'normalized'")
