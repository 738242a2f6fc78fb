"""Golden values from docs/spec/jointid.md (computed by the spec's authors with the original Joint-ID loss
code; the spec records them, murk does not read that code)."""

from __future__ import annotations

import math

import pytest
import torch

from murk.train.losses import LossWeights, jointid_loss, laplacian, row_l2, silog, ssim_index
from murk.train.schedule import Schedule


def _golden_pair() -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.arange(120, dtype=torch.float64).reshape(2, 3, 4, 5) / 120
    return g, torch.flip(g, dims=[-1]) ** 2


def test_row_l2_and_laplacian_goldens() -> None:
    g, t = _golden_pair()
    assert float(row_l2(g, t)) == pytest.approx(0.378779, abs=5e-7)
    assert float(0.1 * row_l2(laplacian(g), laplacian(t))) == pytest.approx(0.0414454, abs=5e-8)


def test_silog_golden_with_invalid_pixels() -> None:
    pred = torch.linspace(0.5, 10, 40, dtype=torch.float64).reshape(2, 1, 4, 5)
    gt = torch.flip(pred, dims=[-1]).clone()
    gt[0, 0, 0, :2] = 0
    assert float(silog(pred, gt)) == pytest.approx(2.493537, abs=5e-7)


def test_loss_properties() -> None:
    x = torch.rand(2, 3, 16, 16, dtype=torch.float64)
    assert float(row_l2(x, x)) == pytest.approx(1e-6 * 16**0.5, rel=1e-9)  # only the +1e-6 offset remains
    assert float(laplacian(torch.ones(1, 1, 5, 5))[0, 0, 2, 2]) == 0.0  # a constant has no Laplacian inside
    d = torch.rand(2, 1, 8, 8, dtype=torch.float64) + 0.5
    assert float(silog(d, d)) == pytest.approx(0.0, abs=1e-6)
    # a uniform factor k: d = ln k everywhere, so SILog = 10 sqrt(0.15) ln k (scale-invariant up to lambda)
    assert float(silog(d * 3, d)) == pytest.approx(10 * 0.15**0.5 * math.log(3), rel=1e-9)
    assert float(ssim_index(x, x)) == pytest.approx(1.0)
    terms = jointid_loss(x.float(), x.float(), d.float(), d.float())
    assert float(terms.total) < 1e-3 and float(terms.ssim) == 0.0
    with_ssim = jointid_loss(x.float(), (x * 0.5).float(), d.float(), d.float(), LossWeights(ssim=2.5))
    assert float(with_ssim.ssim) > 0.01
    assert float(with_ssim.total) == pytest.approx(
        float(2.0 * (with_ssim.l2 + 0.1 * with_ssim.lap) + 1.8 * with_ssim.silog + 2.5 * with_ssim.ssim), rel=1e-6
    )


def test_no_valid_depth_gives_zero_silog_with_a_graph() -> None:
    pred = torch.rand(1, 1, 4, 4, requires_grad=True)
    loss = silog(pred, torch.zeros(1, 1, 4, 4))
    loss.backward()
    assert float(loss.detach()) == 0.0 and pred.grad is not None


def test_schedule_reference_sequence() -> None:
    s = Schedule(steps_per_epoch=4)
    seq = [s.lr(i) for i in range(20)]
    expect = [2e-6, 2e-6, 5.15e-5, 1.01e-4, 1.505e-4, 2e-4, 1.981e-4]
    assert seq[:7] == pytest.approx(expect, rel=1e-3)
    assert seq[-1] == pytest.approx(9.54e-6, rel=1e-3)
    assert s.total_steps == 20 and max(seq) == pytest.approx(2e-4)
    with pytest.raises(ValueError, match="steps_per_epoch: expected >= 1"):
        Schedule(0)
    with pytest.raises(ValueError, match="warmup_epochs"):
        Schedule(4, epochs=1, warmup_epochs=1)
