"""Eq. (1) run backwards, the water features and the global colour map (murk.restore_ops.water); the numpy/torch
twin of the inversion is pinned in tests/twins.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from murk.errors import ShapeError
from murk.restore_ops.water import FEATURES, invert_eq1, visibility_m, water_features


def _scene(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    clean = rng.uniform(0.0, 1.0, (24, 32, 3)).astype(np.float32)
    dist = np.tile(np.linspace(0.5, 6.0, 32, dtype=np.float32), (24, 1))
    return clean, dist


def test_invert_eq1_recovers_the_clean_scene_where_the_transmission_is_above_the_floor() -> None:
    clean, dist = _scene()
    veil = np.array([0.1, 0.5, 0.6], np.float32)
    att = np.array([0.35, 0.08, 0.1], np.float32)
    t = np.exp(-att * dist[..., None])
    degraded = clean * t + veil * (1.0 - t)
    assert t.min() > 0.1
    np.testing.assert_allclose(invert_eq1(degraded, dist, veil, att, t_min=0.1), clean, atol=2e-5)


def test_invert_eq1_floors_the_transmission() -> None:
    clean, dist = _scene(1)
    veil = np.full(3, 0.4, np.float32)
    att = np.full(3, 1.0, np.float32)  # t = exp(-6) at the far end, far below the floor
    out = invert_eq1(clean, dist, veil, att, t_min=0.5)
    expect = np.clip((clean - veil * 0.5) / 0.5, 0.0, 1.0)
    np.testing.assert_allclose(out[:, -1], expect[:, -1], atol=1e-6)


def test_invert_eq1_refuses_bad_shapes_and_floors() -> None:
    clean, dist = _scene()
    with pytest.raises(ShapeError, match="distance_m"):
        invert_eq1(clean, dist[:10], np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="t_min"):
        invert_eq1(clean, dist, np.zeros(3), np.zeros(3), t_min=0.0)


def test_water_features_have_a_fixed_length_and_check_their_inputs() -> None:
    clean, dist = _scene()
    f = water_features(clean, dist)
    assert f.shape == (FEATURES,) and f.dtype == np.float32 and np.isfinite(f).all()
    # per bin: log median distance, then the 5/50/95th percentiles of R, G, B; the nearest bin comes first
    log_d = f[0:80:10]
    assert np.all(np.diff(log_d) > 0) and np.exp(log_d[0]) < 1.5 and np.exp(log_d[-1]) > 5.0
    flat = water_features(np.full_like(clean, 0.25), dist)
    np.testing.assert_allclose(flat[1:10], 0.25, atol=1e-6)  # every percentile of a flat image
    np.testing.assert_allclose(flat[-6:], [0.25, 0.25, 0.25, 0.0, 0.0, 0.0], atol=1e-6)  # means, then stds
    big = water_features(np.repeat(np.repeat(clean, 4, 0), 4, 1), np.repeat(np.repeat(dist, 4, 0), 4, 1))
    assert big.shape == (FEATURES,)
    with pytest.raises(ShapeError, match="image"):
        water_features(clean[..., :2], dist)


def test_visibility_is_where_the_clearest_channel_keeps_five_percent() -> None:
    assert visibility_m(np.array([0.5, 0.1, 0.2])) == pytest.approx(math.log(20) / 0.1)
