"""``loss.local`` (issue 46): the training error left after the output's best global colour map onto the clean
scene, so that a network cannot lower the loss by colour alone."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from murk.metrics import affine_fit
from murk.train.config import LossWeights
from murk.train.losses import jointid_loss, local_l2, row_l2


def test_a_global_colour_error_costs_nothing_and_a_local_one_does() -> None:
    g = torch.Generator().manual_seed(0)
    clean = torch.rand(2, 3, 12, 16, generator=g)
    gain = torch.tensor([0.5, 0.8, 1.2]).view(1, 3, 1, 1)
    offset = torch.tensor([0.1, -0.05, 0.0]).view(1, 3, 1, 1)
    assert float(local_l2(clean * gain + offset, clean)) < 1e-3  # only the 1e-6 guards are left
    assert float(row_l2(clean * gain + offset, clean)) > 0.3
    haze = torch.linspace(0.0, 0.6, 16).view(1, 1, 1, 16)  # grows across the frame
    hazy = clean * (1 - haze) + 0.5 * haze
    assert float(local_l2(hazy, clean)) > 0.1
    assert float(local_l2(hazy * gain + offset, clean)) == pytest.approx(float(local_l2(hazy, clean)), rel=1e-3)


def test_it_is_row_l2_of_the_metric_s_fit() -> None:
    rng = np.random.default_rng(1)
    clean = rng.random((1, 10, 14, 3))
    pred = np.clip(0.7 * clean + 0.1 + 0.05 * rng.standard_normal(clean.shape), 0, 1)
    fitted = affine_fit(pred[0], clean[0])[None]
    to_t = lambda a: torch.from_numpy(a).permute(0, 3, 1, 2)  # noqa: E731
    expected = float(row_l2(to_t(fitted), to_t(clean)))
    assert float(local_l2(to_t(pred), to_t(clean))) == pytest.approx(expected, rel=1e-4)


def test_the_term_is_added_inside_the_enhancement_term_only_when_asked_and_has_gradients() -> None:
    g = torch.Generator().manual_seed(2)
    clean = torch.rand(2, 3, 16, 16, generator=g)
    enhanced = (clean + 0.05 * torch.randn(2, 3, 16, 16, generator=g)).clamp(0, 1).requires_grad_(True)
    plain = jointid_loss(enhanced, clean, None, clean[:, :1], LossWeights())
    assert plain.local is None
    w = LossWeights(local=2.0)
    terms = jointid_loss(enhanced, clean, None, clean[:, :1], w)
    assert terms.local is not None
    expected = float(plain.total.detach()) + w.enhance * 2.0 * float(local_l2(enhanced, clean).detach())
    assert float(terms.total.detach()) == pytest.approx(expected, rel=1e-6)
    terms.total.backward()
    assert enhanced.grad is not None and torch.isfinite(enhanced.grad).all()
    flat = torch.full((1, 3, 8, 8), 0.5, requires_grad=True)  # a flat output: finite gradient too
    local_l2(flat, torch.rand(1, 3, 8, 8, generator=g)).backward()
    assert flat.grad is not None and torch.isfinite(flat.grad).all()


def test_a_negative_weight_is_refused() -> None:
    with pytest.raises(ValueError, match="local"):
        LossWeights(local=-1.0)


def test_local_mse_is_the_squared_error_the_least_squares_colour_map_leaves() -> None:
    from murk.metrics import affine_fit
    from murk.train.losses import local_mse

    rng = np.random.default_rng(3)
    clean = rng.uniform(0, 1, (2, 3, 12, 16)).astype(np.float32)
    other = (clean * 0.7 + 0.1 + rng.normal(0, 0.05, clean.shape)).astype(np.float32)
    got = float(local_mse(torch.from_numpy(other), torch.from_numpy(clean)))
    fitted = np.stack(
        [affine_fit(o.transpose(1, 2, 0), c.transpose(1, 2, 0)) for o, c in zip(other, clean, strict=True)]
    )
    expect = float(np.mean((fitted - clean.transpose(0, 2, 3, 1)) ** 2))
    assert got == pytest.approx(expect, rel=1e-3)  # the 1e-6 guard on the variance is all that differs
    assert float(local_mse(torch.from_numpy(clean * 0.5 + 0.2), torch.from_numpy(clean))) < 1e-8
