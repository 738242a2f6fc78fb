"""The affine-fit PSNR: PSNR after the best per-channel gain and offset onto the reference.

Provenance: the fit is checked against numpy's least-squares solver (``np.linalg.lstsq`` on the design matrix
``[pred_c, 1]``, the form benchmarks/bench_model.py used before the metric moved into murk.metrics); the other
expected values follow from the definition (an exact global map is forgiven completely; local errors are not).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from murk.errors import ShapeError
from murk.metrics import affine_fit, affine_fit_psnr, affine_fit_psnr_torch, psnr


def _lstsq_fit(pred: np.ndarray, ref: np.ndarray) -> np.ndarray:
    out = np.empty(pred.shape, np.float64)
    for c in range(pred.shape[2]):
        design = np.stack([pred[..., c].ravel(), np.ones(pred[..., c].size)], axis=1)
        coef = np.linalg.lstsq(design, ref[..., c].ravel(), rcond=None)[0]
        out[..., c] = coef[0] * pred[..., c] + coef[1]
    return out


def test_fit_equals_least_squares() -> None:
    rng = np.random.default_rng(0)
    ref = rng.random((17, 23, 3))
    pred = 0.4 * ref[..., ::-1] + 0.3 * rng.random(ref.shape)
    np.testing.assert_allclose(affine_fit(pred, ref), _lstsq_fit(pred, ref), atol=1e-12)


def test_a_global_colour_map_is_forgiven_and_local_error_is_not() -> None:
    rng = np.random.default_rng(1)
    ref = rng.random((32, 40, 3)) * 0.8 + 0.1
    gain, offset = np.array([0.3, 0.7, 0.9]), np.array([0.05, 0.2, 0.1])
    cast = ref * gain + offset  # Eq. (1) at one distance: J t + B (1 - t)
    assert psnr(cast, ref, data_range=1.0) < 20.0
    assert affine_fit_psnr(cast, ref, data_range=1.0) > 100.0  # exact up to rounding
    haze = np.linspace(0.0, 0.6, 40)[None, :, None]  # haze that grows across the frame: not one global map
    hazy = ref * (1 - haze) + 0.5 * haze
    assert affine_fit_psnr(hazy, ref, data_range=1.0) < 30.0
    assert affine_fit_psnr(hazy * gain + offset, ref, data_range=1.0) == pytest.approx(
        affine_fit_psnr(hazy, ref, data_range=1.0), abs=1e-6
    )


def test_fit_never_scores_below_plain_psnr_without_clipping() -> None:
    rng = np.random.default_rng(2)
    ref = rng.random((20, 20, 3)) * 0.5 + 0.25
    pred = np.clip(ref + 0.05 * rng.standard_normal(ref.shape), 0.0, 1.0)
    assert affine_fit_psnr(pred, ref, data_range=1.0) >= psnr(pred, ref, data_range=1.0)


def test_flat_channel_maps_to_the_reference_mean() -> None:
    ref = np.random.default_rng(3).random((8, 9, 3))
    pred = np.full_like(ref, 0.5)
    fitted = affine_fit(pred, ref)
    np.testing.assert_allclose(fitted, np.broadcast_to(ref.mean(axis=(0, 1)), ref.shape), atol=1e-15)


def test_identical_images_are_infinite() -> None:
    ref = np.random.default_rng(4).random((5, 6, 3))
    assert affine_fit_psnr(ref, ref, data_range=1.0) == math.inf
    t = torch.from_numpy(ref).permute(2, 0, 1)[None]
    assert float(affine_fit_psnr_torch(t, t, data_range=1.0)[0]) == math.inf


def test_uint8_and_its_range() -> None:
    rng = np.random.default_rng(5)
    ref = rng.random((10, 12, 3))
    pred = np.clip(ref * 0.5 + 0.2 + 0.03 * rng.standard_normal(ref.shape), 0, 1)
    a = affine_fit_psnr(pred, ref, data_range=1.0)
    b = affine_fit_psnr(pred * 255.0, ref * 255.0, data_range=255.0)
    assert a == pytest.approx(b, rel=1e-9)


@pytest.mark.parametrize(
    ("pred", "ref", "error", "match"),
    [
        (np.ones((3, 3)), np.ones((3, 3)), ShapeError, "pred: expected shape"),
        (np.ones((3, 3, 3)), np.ones((3, 4, 3)), ShapeError, "pred: expected the shape of ref"),
        ("x", np.ones((3, 3, 3)), TypeError, "pred: expected a numpy array"),
        (np.ones((3, 3, 3), bool), np.ones((3, 3, 3)), TypeError, "dtype bool"),
    ],
)
def test_invalid_inputs_raise(pred: object, ref: object, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        affine_fit_psnr(pred, ref, data_range=1.0)  # type: ignore[arg-type]


def test_torch_invalid_inputs_raise() -> None:
    with pytest.raises(ShapeError, match="pred: expected shape"):
        affine_fit_psnr_torch(torch.ones(3, 4, 4), torch.ones(3, 4, 4), data_range=1.0)
    with pytest.raises(ValueError, match="data_range"):
        affine_fit_psnr_torch(torch.ones(1, 3, 4, 4), torch.ones(1, 3, 4, 4), data_range=0.0)
