"""Marine-snow removal measured on pairs of the same real scene without and with snow.

A no-reference particle count (:func:`murk.metrics.particle_count`) cannot tell snow from the scene's own
small bright details. With a snow-free image ``clean`` of the same scene as the snowy one, the particle sites
are known: they are where ``snowy`` is brighter than ``clean`` in small blobs. A restorer removes the snow
when its outputs for the snowy and for the clean image no longer differ there.

Definitions (luma ``Y`` of Rec. 709, float in [0, 1]):

- **sites** (:func:`snow_sites`): ``D = Y(snowy) - Y(clean)``; pixels with ``D > site_threshold`` (default
  0.04, about 10 of 255 levels) form connected components (8-connectivity); components of ``min_area`` to
  ``max_area`` pixels (2-400) are the particle sites (larger ones are scene changes, not particles).
- **residue** (:func:`snow_residue`) of a restorer with outputs ``S = R(snowy)`` and ``C = R(clean)``:
  ``D' = (Y(S) - Y(C)) / g`` with ``g = std(Y(C)) / std(Y(clean))`` the restorer's own contrast gain (a
  contrast stretch amplifies the particles' difference as much as everything else, which is not a failure to
  remove them), then ``residue = sum_sites max(D', 0) / sum_sites max(D, 0)``: 1 = the particles kept their
  contrast, 0 = removed, > 1 = amplified. ``sites_left`` is the share of sites whose peak ``D'`` is still at
  least half of its peak ``D``.
- **colour residue** (``colour_residue`` of :func:`snow_residue`): the same ratio for the RGB difference,
  ``sum_sites ||S - C|| / g_rgb / sum_sites ||snowy - clean||`` (Euclidean norm over the three channels), with
  ``g_rgb = ||std_c(C)|| / ||std_c(clean)||`` the restorer's colour contrast gain (the norm of the three channel
  standard deviations), so that a colour stretch alone reads 1 as a luma stretch does above. The luma residue
  counts only what is still brighter than the snow-free output, so a particle turned into a darker or coloured dot
  counts as removed there; here it does not (a dot as different as the particle reads 1).

- **snow-free structure**: "removing snow without blurring the rest" is read with the structure fidelity
  (GMS, :func:`murk.metrics.fidelity.structure_fidelity`) of ``R(snowy)`` to ``snowy`` over the pixels at least
  :data:`CLEAR_MARGIN_PX` away from every site (:func:`snow_free_mask`).

The raw input (``R`` the identity) has residue 1 and sites_left 1 by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from murk.errors import ShapeError

SITE_THRESHOLD = 0.04
"""Luma excess of the snowy image over the clean one that marks a particle pixel (~10 of 255 levels)."""
MIN_AREA_PX = 2
MAX_AREA_PX = 400
GAIN_FLOOR = 1e-3
CLEAR_MARGIN_PX = 3
"""Pixels this close to a particle site are left out of the snow-free structure measure."""


@dataclass(frozen=True)
class SnowSites:
    """Particle sites of a snowy/clean pair: ``labels`` (H, W) int32 (0 = no site, k = site k), ``count``,
    ``excess`` (H, W) float32, the luma excess ``D``, and ``colour_diff`` (H, W) float32, ``||snowy - clean||``."""

    labels: np.ndarray
    count: int
    excess: np.ndarray
    colour_diff: np.ndarray

    @property
    def per_megapixel(self) -> float:
        return self.count / (self.labels.size / 1e6)


@dataclass(frozen=True)
class SnowResidue:
    """:func:`snow_residue`: contrast-normalised share of the particles' luma excess left (``residue``), share
    of sites still visible (``sites_left``), the sites per megapixel, the contrast gain used, and the share of the
    particles' RGB difference left (``colour_residue``)."""

    residue: float
    sites_left: float
    sites_per_mp: float
    gain: float
    colour_residue: float = float("nan")


def _luma(image: np.ndarray, name: str) -> np.ndarray:
    if not isinstance(image, np.ndarray) or image.ndim != 3 or image.shape[2] != 3:
        raise ShapeError(f"{name}: expected an RGB image (H, W, 3), got {getattr(image, 'shape', type(image))}")
    x = np.asarray(image, np.float32)
    return x[..., 0] * np.float32(0.2126) + x[..., 1] * np.float32(0.7152) + x[..., 2] * np.float32(0.0722)


