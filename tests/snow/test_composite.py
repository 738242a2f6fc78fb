from __future__ import annotations

import numpy as np
import pytest
import torch

from murk.data import default_snow_bank
from murk.snow.bank import load_bank
from murk.snow.composite import (
    SnowParams,
    composite_snow,
    composite_snow_torch,
    sample_snow,
    snow_layers,
    snow_layout,
)

from .conftest import make_bank


def _params(
    n: int, rho: float = 0.5, scale: tuple[float, float] = (0.3, 0.6), seed: int = 1, bank_id: str = ""
) -> SnowParams:
    return SnowParams(n_particles=n, rho_px=rho, scale_range=scale, layout_seed=seed, bank_id=bank_id)


def test_alpha_in_unit_range_and_image_in_range(rng: np.random.Generator) -> None:
    bank = load_bank(default_snow_bank())
    img = rng.random((60, 80, 3)).astype(np.float32)
    for seed in range(3):
        p = sample_snow(seed, bank)
        out, alpha = composite_snow(img, p, bank)
        assert alpha.shape == (60, 80) and alpha.min() >= 0.0 and alpha.max() <= 1.0 and alpha.max() > 0.2
        assert out.min() >= 0.0 and out.max() <= 1.0 + 1e-6


def test_zero_alpha_leaves_the_image_unchanged(rng: np.random.Generator, solid_bank) -> None:
    img = rng.random((30, 40, 3)).astype(np.float32)
    out, alpha = composite_snow(img, _params(0), solid_bank)
    assert not alpha.any()
    np.testing.assert_array_equal(out, img)
    # and away from every particle the image is untouched too
    out, alpha = composite_snow(img, _params(5), solid_bank)
    far = alpha == 0
    assert far.mean() > 0.5
    np.testing.assert_array_equal(out[far], img[far])


def test_particle_colours_come_from_the_bank() -> None:
    bank = make_bank(colour=(40, 220, 90))
    black = np.zeros((50, 60, 3), np.float32)
    out, alpha = composite_snow(black, _params(40, rho=0.7), bank)
    covered = alpha > 0.02
    assert covered.sum() > 50
    # on black, I_ms = a_ms * M': the colour divided by alpha is exactly the bank colour everywhere (the
    # normalised convolution keeps particle edges in the particle's own colour, not darker)
    ratio = out[covered] / alpha[covered, None]
    np.testing.assert_allclose(ratio, np.broadcast_to(np.array([40, 220, 90]) / 255.0, ratio.shape), atol=1e-4)


def test_n_particles_and_mass_are_respected() -> None:
    bank = make_bank(sizes=(1,))  # single pixels: after resizing by s each carries s^2 of coverage
    p = _params(9, scale=(0.3, 0.6), seed=11)
    layout = snow_layout(p, len(bank), 1000, 1000)
    assert len(layout.index) == 9 and (layout.scale >= 0.3).all() and (layout.scale <= 0.6).all()
    assert ((layout.centre_xy >= 1) & (layout.centre_xy <= 998)).all()  # precondition: no particle at the border
    b, _, _ = snow_layers(p, bank, 1000, 1000)  # the padded canvas keeps the mass of border particles too
    assert b.sum() == pytest.approx(float((layout.scale**2).sum()), rel=1e-5)
    assert np.count_nonzero(b) <= 4 * 9


def test_enlarged_particles_stay_solid() -> None:
    bank = make_bank(sizes=(3,))
    p = _params(1, scale=(2.0, 2.0), seed=3)
    b, _, _ = snow_layers(p, bank, 40, 40)
    assert b.sum() == pytest.approx(4 * 9, rel=1e-5)  # area scales by s^2
    assert (b > 0.99).sum() >= 16  # the interior of a 6x6 square is fully covered: no holes


def test_determinism_and_bank_mismatch(solid_bank, rng: np.random.Generator) -> None:
    img = rng.random((20, 20, 3)).astype(np.float32)
    p = sample_snow(5, solid_bank, n_particles=(30, 30))
    a, b = composite_snow(img, p, solid_bank), composite_snow(img, p, solid_bank)
    assert a[0].tobytes() == b[0].tobytes() and p.n_particles == 30
    other = make_bank(colour=(1, 2, 3))
    with pytest.raises(ValueError, match="bank: the parameters were drawn from bank"):
        composite_snow(img, p, other)


def test_torch_twin_needs_one_parameter_set_per_image(rng: np.random.Generator) -> None:  # equal: tests/twins.py
    bank = load_bank(default_snow_bank())
    imgs = rng.random((3, 45, 55, 3)).astype(np.float32)
    params = [sample_snow(s, bank, n_particles=(200, 300)) for s in range(3)]
    with pytest.raises(ValueError, match="expected 3 snow parameter sets"):
        composite_snow_torch(torch.from_numpy(imgs).permute(0, 3, 1, 2), params[:2], bank)


def test_reference_area_scales_the_count_with_the_image_area() -> None:
    """reference_area_px: N_p counts particles per reference frame, so a crop keeps a full frame's density."""
    from dataclasses import replace

    from murk.snow.composite import particle_count

    p = replace(_params(1200), reference_area_px=640 * 480)
    assert particle_count(p, 640, 480) == 1200
    assert particle_count(p, 160, 120) == 75  # 1/16 of the area
    assert len(snow_layout(p, 10, 160, 120).index) == 75
    assert particle_count(_params(1200), 160, 120) == 1200  # default: per image, as in the paper
    g = np.random.default_rng(0)
    bank = load_bank(default_snow_bank())
    assert sample_snow(g, bank, reference_area_px=307200).reference_area_px == 307200
