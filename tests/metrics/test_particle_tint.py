"""murk.metrics.particle_tint: a* at the input's bright particles against a ring around them, in and out.

Provenance: the expected signs and sizes follow from the definition on synthetic frames built here (grey
particles on green water; a per-channel stretch that reddens them, and one that keeps them neutral).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from murk.errors import ShapeError
from murk.metrics.particle_tint import particle_sites, particle_tint


def _snowy_water(seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    img = np.empty((120, 160, 3), np.float32)
    img[...] = (0.10, 0.45, 0.35)  # green water
    img += rng.normal(0.0, 0.01, img.shape).astype(np.float32)
    for _ in range(40):
        y, x = int(rng.integers(5, 115)), int(rng.integers(5, 155))
        cv2.circle(img, (x, y), 1, (0.55, 0.75, 0.72), -1)  # bright cyan-white particles
    return np.clip(img, 0.0, 1.0)


def test_sites_are_the_bright_particles() -> None:
    mask, count = particle_sites(_snowy_water())
    assert 25 <= count <= 40 and mask.sum() > count


def test_a_red_stretch_turns_the_particles_pink_and_the_identity_does_not() -> None:
    img = _snowy_water()
    same = particle_tint(img, img)
    assert same.rise == 0.0 and same.sites > 0
    stretched = np.clip(img * np.array([4.0, 1.2, 1.3], np.float32) - np.array([0.3, 0.1, 0.1], np.float32), 0, 1)
    pink = particle_tint(img, stretched)
    assert pink.rise > 5.0  # the red gain lifts a* of the particles more than of the water around them
    neutral = img.copy()
    neutral[...] = neutral.mean(axis=2, keepdims=True)  # everything grey: no tint anywhere
    assert abs(particle_tint(img, neutral).tint_out) < 0.1  # grey has a* 0 up to OpenCV's float rounding


def test_no_particle_gives_nan() -> None:
    flat = np.full((40, 50, 3), 0.3, np.float32)
    r = particle_tint(flat, flat)
    assert r.sites == 0 and math.isnan(r.rise)


def test_shapes_are_checked() -> None:
    with pytest.raises(ShapeError, match="output: expected the shape of input"):
        particle_tint(np.zeros((4, 4, 3), np.float32), np.zeros((4, 5, 3), np.float32))
    with pytest.raises(ShapeError, match="input: expected an RGB image"):
        particle_tint(np.zeros((4, 4), np.float32), np.zeros((4, 4), np.float32))
