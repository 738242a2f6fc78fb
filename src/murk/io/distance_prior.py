"""A plausible distance map for a clean photograph that has none: the ground-plane layout prior.

Eq. (1) needs a distance per pixel. Clean photographs (terrestrial, in air) rarely come with one, and murk's own
distance head, trained on underwater synthetic scenes, reads in-air photographs poorly (docs/synthesis.md,
"Photographs without depth": on real RGB-D frames its map is further from the truth's shape than a constant). What
most photographs share is their layout: the camera stands above a floor (sea bed, quay, ground) that recedes
towards a horizon, and what lies beyond is far. The prior is that layout:

- a pinhole camera with vertical field of view ``fov_deg`` at ``camera_height_m`` above a flat floor;
- the camera is pitched so that the horizon crosses the frame's centre column at row fraction ``horizon`` (0 = top
  edge, 1 = bottom edge; negative: above the frame, the camera looks down) and rolled by ``roll_deg`` about its
  optical axis;
- each pixel's ray meets the floor at ``camera_height_m / sin(theta)`` metres, ``theta`` the ray's angle below the
  horizontal (exact ray-plane geometry); the scene ends in a backdrop at ``far_m``, which is also the distance of
  rays at and above the horizon.

It ignores the objects standing on the floor (they get the floor's distance where they stand higher, i.e. farther,
than they are), so haze still grows from the bottom of the frame to the top, as in most real footage. Sample,
then apply: :func:`sample_layout` draws a :class:`Layout`, :func:`layout_distance` renders it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from murk.rng import RngLike, as_generator

HORIZON_RANGE = (-0.4, 0.3)
"""Row fraction of the horizon (uniform): from well above the frame (looking down at the floor) to above the middle
(looking ahead)."""
ROLL_RANGE_DEG = (-6.0, 6.0)
FOV_RANGE_DEG = (45.0, 70.0)
CAMERA_HEIGHT_RANGE_M = (0.5, 3.0)
FAR_RATIO_RANGE = (2.5, 8.0)
"""The backdrop's distance as a multiple of the camera's height (uniform). Real frames span a few times their
nearest distance (5th to 95th percentile: 1.8-3.7 on the RGB-D frames of docs/synthesis.md); the synthesis maps
distances onto the water's visible range anyway (``distance_mode: normalized``)."""


@dataclass(frozen=True)
class Layout:
    """The parameters of the ground-plane prior (see the module docstring)."""

    horizon: float
    roll_deg: float
    fov_deg: float
    camera_height_m: float
    far_m: float

    def __post_init__(self) -> None:
        if not (-5.0 <= self.horizon <= 5.0):
            raise ValueError(f"horizon: expected a row fraction in [-5, 5], got {self.horizon}")
        if not (-45.0 <= self.roll_deg <= 45.0):
            raise ValueError(f"roll_deg: expected -45 to 45 degrees, got {self.roll_deg}")
        if not (0.0 < self.fov_deg < 180.0):
            raise ValueError(f"fov_deg: expected 0 < fov < 180, got {self.fov_deg}")
        if not (self.camera_height_m > 0.0 and self.far_m > self.camera_height_m):
            raise ValueError(
                f"camera_height_m, far_m: expected 0 < height < far, got {self.camera_height_m}, {self.far_m}"
            )


def sample_layout(rng: RngLike) -> Layout:
    """A layout drawn uniformly from the ranges of this module."""
    rng = as_generator(rng)
    horizon = float(rng.uniform(*HORIZON_RANGE))
    roll_deg = float(rng.uniform(*ROLL_RANGE_DEG))
    fov_deg = float(rng.uniform(*FOV_RANGE_DEG))
    height_m = float(rng.uniform(*CAMERA_HEIGHT_RANGE_M))
    return Layout(horizon, roll_deg, fov_deg, height_m, height_m * float(rng.uniform(*FAR_RATIO_RANGE)))


def layout_distance(height: int, width: int, layout: Layout) -> np.ndarray:
    """The distance in metres (float32, shape (height, width)) along each pixel's ray to the floor of ``layout``,
    capped at ``far_m``: the ray ``(u, v, f)`` (pixel offset from the centre, focal length in pixels) is rolled about
    the optical axis by ``roll_deg``, pitched down so that the centre column's horizon lies at row ``horizon *
    height``, and meets the floor at ``camera_height_m * |ray| / down`` (``down``: its component towards the floor)."""
    if height < 1 or width < 1:
        raise ValueError(f"height, width: expected >= 1, got {height}, {width}")
    focal_px = 0.5 * height / math.tan(math.radians(layout.fov_deg) / 2.0)
    v = np.arange(height, dtype=np.float64)[:, None] + 0.5 - 0.5 * height
    u = np.arange(width, dtype=np.float64)[None, :] + 0.5 - 0.5 * width
    pitch = math.atan2((0.5 - layout.horizon) * height, focal_px)  # > 0: looking down
    roll = math.radians(layout.roll_deg)
    down = (u * math.sin(roll) + v * math.cos(roll)) * math.cos(pitch) + focal_px * math.sin(pitch)
    norm = np.sqrt(u * u + v * v + focal_px * focal_px)
    with np.errstate(divide="ignore"):
        dist = np.where(down > 0, layout.camera_height_m * norm / np.maximum(down, 1e-12), np.inf)
    return np.minimum(dist, layout.far_m).astype(np.float32)
