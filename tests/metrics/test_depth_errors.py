"""Depth errors with Joint-ID's conventions: hand-computed values, clipping/validity rules, torch twin.

Provenance: every expected value below is computed by hand from the definitions in docs/spec/metrics.md
(Eigen et al. error set; prediction clipped to [0.001, 15] m, ground truth valid in (0.001, 15) m).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from murk.errors import ShapeError
from murk.metrics import DepthErrors, depth_errors, depth_errors_torch, mean_depth_errors


def test_errors_by_hand() -> None:
    gt = np.array([[1.0, 2.0], [4.0, 8.0]])
    pred = np.array([[1.0, 4.0], [2.0, 8.0]])
    e = depth_errors(pred, gt)
    # gt - pred: 0, -2, 2, 0; max(gt/pred, pred/gt): 1, 2, 2, 1; ln(pred/gt): 0, ln2, -ln2, 0 (mean 0).
    ln2 = math.log(2)
    assert e.abs_rel == pytest.approx((0 + 2 / 2 + 2 / 4 + 0) / 4)
    assert e.sq_rel == pytest.approx((0 + 4 / 2 + 4 / 4 + 0) / 4)
    assert e.rmse == pytest.approx(math.sqrt((4 + 4) / 4))
    assert e.log_rmse == pytest.approx(math.sqrt(2 * ln2**2 / 4))
    assert e.silog == pytest.approx(100 * math.sqrt(2 * ln2**2 / 4 - 0.0))  # mean log error is 0
    assert e.log10 == pytest.approx(2 * math.log10(2) / 4)
    assert (e.d1, e.d2, e.d3) == (0.5, 0.5, 0.5)  # ratio 2 exceeds even 1.25^3 = 1.953125


def test_delta_thresholds_by_hand() -> None:
    gt = np.ones((1, 4))
    pred = np.array([[1.2, 1.5, 1.9, 2.0]])  # ratios vs 1.25, 1.5625, 1.953125
    e = depth_errors(pred, gt)
    assert (e.d1, e.d2, e.d3) == (0.25, 0.5, 0.75)


def test_clipping_and_validity() -> None:
    gt = np.array([[2.0, 0.0, 20.0, np.nan, 3.0, 5.0]])  # valid: 2, 3, 5
    pred = np.array([[0.0, 9.0, 9.0, 9.0, 100.0, np.nan]])  # -> 0.001, (invalid), (invalid), (invalid), 15, 0.001
    e = depth_errors(pred, gt)
    p = np.array([0.001, 15.0, 0.001])
    g = np.array([2.0, 3.0, 5.0])
    assert e.rmse == pytest.approx(math.sqrt(np.mean((g - p) ** 2)))
    assert e.abs_rel == pytest.approx(np.mean(np.abs(g - p) / g))


def test_the_valid_pixel_rule_and_its_torch_twin() -> None:
    from murk.metrics.depth import valid_depth, valid_depth_torch

    gt = np.array([[2.0, 0.0, 20.0, np.nan, 3.0, 0.001, 15.0, -1.0]])  # valid: 2 and 3 (the limits are open)
    expected = np.array([[True, False, False, False, True, False, False, False]])
    assert np.array_equal(valid_depth(gt), expected)
    assert np.array_equal(valid_depth_torch(torch.from_numpy(gt)).numpy(), expected)


def test_perfect_prediction() -> None:
    gt = np.linspace(0.5, 14.0, 30).reshape(5, 6)
    e = depth_errors(gt.copy(), gt)
    assert e == DepthErrors(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0)


def test_silog_is_scale_invariant_and_rmse_is_not() -> None:
    gt = np.linspace(1.0, 10.0, 20).reshape(4, 5)
    e = depth_errors(1.5 * gt, gt)
    assert e.silog == pytest.approx(0.0, abs=1e-6)
    assert e.rmse > 1.0


def test_median_scaled_abs_rel_forgives_the_scale_only() -> None:
    gt = np.linspace(1.0, 10.0, 20).reshape(4, 5)
    e = depth_errors(0.6 * gt, gt)  # the right shape at the wrong scale
    assert e.abs_rel == pytest.approx(0.4)
    assert e.abs_rel_median == pytest.approx(0.0, abs=1e-12)


def test_median_scaled_abs_rel_by_hand() -> None:
    gt = np.array([[1.0, 2.0, 4.0, 8.0]])
    pred = np.array([[1.0, 1.0, 2.0, 4.0]])
    # lower medians ((n - 1) // 2 = index 1 of the sorted values): gt 2, pred 1 -> scale 2 -> pred 2, 2, 4, 8
    e = depth_errors(pred, gt)
    assert e.abs_rel_median == pytest.approx((1.0 / 1.0 + 0 + 0 + 0) / 4)
    assert e.abs_rel == pytest.approx((0 + 1 / 2 + 2 / 4 + 4 / 8) / 4)
    t = depth_errors_torch(torch.from_numpy(pred)[None], torch.from_numpy(gt)[None])
    assert float(t.abs_rel_median[0]) == pytest.approx(e.abs_rel_median, rel=1e-12)


def test_median_scaled_prediction_is_clipped_again() -> None:
    gt = np.array([[1.0, 14.0, 14.5]])
    pred = np.array([[0.5, 7.0, 14.0]])  # scale 14 / 7 = 2: 1, 14, 28 -> 15 after the clip
    e = depth_errors(pred, gt)
    assert e.abs_rel_median == pytest.approx((0 + 0 + 0.5 / 14.5) / 3)


def test_channel_axis_is_accepted() -> None:
    gt = np.linspace(1.0, 10.0, 20).reshape(4, 5)
    assert depth_errors(gt[..., None] * 1.1, gt[None]) == depth_errors(gt * 1.1, gt)


def test_mean_over_images() -> None:
    a = DepthErrors(*range(10))
    b = DepthErrors(*range(2, 22, 2))
    m = mean_depth_errors([a, b])
    assert m.as_dict() == {
        k: (va + vb) / 2 for (k, va), vb in zip(a.as_dict().items(), b.as_dict().values(), strict=True)
    }
    with pytest.raises(ValueError, match="items: expected at least one"):
        mean_depth_errors([])


@pytest.mark.parametrize(
    ("pred", "gt", "kwargs", "error", "match"),
    [
        (np.ones((3, 3)), np.zeros((3, 3)), {}, ValueError, "gt_m: no valid pixel"),
        (np.ones((3, 4)), np.ones((3, 3)), {}, ShapeError, "pred_m: expected the shape of gt_m"),
        (np.ones((3, 3)), np.ones((2, 3, 3)), {}, ShapeError, "gt_m: expected shape"),
        ("x", np.ones((3, 3)), {}, TypeError, "pred_m: expected a numpy array"),
        (np.ones((3, 3)), np.ones((3, 3)), {"min_depth_m": 5.0, "max_depth_m": 2.0}, ValueError, "min_depth_m <"),
        (np.ones((3, 3)), np.ones((3, 3)), {"max_depth_m": -1.0}, ValueError, "max_depth_m"),
    ],
)
def test_invalid_inputs_raise(pred: object, gt: object, kwargs: dict, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        depth_errors(pred, gt, **kwargs)  # type: ignore[arg-type]


def test_torch_invalid_inputs_raise() -> None:
    with pytest.raises(ValueError, match=r"images \[1\] have no valid pixel"):
        depth_errors_torch(torch.ones(2, 4, 4), torch.stack([torch.ones(4, 4), torch.zeros(4, 4)]))
    with pytest.raises(ShapeError, match="pred_m: expected the shape of gt_m"):
        depth_errors_torch(torch.ones(2, 4, 5), torch.ones(2, 4, 4))
    with pytest.raises(TypeError, match=r"gt_m: expected a torch\.Tensor"):
        depth_errors_torch(torch.ones(2, 4, 4), np.ones((2, 4, 4)))  # type: ignore[arg-type]
