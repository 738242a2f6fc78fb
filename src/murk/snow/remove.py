"""Marine snow taken out of a frame (issue 46, item 4): find the particles, then put back the background behind
them. No learning: the rules below, each there because a construction scene broke the one before it.

- **Find** (:func:`find_particles`): on the frame's luma (Rec. 601), a particle is brighter by more than
  ``threshold`` x the frame's luma spread (its 1st to 99th percentile: a particle's contrast as a colour stretch
  would show it, so dim snow in flat green water and bright snow in a contrasty frame are found alike), and by
  :data:`NOISE_SIGMAS` times the frame's noise, than both
  - every opening by a line of ``size`` x the long side, in 8 directions (:func:`line_opening`): a blob is darker
    all round, a cable, a net strand or an edge holds a line along itself; and
  - the median over a square of twice that side (:func:`background`): the bright gaps of a dark net cover most of
    such a square, so they are its background.

  A component of those pixels counts when it fits the ``size`` disc (area and extent), is not longer than
  ``max_elongation`` times its width (the snow bank's measure, :func:`murk.snow.extract.elongation`), its brightest
  pixel is half that above the brightest other pixel within two pixels (the corner of a bright block is
  not), and bright blobs cover at most ``crowd`` of the square of four times ``size`` around it (a grating
  is not snow). The kept particles are grown by ``grow_px`` to take their soft rim.
- **Fill** (:func:`fill_particles`): each particle's pixels become the median background, per channel (through 8
  bits): the colour and level around the particle, with no particle in it. The mask is feathered over one pixel;
  pixels beyond that rim are the input, bit for bit.

Frames are float RGB in [0, 1]; anything else is refused with the dtype or shape named.

It runs before or after a restorer (``desnow+lite``, ``lite+desnow``). What it gains and costs: docs/snow.md,
"Taking real snow out: `desnow`".
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from murk.snow.extract import component_elongations


@dataclass(frozen=True)
class SnowRemoval:
    """The settings of :func:`find_particles`. ``threshold``: the share of the frame's luma spread by which a blob
    must be brighter than its surroundings to be a particle;
    ``size``: the largest particle's diameter as a fraction of the frame's long side; ``max_elongation``: the
    longest particle, in widths (0: any); ``crowd``: the largest share of a particle's surroundings (a square of
    four times ``size``) that bright blobs may cover: real snow covers 1-2 % of a frame (docs/snow.md: 2,700 sites
    per megapixel of about 5 pixels), a coral reef's bright specks 5-10 %, the gaps of a dark net or grating a third
    or more, so a crowd of blobs is texture; ``grow_px``: pixels added around each particle."""

    threshold: float = 0.1
    size: float = 0.03
    max_elongation: float = 3.0
    crowd: float = 0.05
    grow_px: int = 1

    def __post_init__(self) -> None:
        if not 0.0 < float(self.threshold) < 1.0:
            raise ValueError(f"threshold: expected a share of the luma spread in (0, 1), got {self.threshold!r}")
        if not 0.0 < float(self.size) <= 0.25:
            raise ValueError(f"size: expected a fraction of the long side in (0, 0.25], got {self.size!r}")
        if self.max_elongation != 0 and not float(self.max_elongation) >= 1.0:
            raise ValueError(f"max_elongation: expected 0 (any) or >= 1, got {self.max_elongation!r}")
        if not 0.0 < float(self.crowd) <= 1.0:
            raise ValueError(f"crowd: expected a share in (0, 1], got {self.crowd!r}")
        if isinstance(self.grow_px, bool) or not isinstance(self.grow_px, int) or not 0 <= self.grow_px <= 8:
            raise ValueError(f"grow_px: expected an int in [0, 8], got {self.grow_px!r}")

    def size_px(self, height: int, width: int) -> int:
        """The ellipse's side in pixels for a frame of that size: odd, at least 3."""
        return max(3, round(float(self.size) * max(height, width)) | 1)


SPREAD_PERCENTILES = (1.0, 99.0)
"""The frame's luma spread: from its 1st to its 99th percentile."""

