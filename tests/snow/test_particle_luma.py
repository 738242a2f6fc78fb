"""marine_snow.particle_luma: particles relit to a drawn mean luma, hue kept, nothing else moved."""

from __future__ import annotations

import numpy as np
import pytest

from murk.snow.bank import load_bank
from murk.snow.composite import composite_snow, particle_lumas, sample_snow, snow_layout
from murk.synth.config import SnowConfig


def test_layout_is_the_same_with_and_without_relighting() -> None:
    bank = load_bank("builtin:snow-real")
    plain = sample_snow(np.random.default_rng(3), bank, n_particles=(50, 50))
    lit = sample_snow(np.random.default_rng(3), bank, n_particles=(50, 50), particle_luma=(150.0, 200.0))
    a, b = snow_layout(plain, len(bank), 64, 48), snow_layout(lit, len(bank), 64, 48)
    assert np.array_equal(a.index, b.index) and np.array_equal(a.centre_xy, b.centre_xy)
    assert a.target_luma is None and b.target_luma is not None
    assert np.all((b.target_luma >= 150) & (b.target_luma <= 200))


def test_relit_particles_are_brighter_with_the_same_coverage() -> None:
    bank = load_bank("builtin:snow-real")
    assert float(np.median(particle_lumas(bank))) < 60  # cut from dark ROV footage
    img = np.full((64, 80, 3), 0.3, np.float32)
    plain = sample_snow(np.random.default_rng(1), bank, n_particles=(200, 200), scale=(0.8, 1.0))
    lit = sample_snow(
        np.random.default_rng(1), bank, n_particles=(200, 200), scale=(0.8, 1.0), particle_luma=(200, 200)
    )
    out_plain, alpha_plain = composite_snow(img, plain, bank)
    out_lit, alpha_lit = composite_snow(img, lit, bank)
    np.testing.assert_array_equal(alpha_plain, alpha_lit)
    on = alpha_lit[..., 0] > 0.5 if alpha_lit.ndim == 3 else alpha_lit > 0.5
    assert out_lit[on].mean() > 0.5 > 0.3 > out_plain[on].mean()


def test_bad_range_is_refused() -> None:
    with pytest.raises(ValueError, match="particle_luma"):
        SnowConfig(particle_luma=(200.0, 100.0))
