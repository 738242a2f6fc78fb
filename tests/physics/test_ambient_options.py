"""medium.ambient_gain / ambient_tint: veils beyond the Jerlov table, drawn only when switched on."""

from __future__ import annotations

import numpy as np
import pytest

from murk.physics.medium import ambient_light
from murk.synth.config import MediumConfig
from murk.synth.params import sample_medium


def test_defaults_draw_exactly_as_before() -> None:
    a = sample_medium(np.random.default_rng(1), MediumConfig())
    g = np.random.default_rng(1)
    wt = MediumConfig().water_types[int(g.integers(len(MediumConfig().water_types)))]
    assert a.water_type == wt
    b_inf = ambient_light(a.water_type, a.vertical_depth_m, scale=1.5)  # type: ignore[arg-type]
    np.testing.assert_allclose(a.b_inf, b_inf)


def test_gain_scales_the_veil_within_its_range() -> None:
    for seed in range(10):
        plain = sample_medium(np.random.default_rng(seed), MediumConfig())
        gained = sample_medium(np.random.default_rng(seed), MediumConfig(ambient_gain=(0.5, 2.0)))
        ratio = np.asarray(gained.b_inf) / np.asarray(plain.b_inf)
        assert np.allclose(ratio, ratio[0]) and 0.5 <= ratio[0] <= 2.0
        assert gained.water_type == plain.water_type and gained.vertical_depth_m == plain.vertical_depth_m


def test_tint_changes_the_colour_and_keeps_the_mean() -> None:
    changed = 0
    for seed in range(10):
        plain = np.asarray(sample_medium(np.random.default_rng(seed), MediumConfig()).b_inf)
        tinted = np.asarray(sample_medium(np.random.default_rng(seed), MediumConfig(ambient_tint=0.3)).b_inf)
        assert tinted.mean() == pytest.approx(plain.mean())
        changed += not np.allclose(tinted / tinted.sum(), plain / plain.sum(), atol=1e-3)
    assert changed >= 8


def test_bad_values_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="ambient_gain"):
        MediumConfig(ambient_gain=(2.0, 1.0))
    with pytest.raises(ValueError, match="ambient_tint"):
        MediumConfig(ambient_tint=-1.0)