NOISE_SIGMAS = 6.0
"""A particle also stands this many times the frame's noise above its surroundings, so that the sensor noise of flat
water is never taken for snow. The noise is 1.4826 times the median absolute deviation of the luma from its 3x3
median (8-bit levels), at least one level: robust to the particles themselves and to the scene's edges."""


def _noise_levels(luma_u8: np.ndarray) -> float:
    """The noise of an 8-bit luma frame in levels (:data:`NOISE_SIGMAS`)."""
    residual = cv2.absdiff(luma_u8, cv2.medianBlur(luma_u8, 3))
    return max(1.0, 1.4826 * _percentile_u8(residual, 50.0))


def _percentile_u8(values: np.ndarray, q: float) -> float:
    """The lowest 8-bit level at or below which ``q`` per cent of ``values`` lie (from their histogram: one pass)."""
    counts = np.bincount(values.ravel(), minlength=256).cumsum()
    return float(np.searchsorted(counts, q / 100.0 * counts[-1]))


def _ellipse(side_px: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (side_px, side_px))


def _label_max(values: np.ndarray, lab: np.ndarray, n: int) -> np.ndarray:
    """The largest of ``values`` per label 0..n-1 (0 for a label with none)."""
    out = np.zeros(n, np.float32)
    np.maximum.at(out, lab, values.astype(np.float32, copy=False))
    return out


def _line(side_px: int, angle: float) -> np.ndarray:
    """A one-pixel line of ``side_px`` pixels through the centre of a square kernel, at ``angle`` radians."""
    kernel = np.zeros((side_px, side_px), np.uint8)
    c = (side_px - 1) / 2.0
    dx, dy = c * np.cos(angle), c * np.sin(angle)
    cv2.line(kernel, (round(c - dx), round(c - dy)), (round(c + dx), round(c + dy)), 1)
    return kernel


def line_opening(luma: np.ndarray, side_px: int, directions: int = 8) -> np.ndarray:
    """The largest of the openings of ``luma`` (H, W; uint8 or float) by lines of ``side_px`` pixels in ``directions``
    directions, in ``luma``'s type. A particle is brighter than its surroundings along every line through it, so
    every opening removes it; a cable, a net strand or an edge holds a line along itself, so one opening keeps it and
    it is no particle (``luma`` minus this is the smallest of the directional top-hats)."""
    y = np.ascontiguousarray(luma)
    out = np.zeros_like(y)
    for k in range(directions):
        np.maximum(out, cv2.morphologyEx(y, cv2.MORPH_OPEN, _line(side_px, np.pi * k / directions)), out=out)
    return out


def background(image: np.ndarray, side_px: int) -> np.ndarray:
    """The background of float ``image`` (H, W) or (H, W, 3) in [0, 1]: its median over a square of ``2 side_px + 1``
    pixels, per channel, at 8 bits (OpenCV's median of any size needs them), taken at half the size from 8 pixels up
    and at a quarter from 16 (the background is smooth at that scale; the median is most of the cost); float32. A
    particle covers far less than half of that square, so it has no say in the median; the bright gaps of a net or a
    grating cover more, so they are the background there, and nothing in them stands out of it."""
    return _smooth_median_u8(_to_u8(image), side_px).astype(np.float32) * np.float32(1.0 / 255.0)


def _to_u8(image: np.ndarray) -> np.ndarray:
    return np.rint(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8)


def _median_u8(u8: np.ndarray, side_px: int) -> np.ndarray:
    return np.asarray(cv2.medianBlur(u8, 2 * int(side_px) + 1))


