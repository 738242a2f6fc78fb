"""Small sharp details painted on a rendered clean scene: dots (shells, barnacles, gravel), strokes (rope, wire,
the edge of a rebar) and small ellipses (fish), bright or dark.

Why: real photographs hold many small bright details that belong to the scene, and murk's procedural scenes hold
almost none. A network that learns to take marine snow out of them learns that every small bright spot is snow:
the ``detail`` stage fades a thin rope, small fish and the pale specks of a reef on real photographs
(docs/models/detail.md). Painted on the clean scene, before the water degrades it, a speck is in the target as well
as in the input, at the distance of the surface under it, so it is attenuated, veiled and blurred with the scene:
something small and bright that must stay.

Sample, then apply (DESIGN.md rule 3)::

    specks = sample_specks(seed, (h, w), per_mpx=300.0)
    rgb = apply_specks(rgb, specks)

Sizes are drawn in pixels of a frame whose shorter side is 240 pixels and scaled by ``min(h, w) / 240``; the count
is per megapixel of that reference frame, so the share of the frame the specks cover does not depend on its size.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from murk.rng import RngLike, as_generator

DOT, STROKE, ELLIPSE = 0, 1, 2
"""Speck kinds."""

BRIGHT_SHARE = 0.75
"""Share of bright specks (the rest are dark)."""


@dataclass(frozen=True)
class Specks:
    """Sampled specks, one row per speck (arrays of length N: ``kind`` int64, the rest float64; colours (N, 3)).

    Attributes:
        kind: DOT, STROKE or ELLIPSE.
        centre_yx_px: centre (row, column) in pixels.
        length_px: the dot's radius, the stroke's length between the centres of its rounded ends, the ellipse's long
            semi-axis.
        width_px: the stroke's width, the ellipse's short semi-axis (unused by dots).
        angle_rad: orientation of strokes and ellipses.
        colour: RGB in [0, 1], in the render's values.
        opacity: in (0, 1].
    """

    kind: np.ndarray
    centre_yx_px: np.ndarray
    length_px: np.ndarray
    width_px: np.ndarray
    angle_rad: np.ndarray
    colour: np.ndarray
    opacity: np.ndarray

    def __len__(self) -> int:
        return int(self.kind.shape[0])


def sample_specks(rng: RngLike, size_hw: tuple[int, int], per_mpx: float) -> Specks:
    """Specks for a frame of ``size_hw``, deterministic in ``rng`` (a seed or a generator): Poisson(``per_mpx`` x the
    frame's megapixels / scale^2) of them, scale = ``min(h, w) / 240``; a third each of dots (radius 0.6-2.5 px),
    strokes (6-30 px between the centres of their round ends, 0.7-1.8 px wide) and ellipses (semi-axes 2-6 by 0.8-2
    px), sizes times scale; three in four bright (value 0.65-1, saturation at most 0.35), the rest dark (value
    0.03-0.25).

    Raises:
        ValueError: ``per_mpx`` negative or not finite, or a size that is not two positive integers.
    """
    if len(size_hw) != 2 or any(isinstance(v, bool) or int(v) != v or v < 1 for v in size_hw):
        raise ValueError(f"size_hw: expected two positive integer sizes, got {size_hw!r}")
    h, w = int(size_hw[0]), int(size_hw[1])
    if not np.isfinite(per_mpx) or per_mpx < 0:
        raise ValueError(f"per_mpx: expected a finite count >= 0 per megapixel, got {per_mpx!r}")
    gen = as_generator(rng)
    scale = min(h, w) / 240.0
    n = int(gen.poisson(per_mpx * h * w / 1e6 / scale**2))
    kind = gen.integers(0, 3, n)
    centre = gen.uniform(0.0, 1.0, (n, 2)) * np.array([h, w], dtype=np.float64)
    dot_r = gen.uniform(0.6, 2.5, n)
    stroke_len, stroke_w = gen.uniform(6.0, 30.0, n), gen.uniform(0.7, 1.8, n)
    ell_a, ell_b = gen.uniform(2.0, 6.0, n), gen.uniform(0.8, 2.0, n)
    length = np.select([kind == DOT, kind == STROKE], [dot_r, stroke_len], ell_a) * scale
    width = np.where(kind == STROKE, stroke_w, ell_b) * scale
    angle = gen.uniform(0.0, np.pi, n)
    bright = gen.uniform(0.0, 1.0, n) < BRIGHT_SHARE
    value = np.where(bright, gen.uniform(0.65, 1.0, n), gen.uniform(0.03, 0.25, n))
    saturation = gen.uniform(0.0, 0.35, n)
    hue = gen.uniform(0.0, 1.0, (n, 3))
    hue = hue / np.maximum(hue.max(axis=1, keepdims=True), 1e-9)
    colour = value[:, None] * (1.0 - saturation[:, None] * (1.0 - hue))
    opacity = gen.uniform(0.6, 1.0, n)
    return Specks(kind, centre, length, width, angle, colour, opacity)


def _signed_distance(s: Specks, k: int, yy: np.ndarray, xx: np.ndarray) -> np.ndarray:
    """Signed distance in pixels from the pixel centres ``(yy, xx)`` to speck ``k``'s outline (negative inside)."""
    dy, dx = yy - s.centre_yx_px[k, 0], xx - s.centre_yx_px[k, 1]
    if s.kind[k] == DOT:
        return np.hypot(dy, dx) - s.length_px[k]
    c, si = np.cos(s.angle_rad[k]), np.sin(s.angle_rad[k])
    u, v = dx * c + dy * si, -dx * si + dy * c
    if s.kind[k] == STROKE:
        along = np.clip(u, -s.length_px[k] / 2.0, s.length_px[k] / 2.0)
        return np.hypot(u - along, v) - s.width_px[k] / 2.0
    a, b = s.length_px[k], s.width_px[k]
    f = np.hypot(u / a, v / b)
    grad = np.hypot(u / a**2, v / b**2)  # |grad f|: (f - 1) f / |grad f| is the distance to first order
    return np.where(f > 1e-6, (f - 1.0) * f / np.maximum(grad, 1e-12), -b)


def apply_specks(rgb: np.ndarray, specks: Specks) -> np.ndarray:
    """``rgb`` (H, W, 3) in [0, 1] with ``specks`` painted over it, anti-aliased over one pixel; a new float32
    array (``rgb`` is not changed). Specks outside the frame are clipped.

    Raises:
        ValueError: ``rgb`` not (H, W, 3).
    """
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb: expected (H, W, 3), got shape {rgb.shape}")
    out = np.array(rgb, dtype=np.float32, copy=True)
    h, w = out.shape[:2]
    for k in range(len(specks)):
        reach = max(specks.length_px[k], specks.width_px[k]) + 2.0  # paint ends 0.5 px outside the outline
        cy, cx = specks.centre_yx_px[k]
        y0, y1 = max(int(cy - reach), 0), min(int(cy + reach) + 1, h)
        x0, x1 = max(int(cx - reach), 0), min(int(cx + reach) + 1, w)
        if y0 >= y1 or x0 >= x1:
            continue
        yy, xx = np.mgrid[y0:y1, x0:x1].astype(np.float64) + 0.5
        alpha = specks.opacity[k] * np.clip(0.5 - _signed_distance(specks, k, yy, xx), 0.0, 1.0)
        patch = out[y0:y1, x0:x1]
        out[y0:y1, x0:x1] = (patch * (1.0 - alpha[..., None]) + specks.colour[k] * alpha[..., None]).astype(np.float32)
    return out
