from __future__ import annotations

import numpy as np
import pytest
import torch

from murk.data import sample_underwater_dir
from murk.io import read_rgb
from murk.physics.forward_scatter import (
    blend_weight,
    forward_scatter,
    forward_scatter_approx,
    forward_scatter_exact,
    forward_scatter_reference,
    gaussian_blur,
    gaussian_blur_torch,
    psf,
    sigma_levels,
    sigma_px,
)


def test_blend_weight_is_63_percent_at_5_m() -> None:
    assert blend_weight(np.array([[5.0]], np.float32))[0, 0] == pytest.approx(0.632, abs=5e-4)
    assert blend_weight(np.array([[0.0]], np.float32))[0, 0] == 0.0
    a = blend_weight(np.linspace(0, 15, 20, dtype=np.float32)[None])
    assert np.all(np.diff(a) > 0)


def test_sigma_spans_the_paper_range() -> None:
    assert sigma_px(0.3) == pytest.approx(0.545)
    assert sigma_px(15.0) == pytest.approx(2.75)


@pytest.mark.parametrize("sigma", [0.3, 0.545, 1.7, 2.75])
def test_psf_sums_to_one_and_is_symmetric(sigma: float) -> None:
    k = psf(sigma)
    assert k.sum() == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(k, k.T)
    np.testing.assert_allclose(k, k[::-1, ::-1])
    assert k.argmax() == k.size // 2


def test_distance_zero_is_unchanged_in_approx_mode(rng: np.random.Generator) -> None:
    img = rng.random((16, 20, 3)).astype(np.float32)
    out, _ = forward_scatter_approx(img, np.zeros((16, 20), np.float32))
    np.testing.assert_allclose(out, img, atol=1e-7)


def test_approx_blurs_more_with_distance() -> None:
    # A vertical edge; the left half of the image is near, the right half far.
    img = np.zeros((32, 64, 3), np.float32)
    img[:, 8:16] = 1.0  # near edge pair
    img[:, 40:48] = 1.0  # far edge pair
    dist = np.where(np.arange(64) < 32, 0.5, 14.0).astype(np.float32)[None].repeat(32, 0)
    out, s_max = forward_scatter_approx(img, dist)
    assert s_max == pytest.approx(sigma_px(14.0), rel=1e-6)
    near_jump = out[16, 15, 0] - out[16, 16, 0]
    far_jump = out[16, 47, 0] - out[16, 48, 0]
    assert near_jump > far_jump + 0.2  # the far edge is softened much more


def test_blur_and_brute_force_agree(rng: np.random.Generator) -> None:  # the torch twin: tests/twins.py
    img = rng.random((13, 17, 3)).astype(np.float32)
    for s in (0.545, 1.3, 2.75):
        a = gaussian_blur(img, s)
        c = forward_scatter_reference(img, np.full((13, 17), (s - 0.5) / 0.15, np.float32))
        np.testing.assert_allclose(c, a, atol=1e-6)


# Error bound of the exact mode (step 0.1 px) against brute-force Eq. (4), stated in docs/synthesis.md.
# Measured 2026-11-23: natural crop max 6e-5; uniform noise (worst case, all energy at the Nyquist limit) 0.011.
EXACT_BOUND_NATURAL = 2e-4
EXACT_BOUND_NOISE = 0.02


def _ramp(h: int, w: int) -> np.ndarray:
    return (0.3 + 14.7 * np.arange(w) / (w - 1)).astype(np.float32)[None].repeat(h, 0)


def test_exact_mode_matches_brute_force_within_the_stated_bound(rng: np.random.Generator) -> None:
    natural = read_rgb(sample_underwater_dir() / "suim" / "d_r_47_.jpg")[100:140, 100:148]
    noise = rng.random((24, 30, 3)).astype(np.float32)
    for img, bound in ((natural, EXACT_BOUND_NATURAL), (noise, EXACT_BOUND_NOISE)):
        d = _ramp(*img.shape[:2])
        ref = forward_scatter_reference(img, d)
        out, s_max = forward_scatter_exact(img, d, step_px=0.1)
        assert np.abs(out - ref).max() < bound
        assert s_max == pytest.approx(2.75, rel=1e-5)
    # coarser grids are worse: the error really comes from the interpolation between levels
    d = _ramp(24, 30)
    ref = forward_scatter_reference(noise, d)
    err = [np.abs(forward_scatter_exact(noise, d, step_px=s)[0] - ref).max() for s in (0.5, 0.1)]
    assert err[0] > 3 * err[1]


def test_exact_mode_is_exact_on_grid_levels(rng: np.random.Generator) -> None:
    img = rng.random((12, 12, 3)).astype(np.float32)
    d = np.full((12, 12), 6.0, np.float32)  # sigma = 0.5 + 0.9 = 1.4 = 0.5 + 9 * 0.1, a grid level
    out, _ = forward_scatter_exact(img, d, step_px=0.1)
    np.testing.assert_allclose(out, forward_scatter_reference(img, d), atol=1e-6)


def test_sigma_levels_bracket_the_range() -> None:
    lv = sigma_levels(0.545, 2.75, sigma0_px=0.5, step_px=0.25)
    assert lv[0] <= 0.545 and lv[-1] >= 2.75
    np.testing.assert_allclose(np.diff(lv), 0.25)
    with pytest.raises(ValueError, match="exact_step_px: expected > 0"):
        sigma_levels(1, 2, sigma0_px=0.5, step_px=0)


def test_errors() -> None:
    img = np.zeros((4, 4, 3), np.float32)
    with pytest.raises(ValueError, match="fs_mode: expected 'approx' or 'exact'"):
        forward_scatter(img, np.ones((4, 4), np.float32), mode="fast")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="sigma: expected > 0"):
        psf(0.0)
    with pytest.raises(ValueError, match="sigma: expected 1 values"):
        gaussian_blur_torch(torch.zeros(1, 3, 4, 4), torch.tensor([1.0, 2.0]))
