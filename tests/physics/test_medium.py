from __future__ import annotations

import numpy as np
import pytest

from murk.physics.jerlov import beta_per_m, residual_ratio
from murk.physics.medium import (
    ambient_light,
    apply_medium,
    distance_map,
    distance_range,
    transmission,
)


def test_distance_zero_leaves_the_image_unchanged(rng: np.random.Generator) -> None:
    clean = rng.random((5, 6, 3)).astype(np.float32)
    out, t = apply_medium(clean, np.zeros((5, 6), np.float32), beta_per_m("9C"), np.array([0.1, 0.5, 0.7]))
    np.testing.assert_array_equal(t, 1.0)
    np.testing.assert_allclose(out, clean, atol=1e-7)


def test_haze_grows_with_distance() -> None:
    # A constant scene seen along a distance ramp: farther pixels are closer to the ambient light B_inf.
    clean = np.full((1, 50, 3), [0.9, 0.2, 0.6], np.float32)
    dist = np.linspace(0.3, 15.0, 50, dtype=np.float32)[None, :]
    b_inf = ambient_light("3C", 4.0)
    out, _ = apply_medium(clean, dist, beta_per_m("3C"), b_inf)
    gap = np.abs(out[0] - b_inf.astype(np.float32)).sum(axis=1)
    assert np.all(np.diff(gap) < 0)
    assert gap[-1] < 0.05 * gap[0]  # at 15 m in coastal 3C water almost only the veiling light is left


def test_eq1_against_hand_values() -> None:
    clean = np.array([[[1.0, 0.5, 0.0]]], np.float32)
    beta = np.array([0.5, 0.1, 1.0])
    b = np.array([0.2, 0.4, 0.6])
    out, t = apply_medium(clean, np.array([[2.0]], np.float32), beta, b)
    expect_t = np.exp(-beta * 2.0)
    np.testing.assert_allclose(t[0, 0], expect_t, rtol=1e-6)
    np.testing.assert_allclose(out[0, 0], clean[0, 0] * expect_t + b * (1 - expect_t), rtol=1e-6)
    np.testing.assert_allclose(transmission(np.array([[1.0]], np.float32), beta)[0, 0], np.exp(-beta), rtol=1e-6)


def test_transmission_is_bit_identical_to_the_float32_product_then_exp(rng: np.random.Generator) -> None:
    """T_c = exp(float32(-beta_c) * d) in float32, what cv2.transform with a 3x1 matrix gave before (issue 29:
    the same bits, 3.5x faster), on odd sizes and the whole range of Jerlov coefficients."""
    import cv2

    for h, w in ((1, 1), (7, 3), (37, 101), (480, 640)):
        d = (rng.random((h, w)) * rng.uniform(0.1, 30.0) + 0.3).astype(np.float32)
        beta = rng.uniform(0.001, 3.0, 3)
        m = (-beta).reshape(3, 1).astype(np.float32)
        reference = cv2.exp(cv2.transform(d, m))
        got = transmission(d, beta)
        assert got.dtype == np.float32 and got.shape == (h, w, 3)
        np.testing.assert_array_equal(got, reference)
        np.testing.assert_array_equal(got, cv2.exp(d[:, :, None] * (-beta).astype(np.float32)))


def test_ambient_light_formula() -> None:
    np.testing.assert_allclose(ambient_light("II", 3.5), 1.5 * residual_ratio("II") ** 3.5)
    assert (ambient_light("I", 3.0) > 1).any()  # clear water: B_inf can exceed 1 (clipped at the end)


def test_distance_map_modes() -> None:
    depth = np.array([[1.0, 2.0, 4.0]], np.float32)
    np.testing.assert_allclose(distance_map(depth, near_m=0.3, far_m=10.0), [[0.3 + 9.7 / 4, 0.3 + 9.7 / 2, 10.0]])
    np.testing.assert_allclose(distance_map(np.array([[0.1, 20.0]], np.float32), mode="metric"), [[0.3, 15.0]])
    with pytest.raises(ValueError, match="distance_mode: expected"):
        distance_map(depth, mode="log")  # type: ignore[arg-type]


@pytest.mark.parametrize("mode", ["normalized", "metric"])
def test_distance_range_is_the_exact_min_and_max_of_the_map(rng: np.random.Generator, mode: str) -> None:
    """The runner reports the distance range of every variant from the depth's range (issue 29: two passes over
    the map less per variant); float32 rounding keeps every step monotonic, so it is exact, not close."""
    for _ in range(200):
        h, w = (int(v) for v in rng.integers(1, 60, 2))
        depth = (rng.random((h, w)) ** rng.uniform(0.2, 5.0) * rng.uniform(0.01, 40.0) + 1e-3).astype(np.float32)
        near, far = float(rng.uniform(0.05, 2.0)), float(rng.uniform(2.5, 20.0))
        dist = distance_map(depth, mode=mode, near_m=near, far_m=far)  # type: ignore[arg-type]
        given = distance_map(depth, mode=mode, near_m=near, far_m=far, depth_max_m=float(depth.max()))  # type: ignore[arg-type]
        np.testing.assert_array_equal(given, dist)
        lo, hi = distance_range(float(depth.min()), float(depth.max()), mode=mode, near_m=near, far_m=far)  # type: ignore[arg-type]
        assert (lo, hi) == (float(dist.min()), float(dist.max()))


def test_distance_range_of_a_reversed_range_is_still_min_then_max() -> None:
    lo, hi = distance_range(1.0, 4.0, near_m=4.0, far_m=1.0)
    dist = distance_map(np.array([[1.0, 2.0, 4.0]], np.float32), near_m=4.0, far_m=1.0)
    assert (lo, hi) == (float(dist.min()), float(dist.max())) and lo < hi
