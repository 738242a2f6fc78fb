from __future__ import annotations

import numpy as np
import pytest

from murk._config import merge
from murk.physics.jerlov import WATER_TYPES, residual_ratio, visible_range_m
from murk.synth.config import SynthConfig
from murk.synth.params import sample_medium, sample_variant, variant_from_dict, variant_to_dict


def test_sampled_ranges_follow_the_spec() -> None:
    cfg = SynthConfig().medium
    g = np.random.default_rng(0)
    seen = set()
    for _ in range(400):
        m = sample_medium(g, cfg)
        seen.add(m.water_type)
        assert 3.0 <= m.vertical_depth_m <= 5.0  # type: ignore[operator]
        assert 0.8 <= m.far_m <= visible_range_m(m.water_type) + 1e-9
        np.testing.assert_allclose(m.b_inf, 1.5 * residual_ratio(m.water_type) ** m.vertical_depth_m)
    assert seen == set(WATER_TYPES)  # uniform over all ten types


def test_ambient_override_and_metric_mode() -> None:
    cfg = merge(SynthConfig(), {"medium": {"ambient_override": [0.1, 0.2, 0.3], "distance_mode": "metric"}}).medium
    m = sample_medium(1, cfg)
    assert m.b_inf == (0.1, 0.2, 0.3) and m.vertical_depth_m is None and m.far_m == 15.0


def test_same_seed_same_params_and_dict_round_trip() -> None:
    cfg = SynthConfig()
    a, b = sample_variant(42, cfg), sample_variant(42, cfg)
    assert a == b and sample_variant(43, cfg) != a
    assert variant_from_dict(variant_to_dict(a)) == a
    assert variant_from_dict({**variant_to_dict(a), "stem": "x", "variant": 3}) == a


def test_turning_a_stage_off_keeps_the_other_draws() -> None:
    on = sample_variant(7, SynthConfig())
    off = sample_variant(7, merge(SynthConfig(), {"stages": ["basic"]}))
    assert off.forward_scatter is None and on.medium == off.medium


def test_marine_snow_needs_a_sampler() -> None:
    cfg = merge(SynthConfig(), {"stages": ["basic", "marine_snow"]})
    with pytest.raises(ValueError, match="'marine_snow' needs a particle bank"):
        sample_variant(0, cfg)