def snow_sites(
    snowy: np.ndarray,
    clean: np.ndarray,
    *,
    site_threshold: float = SITE_THRESHOLD,
    min_area: int = MIN_AREA_PX,
    max_area: int = MAX_AREA_PX,
) -> SnowSites:
    """The particle sites of a pair (module doc). Both float RGB (H, W, 3) in [0, 1], one shape.

    Raises:
        ShapeError: not RGB, or the shapes differ.
    """
    ys, yc = _luma(snowy, "snowy"), _luma(clean, "clean")
    if ys.shape != yc.shape:
        raise ShapeError(f"snowy {ys.shape[1]}x{ys.shape[0]} and clean {yc.shape[1]}x{yc.shape[0]} differ in size")
    excess = ys - yc
    mask = (excess > np.float32(site_threshold)).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    areas = stats[1:, cv2.CC_STAT_AREA]
    keep = np.zeros(n, np.int32)
    kept = np.flatnonzero((areas >= min_area) & (areas <= max_area)) + 1
    keep[kept] = np.arange(1, kept.size + 1, dtype=np.int32)
    diff = np.linalg.norm(np.asarray(snowy, np.float32) - np.asarray(clean, np.float32), axis=-1)
    return SnowSites(keep[labels], int(kept.size), excess, diff.astype(np.float32))


def snow_residue(sites: SnowSites, clean: np.ndarray, out_snowy: np.ndarray, out_clean: np.ndarray) -> SnowResidue:
    """The residue of a restorer's outputs ``out_snowy = R(snowy)``, ``out_clean = R(clean)`` on ``sites``
    (module doc). ``clean`` is the snow-free input (for the contrast gain). Outputs at another size than the
    pair are resized to it (area or bilinear). With no site, residue, sites_left and colour_residue are NaN."""
    h, w = sites.labels.shape
    rgbs = []
    for name, o in (("out_snowy", out_snowy), ("out_clean", out_clean)):
        _luma(o, name)  # the shape check
        rgb = np.asarray(o, np.float32)
        if rgb.shape[:2] != (h, w):
            shrink = rgb.shape[0] * rgb.shape[1] > h * w
            rgb = np.asarray(
                cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR), np.float32
            )
        rgbs.append(rgb)
    ys, yc = (_luma(x, "output") for x in rgbs)
    gain = max(float(yc.std()) / max(float(_luma(clean, "clean").std()), GAIN_FLOOR), GAIN_FLOOR)
    d_out = (ys - yc) / np.float32(gain)
    on = sites.labels > 0
    if not sites.count:
        return SnowResidue(float("nan"), float("nan"), 0.0, gain)
    before = np.maximum(sites.excess[on], 0.0)
    after = np.maximum(d_out[on], 0.0)
    residue = float(after.sum() / max(float(before.sum()), 1e-12))
    spread_in = float(np.linalg.norm(np.asarray(clean, np.float32).reshape(-1, 3).std(axis=0)))
    gain_rgb = max(float(np.linalg.norm(rgbs[1].reshape(-1, 3).std(axis=0))) / max(spread_in, GAIN_FLOOR), GAIN_FLOOR)
    colour_after = np.linalg.norm(rgbs[0][on] - rgbs[1][on], axis=-1) / np.float32(gain_rgb)
    colour = float(colour_after.sum() / max(float(sites.colour_diff[on].sum()), 1e-12))
    idx = sites.labels[on]
    peak_in = np.zeros(sites.count + 1, np.float32)
    peak_out = np.zeros(sites.count + 1, np.float32)
    np.maximum.at(peak_in, idx, sites.excess[on])
    np.maximum.at(peak_out, idx, d_out[on])
    left = float(np.mean(peak_out[1:] >= 0.5 * peak_in[1:]))
    return SnowResidue(residue, left, sites.per_megapixel, gain, colour)


def snow_free_mask(sites: SnowSites, margin_px: int = CLEAR_MARGIN_PX) -> np.ndarray:
    """Boolean (H, W): the pixels at least ``margin_px`` away from every particle site."""
    near = (sites.labels > 0).astype(np.uint8)
    if margin_px > 0:
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin_px + 1, 2 * margin_px + 1))
        return np.asarray(cv2.dilate(near, kernel)) == 0
    return near == 0
