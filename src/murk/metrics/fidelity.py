"""Input-vs-output restoration measures that noise cannot fool: artefacts, structure, particles, cast, exposure.

UIQM and UCIQE score an output alone and reward contrast and edges, wherever they come from: a restoration
destroyed by a pixel-shuffle checkerboard or by noise scores higher than a sensible one. The measures here
compare a method's ``output`` with the raw degraded ``input`` it was computed from (same shape, float RGB in
[0, 1]) and are built so that a legitimate restoration (global or local contrast and colour changes) keeps
them near their identity values while artefacts, blur and collapse move them clearly:

- :func:`artefact_energy` / :func:`artefact_ratio`: periodic (tiling, checkerboard) and isolated (pixel
  noise, impulses) energy of the luminance, as fractions of the image's own signal energy.
- :func:`structure_fidelity`: Gradient Magnitude Similarity (Xue et al. 2014) of the locally contrast-
  normalised luminances: do the output's edges follow the input's?
- :func:`particle_count`: small isolated bright (marine snow) and dark blobs per megapixel.
- :func:`colour_exposure`: colour cast (CIELAB chroma of the mean colour), mean luminance and contrast.
- :func:`restoration_measures`: all of them for one (input, output) pair as a flat ``dict``;
  :func:`flags` turns it into named warnings with the thresholds below.

Luminance everywhere is the Rec. 709 luma ``Y = 0.2126 R + 0.7152 G + 0.0722 B`` of the (gamma-encoded)
RGB values. Ratios are ``(out + floor) / (in + floor)``, so an identical pair gives exactly 1.0 and a zero
input gives a finite ratio; each floor is a module constant. Every function works at full resolution in
float32 (the spectrum in complex64 where numpy >= 2 keeps single precision). ``docs/metrics.md`` has the
calibration on the shipped real images.

References:
    W. Xue, L. Zhang, X. Mou, A. C. Bovik, "Gradient Magnitude Similarity Deviation: A Highly Efficient
    Perceptual Image Quality Index", IEEE Trans. Image Process. 23(2):684-695, 2014,
    doi:10.1109/TIP.2013.2293423 (GMS map, Prewitt filters).
    A. Mittal, A. K. Moorthy, A. C. Bovik, "No-Reference Image Quality Assessment in the Spatial Domain", IEEE
    Trans. Image Process. 21(12):4695-4708, 2012, doi:10.1109/TIP.2012.2214050 (local mean / contrast
    normalisation, the MSCN coefficients).
    L. Moisan, "Periodic Plus Smooth Image Decomposition", J. Math. Imaging Vis. 39(2):161-179, 2011,
    doi:10.1007/s10851-010-0227-1 (spectrum without the image-border cross).
    A. Odena, V. Dumoulin, C. Olah, "Deconvolution and Checkerboard Artifacts", Distill, 2016,
    doi:10.23915/distill.00003 (why upsampling layers leave period-2/4/8 patterns).
    Rec. ITU-R BT.709-6 (luma weights); CIE 15:2004 (CIELAB, through OpenCV's sRGB conversion).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from murk.errors import ShapeError
from murk.metrics._common import check_rgb_numpy, warn_metric
from murk.snow.extract import ExtractConfig, kept_components, particle_mask

LUMA_WEIGHTS = (0.2126, 0.7152, 0.0722)
"""Rec. 709 luma weights (R, G, B) of every luminance in this module."""

# --- artefact energy ---------------------------------------------------------------------------------------
ARTEFACT_PERIODS_PX = (2, 4, 8, 16)
"""Tiling periods whose spectral grid is searched (each coarser grid is a subset of the period-16 grid)."""
ARTEFACT_MIN_SIZE_PX = 32
"""Smallest cropped height/width for the periodic term (grid bins must have non-grid neighbours)."""
ARTEFACT_FLOOR = 1e-4
"""Added to both energies of :func:`artefact_ratio` (fractions of the signal energy). 1e-4 is the periodic
energy of a period-2 checkerboard of 1 % of the image's luminance std: invisible."""
GRADIENT_ENERGY_FLOOR = 1e-6
"""Lower bound of the gradient energy that divides the isolated energy (a flat image gives 0, not 0/0)."""