def _smooth_median_u8(u8: np.ndarray, side_px: int) -> np.ndarray:
    """The median of :func:`background` on 8-bit ``u8``, at the size it names, brought back to the full size."""
    scale = 4 if side_px >= 16 else 2 if side_px >= 8 else 1
    if scale == 1:
        return _median_u8(u8, side_px)
    h, w = u8.shape[:2]
    small = cv2.resize(u8, (-(-w // scale), -(-h // scale)), interpolation=cv2.INTER_AREA)
    return np.asarray(cv2.resize(_median_u8(small, side_px // scale), (w, h), interpolation=cv2.INTER_LINEAR))


def _check_image(image: np.ndarray) -> None:
    if image.ndim != 3 or image.shape[-1] != 3:
        raise ValueError(f"image: expected (H, W, 3) RGB, got shape {image.shape}")
    if not np.issubdtype(image.dtype, np.floating):
        raise ValueError(f"image: expected float RGB in [0, 1], got {image.dtype} (convert 8-bit frames: x / 255)")


def find_particles(image: np.ndarray, removal: SnowRemoval) -> np.ndarray:
    """The particle mask of float RGB ``image`` (H, W, 3) in [0, 1]: (H, W) bool, True on particles and their rim
    (the rules: module doc)."""
    _check_image(image)
    side = removal.size_px(image.shape[0], image.shape[1])
    luma = _to_u8(cv2.cvtColor(np.ascontiguousarray(image, dtype=np.float32), cv2.COLOR_RGB2GRAY))  # 8 bits: fast
    around = np.maximum(line_opening(luma, side), _smooth_median_u8(luma, side))
    low, high = (_percentile_u8(luma, q) for q in SPREAD_PERCENTILES)
    excess = luma.astype(np.float32) - around
    threshold = np.float32(max(removal.threshold * float(high - low), NOISE_SIGMAS * _noise_levels(luma)))
    found = (excess > threshold).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(found, connectivity=8)
    if n <= 1:
        return np.zeros(found.shape, bool)
    rows, cols = np.nonzero(found)  # the few candidate pixels: every per-component figure is taken over them
    lab = labels[rows, cols]
    area = stats[:, cv2.CC_STAT_AREA]
    extent = np.maximum(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT])
    near = cv2.dilate(np.where(found > 0, np.uint8(0), luma), _ellipse(5))  # the brightest non-particle near
    crowd = cv2.blur(found.astype(np.float32), (4 * side + 1, 4 * side + 1))  # the share of bright blobs around
    peak, ring = _label_max(luma[rows, cols], lab, n), _label_max(near[rows, cols], lab, n)
    keep = (area <= np.pi * side * side / 4) & (extent <= side) & (peak - ring >= threshold / 2)
    keep &= _label_max(crowd[rows, cols], lab, n) <= np.float32(removal.crowd)
    if removal.max_elongation:
        keep &= component_elongations(rows, cols, lab, n) <= removal.max_elongation
    keep[0] = False
    mask = keep[labels].astype(np.uint8)
    if removal.grow_px > 0:
        mask = cv2.dilate(mask, _ellipse(2 * removal.grow_px + 1))
    return mask.astype(bool)


def fill_particles(image: np.ndarray, mask: np.ndarray, side_px: int) -> np.ndarray:
    """``image`` (H, W, 3, float in [0, 1]) with the pixels under ``mask`` (H, W) replaced by their :func:`background`
    for ``side_px``, feathered over one pixel; float32."""
    _check_image(image)
    img = np.ascontiguousarray(image, dtype=np.float32)
    if mask.shape != img.shape[:2]:
        raise ValueError(f"mask: expected shape {img.shape[:2]}, got {mask.shape}")
    if not mask.any():
        return img.copy()
    behind = background(img, int(side_px))
    weight = np.maximum(cv2.blur(mask.astype(np.float32), (3, 3)), mask.astype(np.float32))  # particles: fully
    rows, cols = np.nonzero(weight)  # the particles and their rim: the rest of the frame is not touched
    out = img.copy()
    w = weight[rows, cols][:, None]
    out[rows, cols] = img[rows, cols] + w * (behind[rows, cols] - img[rows, cols])
    return out


def remove_snow(image: np.ndarray, removal: SnowRemoval) -> np.ndarray:
    """:func:`find_particles`, then :func:`fill_particles`: ``image`` without its marine snow, float32 (H, W, 3)."""
    side = removal.size_px(image.shape[0], image.shape[1])
    return fill_particles(image, find_particles(image, removal), side)
