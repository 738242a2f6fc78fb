"""Training the water estimator (murk.train.water.fit_water) on water made with Eq. (1) from known coefficients."""

from __future__ import annotations

import numpy as np
import pytest

from murk.train.water import WaterSamples, WaterTrainSettings, fit_water


def _samples(n: int = 60, seed: int = 0) -> WaterSamples:
    rng = np.random.default_rng(seed)
    h, w = 30, 40
    yy = np.linspace(0, 1, h, dtype=np.float32)[:, None]
    clean = rng.uniform(0.05, 0.95, (n, h, w, 3)).astype(np.float32)
    dist = np.stack([np.broadcast_to(1.0 + rng.uniform(2, 8) * yy, (h, w)) for _ in range(n)]).astype(np.float32)
    veil = rng.uniform(0.1, 0.9, (n, 1, 1, 3)).astype(np.float32)
    att = rng.uniform(0.05, 0.4, (n, 1, 1, 3)).astype(np.float32)
    t = np.exp(-att * dist[..., None])
    degraded = (clean * t + veil * (1 - t)).astype(np.float32)
    return WaterSamples(degraded, dist, clean)


def test_fit_water_learns_and_is_seeded() -> None:
    samples = _samples()
    rows: list[dict[str, float]] = []
    settings = WaterTrainSettings(steps=120, batch=16, log_every=10, seed=3)
    est = fit_water(samples, settings, rows.append)
    assert rows[-1]["val_loss"] < 0.7 * rows[0]["val_loss"]
    again = fit_water(samples, settings)
    for k, v in est.arrays.items():
        np.testing.assert_array_equal(v, again.arrays[k])


def test_settings_and_samples_are_checked() -> None:
    with pytest.raises(ValueError, match="t_min"):
        WaterTrainSettings(t_min=0.0)
    s = _samples(12)
    with pytest.raises(ValueError, match="samples"):
        WaterSamples(s.degraded, s.distance_m[:, :5], s.clean)