# --- structure fidelity ------------------------------------------------------------------------------------
GMS_C = 0.01
"""GMS stability constant c, in units of the normalised luminance's squared gradient (calibrated)."""
GMS_WINDOW_SIGMA_PX = 3.0
"""Standard deviation of the Gaussian window of the local mean/contrast normalisation."""
GMS_EPS_FRACTION = 0.05
"""The local std is regularised by this fraction of the image's global luminance std."""
STD_FLOOR = 0.01
"""Lower bound of a global luminance std used for normalisation (2.55 grey levels of 255)."""

# --- particles ---------------------------------------------------------------------------------------------
PARTICLE_CONFIG = ExtractConfig(method="tophat")
"""murk's marine-snow extractor settings used to count particles: top-hat with a 15-px ellipse, response
> 20 of 255, opening 2 px, closing 3 px, 2-400 px area, elongation <= 3 (see :mod:`murk.snow.extract`)."""
PARTICLE_PERCENTILES = (0.5, 99.5)
"""Luminance percentiles stretched to 0 and 255 before counting (so the count ignores global contrast)."""
PARTICLE_SPAN_FLOOR = 0.05
"""Lower bound of the percentile span (the stretch gain is at most 20)."""
PARTICLE_FLOOR_PER_MP = 10.0
"""Added to both totals of ``particle_residue_ratio`` (3 particles in a 640x480 frame)."""

# --- exposure ----------------------------------------------------------------------------------------------
EXPOSURE_FLOOR = 1e-3
"""Added to both sides of ``luminance_ratio`` and ``contrast_ratio``."""

# --- flags -------------------------------------------------------------------------------------------------
ARTEFACT_RATIO_MAX = 1.3
"""Flag ``artefacts`` when the periodic or the isolated energy ratio exceeds this."""
STRUCTURE_GMS_MIN = 0.7
"""Flag ``structure loss`` below this mean GMS. Calibrated on the 13 shipped real images: histogram
equalisation, HE + LoG (Eq. 9), CLAHE, gamma 0.6, a contrast stretch and JPEG q75 stay >= 0.79, a Gaussian
blur of sigma 3 px gives <= 0.62, a flat grey <= 0.31 (``docs/metrics.md``)."""
CONTRAST_RATIO_MIN = 0.5
"""Flag ``grey collapse`` when the output's luminance std is below this fraction of the input's."""
LUMINANCE_RATIO_MIN = 0.9
"""Flag ``darkened`` when the output's mean luminance is below this fraction of the input's."""
PARTICLE_RATIO_MAX = 1.0
"""Flag ``particles not removed`` when the output has more particles per megapixel than the input."""

FLAG_NAMES = ("artefacts", "structure loss", "grey collapse", "darkened", "particles not removed")
"""Every flag :func:`flags` can return, in the order it returns them."""
FLAG_SEPARATOR = "; "
"""Separator of the flags joined into one string (:func:`join_flags`)."""

MEASURE_KEYS = (
    "artefact_periodic_ratio",
    "artefact_isolated_ratio",
    "structure_gms",
    "structure_gmsd",
    "particles_bright_in",
    "particles_bright_out",
    "particles_dark_in",
    "particles_dark_out",
    "particle_residue_ratio",
    "cast_in",
    "cast_out",
    "luminance_in",
    "luminance_out",
    "luminance_ratio",
    "contrast_in",
    "contrast_out",
    "contrast_ratio",
)
"""Keys of :func:`restoration_measures`, in order."""

_PREWITT = np.array([[1.0, 0.0, -1.0]] * 3, np.float32) / np.float32(3.0)  # Xue et al. 2014, Eq. (1)
_MSG_SMALL = (
    "image {h}x{w}: the periodic artefact energy needs at least {m}x{m} pixels (after cropping to a multiple of "
    "16), set to 0"
)


@dataclass(frozen=True)
class ArtefactEnergy:
    """Artefact energy of one image (:func:`artefact_energy`), or the output/input ratios
    (:func:`artefact_ratio`). Both are >= 0; larger = more artefacts."""

    periodic: float
    """Spectral peak energy at the period-2/4/8/16 grid frequencies / total non-DC spectral energy."""
    isolated: float
    """Mean squared residual of the luminance from its 3x3 median / mean squared Prewitt gradient."""


@dataclass(frozen=True)
class StructureFidelity:
    """Gradient Magnitude Similarity of the output's structure to the input's (:func:`structure_fidelity`)."""

    gms_mean: float
    """Mean of the GMS map, in (0, 1]; 1 = the output's edges are the input's (up to local contrast)."""
    gmsd: float
    """Standard deviation of the GMS map (GMSD, Xue et al. 2014); 0 for an identical pair."""


@dataclass(frozen=True)
class ParticleCount:
    """Small isolated blobs per megapixel (:func:`particle_count`)."""

    bright_per_mp: float
    """Bright blobs (white top-hat): marine snow, specular specks."""
    dark_per_mp: float
    """Dark blobs (black top-hat): dirt, dead pixels, dark artefacts."""

    @property
    def total_per_mp(self) -> float:
        return self.bright_per_mp + self.dark_per_mp


@dataclass(frozen=True)
class ColourExposure:
    """Colour cast and exposure of one image (:func:`colour_exposure`)."""

    cast: float
    """``hypot(mean a*, mean b*)`` in CIELAB units: 0 for a neutral (grey-world) image."""
    luminance: float
    """Mean Rec. 709 luma, in [0, 1]."""
    contrast: float
    """Population standard deviation of the Rec. 709 luma."""


# ----------------------------------------------------------------------------------------------------------
# validation and shared pieces


def _check_image(name: str, image: Any) -> np.ndarray:
    """A float RGB (H, W, 3) image in [0, 1], returned as float32."""
    if isinstance(image, np.ndarray) and not np.issubdtype(image.dtype, np.floating):
        raise TypeError(
            f"{name}: expected a float RGB image in [0, 1] (convert integer images with murk.io.to_float), "
            f"got dtype {image.dtype}"
        )
    check_rgb_numpy(name, image, 1.0)
    return np.clip(image, 0.0, 1.0).astype(np.float32, copy=False)


def _check_pair(input: Any, output: Any) -> tuple[np.ndarray, np.ndarray]:
    x = _check_image("input", input)
    y = _check_image("output", output)
    if x.shape != y.shape:
        raise ShapeError(f"output: expected the shape of input {x.shape}, got {y.shape}")
    return x, y


def _luma(image: np.ndarray) -> np.ndarray:
    """Rec. 709 luma (H, W) float32 of a validated float32 RGB image."""
    wr, wg, wb = (np.float32(w) for w in LUMA_WEIGHTS)
    return wr * image[..., 0] + wg * image[..., 1] + wb * image[..., 2]


def _ratio(out: float, inp: float, floor: float) -> float:
    return (out + floor) / (inp + floor)


def _prewitt_magnitude2(y: np.ndarray) -> np.ndarray:
    """Squared Prewitt gradient magnitude ``gx^2 + gy^2`` (Xue et al. 2014, Eq. (1)), replicated border."""
    gx = cv2.filter2D(y, cv2.CV_32F, _PREWITT, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.filter2D(y, cv2.CV_32F, _PREWITT.T, borderType=cv2.BORDER_REPLICATE)
    return gx * gx + gy * gy


# ----------------------------------------------------------------------------------------------------------
# (a) artefact energy


def artefact_energy(image: np.ndarray) -> ArtefactEnergy:
    """Periodic and isolated high-frequency energy of an image's luminance, as fractions of its signal energy.

    ``periodic``: ``Y`` is cropped to its top-left ``H' x W'`` with ``H'``, ``W'`` multiples of 16, its
    border discontinuity removed by Moisan's periodic-plus-smooth decomposition (otherwise the image edges put
    a cross of energy on the spectrum's axes), and its power spectrum ``E = |FFT(Y - mean Y)|^2`` taken. A
    pattern tiled with a period of 2, 4, 8 or 16 px (pixel-shuffle or transposed-convolution checkerboards,
    patch tiling; Odena et al. 2016) puts its energy exactly on the grid bins
    ``G = {(i H'/16, j W'/16) : 0 <= i, j < 16} minus DC``. Each grid bin's peak is its energy above the
    median of its 8 neighbouring bins (the local spectral background, which natural images fill smoothly)::

        periodic = sum_{g in G} max(E(g) - median_8(E around g), 0) / sum_{k != DC} E(k)

    ``isolated``: energy that a 3x3 median removes (impulses, salt-and-pepper and pixel noise, one-pixel
    speckle) relative to the image's edge energy::

        isolated = mean((Y - median_3x3(Y))^2) / max(mean(|grad_Prewitt Y|^2), 1e-6)

    Both are ratios of energies of the same image, so they do not change with a global contrast change.

    Args:
        image: float RGB (H, W, 3) in [0, 1].

    Returns:
        :class:`ArtefactEnergy`; a flat image gives (0, 0).

    Raises:
        TypeError: not a float numpy array.
        ShapeError: not (H, W, 3).
        ValueError: NaN/inf, or values outside [0, 1].

    Warns:
        MetricWarning: the cropped image is smaller than 32x32 (``periodic`` is then 0).
    """
    return _artefact(_luma(_check_image("image", image)))


def _artefact(y: np.ndarray) -> ArtefactEnergy:
    return ArtefactEnergy(_periodic_energy(y), _isolated_energy(y))


def _periodic_energy(y: np.ndarray) -> float:
    grid = max(ARTEFACT_PERIODS_PX)
    h, w = (y.shape[0] // grid) * grid, (y.shape[1] // grid) * grid
    if min(h, w) < ARTEFACT_MIN_SIZE_PX:
        warn_metric(_MSG_SMALL.format(h=y.shape[0], w=y.shape[1], m=ARTEFACT_MIN_SIZE_PX))
        return 0.0
    u = y[:h, :w] - np.float32(y[:h, :w].mean(dtype=np.float64))
    spectrum = _periodic_component_fft(u)
    power = spectrum.real**2 + spectrum.imag**2
    power[0, 0] = 0.0
    total = float(power.sum(dtype=np.float64))
    if total <= 0.0:
        return 0.0
    rows = np.arange(grid) * (h // grid)
    cols = np.arange(grid) * (w // grid)
    peaks = power[np.ix_(rows, cols)]
    neighbours = [
        power[np.ix_((rows + dy) % h, (cols + dx) % w)] for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0)
    ]
    excess = np.maximum(peaks - np.median(np.stack(neighbours), axis=0), 0.0).astype(np.float64)
    excess[0, 0] = 0.0  # DC
    return float(excess.sum() / total)


def _periodic_component_fft(u: np.ndarray) -> np.ndarray:
    """FFT of the periodic component of ``u`` (Moisan 2011): ``FFT(u) - FFT(s)``, with the smooth component
    ``s`` solving ``Laplacian_periodic(s) = v``, ``v`` the jumps across opposite borders (Moisan's Eq. (11))."""
    h, w = u.shape
    v = np.zeros_like(u)
    v[0, :] = u[-1, :] - u[0, :]
    v[-1, :] = u[0, :] - u[-1, :]
    v[:, 0] += u[:, -1] - u[:, 0]
    v[:, -1] += u[:, 0] - u[:, -1]
    cy = np.cos(2.0 * np.pi * np.arange(h) / h).astype(u.dtype)[:, None]
    cx = np.cos(2.0 * np.pi * np.arange(w) / w).astype(u.dtype)[None, :]
    denom = 2.0 * cy + 2.0 * cx - 4.0  # eigenvalues of the periodic discrete Laplacian
    denom[0, 0] = 1.0
    smooth = np.fft.fft2(v) / denom
    smooth[0, 0] = 0.0
    return np.fft.fft2(u) - smooth


def _isolated_energy(y: np.ndarray) -> float:
    residual = y - cv2.medianBlur(y, 3)
    r2 = float(np.mean(np.square(residual, dtype=np.float32), dtype=np.float64))
    g2 = float(np.mean(_prewitt_magnitude2(y), dtype=np.float64))
    return r2 / max(g2, GRADIENT_ENERGY_FLOOR)


def artefact_ratio(input: np.ndarray, output: np.ndarray) -> ArtefactEnergy:
    """Output's artefact energy over the input's, per term: ``(E_out + 1e-4) / (E_in + 1e-4)``.

    The floor (:data:`ARTEFACT_FLOOR`) keeps a flat or artefact-free input finite; it equals the periodic
    energy of a checkerboard of 1 % of the luminance std. 1.0 = no change (exactly 1.0 for an identical pair);
    above :data:`ARTEFACT_RATIO_MAX` (1.3) :func:`flags` says ``artefacts``. See :func:`artefact_energy`.

    Raises:
        TypeError, ShapeError, ValueError: as :func:`artefact_energy`, per image; shapes differ.
    """
    x, y = _check_pair(input, output)
    e_in, e_out = _artefact(_luma(x)), _artefact(_luma(y))
    return ArtefactEnergy(
        _ratio(e_out.periodic, e_in.periodic, ARTEFACT_FLOOR), _ratio(e_out.isolated, e_in.isolated, ARTEFACT_FLOOR)
    )


# ----------------------------------------------------------------------------------------------------------
# (b) structure fidelity


def structure_fidelity(input: np.ndarray, output: np.ndarray, where: np.ndarray | None = None) -> StructureFidelity:
    """Gradient Magnitude Similarity (Xue et al. 2014) of the output's luminance structure to the input's.

    Each luminance is first normalised to zero local mean and unit local contrast (Mittal et al. 2012's MSCN
    normalisation) with a Gaussian window of sigma 3 px::

        z = (Y - mu) / (sigma + 0.05 max(std(Y), 0.01)),   mu = G_3 * Y,   sigma^2 = G_3 * Y^2 - mu^2

    then, with Prewitt gradient magnitudes ``g`` of ``z`` (Xue et al. 2014, Eq. (1)), the GMS map
    (Eq. (4) there) is::

        GMS = (2 g_in g_out + c) / (g_in^2 + g_out^2 + c),   c = 0.01

    ``gms_mean`` is its mean, ``gmsd`` its standard deviation (Eq. (8)). Xue et al. normalise nothing (they
    compare a distorted image with its pristine reference); a restoration legitimately changes contrast, so
    murk compares locally normalised images: any global or slowly varying contrast/brightness change (a
    stretch, gamma, histogram equalisation, CLAHE) leaves ``z`` nearly unchanged and the GMS near 1, while blur
    (edges spread), noise (new gradients) and a collapse to flat grey (no gradients, ``z = 0``) lower it. A
    global normalisation (zero mean, unit std) was not enough: on the shipped real images it scores
    histogram equalisation (>= 0.79) below a sigma-3 blur (up to 0.96); the local one separates them (>= 0.79
    vs <= 0.62). A purely linear contrast reduction is invisible here by design; ``contrast_ratio`` catches it.

    Args:
        input: the raw degraded image, float RGB (H, W, 3) in [0, 1].
        output: a method's result of the same shape.
        where: optional boolean mask (H, W): the map's mean and deviation over these pixels only (e.g. away
            from marine-snow particles, :func:`murk.metrics.snow_pairs.snow_free_mask`); NaN if it is empty.

    Returns:
        :class:`StructureFidelity`; exactly (1.0, 0.0) for an identical pair.

    Raises:
        TypeError, ShapeError, ValueError: as :func:`artefact_energy`, per image; shapes differ.
    """
    x, y = _check_pair(input, output)
    if where is not None and np.shape(where) != x.shape[:2]:
        raise ShapeError(f"where: expected a mask of {x.shape[1]}x{x.shape[0]}, got shape {np.shape(where)}")
    return _structure(_luma(x), _luma(y), where)


def _structure(y_in: np.ndarray, y_out: np.ndarray, where: np.ndarray | None = None) -> StructureFidelity:
    g_in = np.sqrt(_prewitt_magnitude2(_local_normalise(y_in)))
    g_out = np.sqrt(_prewitt_magnitude2(_local_normalise(y_out)))
    c = np.float32(GMS_C)
    gms = (np.float32(2.0) * g_in * g_out + c) / (g_in * g_in + g_out * g_out + c)  # Xue et al. 2014, Eq. (4)
    if where is not None:
        gms = gms[np.asarray(where, bool)]
        if not gms.size:
            return StructureFidelity(float("nan"), float("nan"))
    return StructureFidelity(float(gms.mean(dtype=np.float64)), float(gms.std(dtype=np.float64)))


def _local_normalise(y: np.ndarray) -> np.ndarray:
    """MSCN-style local normalisation ``(Y - mu) / (sigma + eps)`` with a Gaussian window (see above)."""
    mu = cv2.GaussianBlur(y, (0, 0), GMS_WINDOW_SIGMA_PX)
    var = cv2.GaussianBlur(y * y, (0, 0), GMS_WINDOW_SIGMA_PX) - mu * mu
    sigma = np.sqrt(np.maximum(var, 0.0))
    eps = np.float32(GMS_EPS_FRACTION * max(float(y.std(dtype=np.float64)), STD_FLOOR))
    return (y - mu) / (sigma + eps)


# ----------------------------------------------------------------------------------------------------------
# (c) particle residue


def particle_count(image: np.ndarray) -> ParticleCount:
    """Small isolated bright and dark blobs per megapixel, found with murk's marine-snow extractor.

    The luminance is stretched so that its 0.5th and 99.5th percentiles map to 0 and 255 (span at least 0.05,
    so the count does not depend on global contrast), quantised to 8 bits, and passed to
    :func:`murk.snow.extract.particle_mask` with :data:`PARTICLE_CONFIG` (white top-hat with a 15-px ellipse,
    response > 20 of 255, opening, closing); the components kept by
    :func:`murk.snow.extract.kept_components` (2-400 px, elongation <= 3) are counted. Dark blobs are the
    same on the inverted luminance (``255 - Y``), i.e. the black top-hat.

    Args:
        image: float RGB (H, W, 3) in [0, 1].

    Returns:
        :class:`ParticleCount` (per 10^6 pixels).

    Raises:
        TypeError, ShapeError, ValueError: as :func:`artefact_energy`.
    """
    return _particles(_luma(_check_image("image", image)))


def _particles(y: np.ndarray) -> ParticleCount:
    lo, hi = np.percentile(y, PARTICLE_PERCENTILES)
    span = max(float(hi) - float(lo), PARTICLE_SPAN_FLOOR)
    gray = np.rint(np.clip((y - np.float32(lo)) * np.float32(255.0 / span), 0.0, 255.0)).astype(np.uint8)
    megapixels = y.size / 1e6
    bright = len(kept_components(particle_mask(gray, PARTICLE_CONFIG), PARTICLE_CONFIG))
    dark = len(kept_components(particle_mask(255 - gray, PARTICLE_CONFIG), PARTICLE_CONFIG))
    return ParticleCount(bright / megapixels, dark / megapixels)


# ----------------------------------------------------------------------------------------------------------
# (d) colour cast and exposure


def colour_exposure(image: np.ndarray) -> ColourExposure:
    """Colour cast, mean luminance and luminance contrast of an image.

    ``cast = hypot(mean a*, mean b*)``: the CIELAB chroma of the image's mean chromaticity (OpenCV's float
    ``RGB2Lab``: sRGB, D65), 0 for a grey-world neutral image; underwater images are typically blue-green
    (negative a*). ``luminance = mean(Y)`` and ``contrast = std(Y)`` (population) of the Rec. 709 luma ``Y``
    in [0, 1].

    Raises:
        TypeError, ShapeError, ValueError: as :func:`artefact_energy`.
    """
    x = _check_image("image", image)
    return _colour(x, _luma(x))


def _colour(x: np.ndarray, y: np.ndarray) -> ColourExposure:
    lab = cv2.cvtColor(np.ascontiguousarray(x), cv2.COLOR_RGB2Lab)
    a_mean = float(lab[..., 1].mean(dtype=np.float64))
    b_mean = float(lab[..., 2].mean(dtype=np.float64))
    return ColourExposure(math.hypot(a_mean, b_mean), float(y.mean(dtype=np.float64)), float(y.std(dtype=np.float64)))


# ----------------------------------------------------------------------------------------------------------
# one entry point and the flags


def restoration_measures(input: np.ndarray, output: np.ndarray) -> dict[str, float]:
    """Every measure of this module for one (input, output) pair, as a flat dict with :data:`MEASURE_KEYS`.

    - ``artefact_periodic_ratio``, ``artefact_isolated_ratio``: :func:`artefact_ratio`.
    - ``structure_gms``, ``structure_gmsd``: :func:`structure_fidelity`.
    - ``particles_{bright,dark}_{in,out}``: :func:`particle_count` per megapixel;
      ``particle_residue_ratio = (bright_out + dark_out + 10) / (bright_in + dark_in + 10)``.
    - ``cast_{in,out}``, ``luminance_{in,out}``, ``contrast_{in,out}``: :func:`colour_exposure`;
      ``luminance_ratio`` and ``contrast_ratio`` are ``(out + 1e-3) / (in + 1e-3)``.

    An identical pair gives exactly 1.0 for every ratio and ``structure_gms``, and 0.0 for ``structure_gmsd``.

    Args:
        input: the raw degraded image, float RGB (H, W, 3) in [0, 1].
        output: a method's result of the same shape.

    Raises:
        TypeError: not float numpy arrays.
        ShapeError: not (H, W, 3), or the shapes differ.
        ValueError: NaN/inf, or values outside [0, 1].
    """
    x, y = _check_pair(input, output)
    y_in, y_out = _luma(x), _luma(y)
    e_in, e_out = _artefact(y_in), _artefact(y_out)
    s = _structure(y_in, y_out)
    p_in, p_out = _particles(y_in), _particles(y_out)
    c_in, c_out = _colour(x, y_in), _colour(y, y_out)
    return {
        "artefact_periodic_ratio": _ratio(e_out.periodic, e_in.periodic, ARTEFACT_FLOOR),
        "artefact_isolated_ratio": _ratio(e_out.isolated, e_in.isolated, ARTEFACT_FLOOR),
        "structure_gms": s.gms_mean,
        "structure_gmsd": s.gmsd,
        "particles_bright_in": p_in.bright_per_mp,
        "particles_bright_out": p_out.bright_per_mp,
        "particles_dark_in": p_in.dark_per_mp,
        "particles_dark_out": p_out.dark_per_mp,
        "particle_residue_ratio": _ratio(p_out.total_per_mp, p_in.total_per_mp, PARTICLE_FLOOR_PER_MP),
        "cast_in": c_in.cast,
        "cast_out": c_out.cast,
        "luminance_in": c_in.luminance,
        "luminance_out": c_out.luminance,
        "luminance_ratio": _ratio(c_out.luminance, c_in.luminance, EXPOSURE_FLOOR),
        "contrast_in": c_in.contrast,
        "contrast_out": c_out.contrast,
        "contrast_ratio": _ratio(c_out.contrast, c_in.contrast, EXPOSURE_FLOOR),
    }


_FLAG_INPUTS = (
    "artefact_periodic_ratio",
    "artefact_isolated_ratio",
    "structure_gms",
    "contrast_ratio",
    "luminance_ratio",
    "particle_residue_ratio",
)


def flags(measures: Mapping[str, float]) -> list[str]:
    """Named problems of one (input, output) pair, from :func:`restoration_measures`, in :data:`FLAG_NAMES` order.

    - ``artefacts``: ``artefact_periodic_ratio`` or ``artefact_isolated_ratio`` > 1.3 (:data:`ARTEFACT_RATIO_MAX`);
    - ``structure loss``: ``structure_gms`` < 0.7 (:data:`STRUCTURE_GMS_MIN`);
    - ``grey collapse``: ``contrast_ratio`` < 0.5 (:data:`CONTRAST_RATIO_MIN`);
    - ``darkened``: ``luminance_ratio`` < 0.9 (:data:`LUMINANCE_RATIO_MIN`);
    - ``particles not removed``: ``particle_residue_ratio`` > 1.0 (:data:`PARTICLE_RATIO_MAX`).

    NaN values raise no flag.

    Raises:
        TypeError: ``measures`` is not a mapping.
        ValueError: a needed key is missing.
    """
    if not isinstance(measures, Mapping):
        raise TypeError(f"measures: expected a mapping from restoration_measures, got {type(measures).__name__}")
    missing = [k for k in _FLAG_INPUTS if k not in measures]
    if missing:
        raise ValueError(f"measures: expected the keys of restoration_measures, missing {', '.join(missing)}")
    m = {k: float(measures[k]) for k in _FLAG_INPUTS}
    raised = {
        "artefacts": m["artefact_periodic_ratio"] > ARTEFACT_RATIO_MAX
        or m["artefact_isolated_ratio"] > ARTEFACT_RATIO_MAX,
        "structure loss": m["structure_gms"] < STRUCTURE_GMS_MIN,
        "grey collapse": m["contrast_ratio"] < CONTRAST_RATIO_MIN,
        "darkened": m["luminance_ratio"] < LUMINANCE_RATIO_MIN,
        "particles not removed": m["particle_residue_ratio"] > PARTICLE_RATIO_MAX,
    }
    return [name for name in FLAG_NAMES if raised[name]]


def join_flags(names: Iterable[str]) -> str:
    """Flags as one string for tables (``"artefacts; darkened"``; ``""`` when there is none)."""
    return FLAG_SEPARATOR.join(names)


def count_flags(joined: Iterable[str]) -> dict[str, int]:
    """Count flags over rows given as :func:`join_flags` strings.

    Returns:
        ``{"flagged": rows with at least one flag, "n": rows, <flag name>: rows with that flag, ...}`` with
        every name of :data:`FLAG_NAMES`.
    """
    counts = {"flagged": 0, "n": 0, **dict.fromkeys(FLAG_NAMES, 0)}
    for text in joined:
        counts["n"] += 1
        names = [f for f in text.split(FLAG_SEPARATOR) if f] if text else []
        counts["flagged"] += bool(names)
        for f in names:
            if f not in counts:
                raise ValueError(f"flags: expected names from {', '.join(FLAG_NAMES)}, got {f!r}")
            counts[f] += 1
    return counts
