"""PSNR and SSIM: numpy (scikit-image) and torch twins, invariants, hand values, validation.

Provenance: the torch twins are pinned to scikit-image 0.26 ``skimage.metrics`` called directly here with the
documented settings (an independent implementation); PSNR is checked against a hand-computed MSE.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from skimage.metrics import structural_similarity

from murk.errors import ShapeError
from murk.metrics import MetricWarning, psnr, psnr_torch, ssim, ssim_torch


def _nchw(a: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(a)).permute(0, 3, 1, 2)


def test_psnr_by_hand() -> None:
    ref = np.full((4, 5, 3), 0.5)
    pred = ref.copy()
    pred[0, 0, 0] += 0.3  # MSE = 0.09 / 60
    assert psnr(pred, ref, data_range=1.0) == pytest.approx(10 * math.log10(1.0 / (0.09 / 60)), rel=1e-12)
    u8 = (ref * 255).astype(np.uint8)
    u8p = u8.copy()
    u8p[1, 1, 1] += 6  # MSE = 36 / 60 in 8-bit units
    assert psnr(u8p, u8, data_range=255) == pytest.approx(10 * math.log10(255**2 / (36 / 60)), rel=1e-12)


def test_invariants(rng: np.random.Generator) -> None:
    x = rng.random((32, 40, 3))
    assert psnr(x, x, data_range=1.0) == math.inf
    assert ssim(x, x, data_range=1.0) == 1.0
    assert ssim(x, x, data_range=1.0, window="uniform") == 1.0
    t = _nchw(x[None])
    assert float(psnr_torch(t, t, data_range=1.0)[0]) == math.inf
    assert float(ssim_torch(t, t, data_range=1.0)[0]) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(
    ("window", "skimage_kwargs"),
    [
        ("gaussian", {"gaussian_weights": True, "sigma": 1.5, "use_sample_covariance": False}),
        ("uniform", {"win_size": 7}),
    ],
)
def test_ssim_numpy_and_torch_equal_scikit_image(window: str, skimage_kwargs: dict, rng: np.random.Generator) -> None:
    ref = rng.random((2, 33, 47, 3))
    pred = np.clip(ref + 0.1 * rng.standard_normal(ref.shape), 0.0, 1.0)
    got_t = ssim_torch(_nchw(pred), _nchw(ref), data_range=1.0, window=window)  # type: ignore[arg-type]
    for i in range(2):
        expected = structural_similarity(ref[i], pred[i], data_range=1.0, channel_axis=-1, **skimage_kwargs)
        assert ssim(pred[i], ref[i], data_range=1.0, window=window) == pytest.approx(expected, rel=1e-12)  # type: ignore[arg-type]
        assert float(got_t[i]) == pytest.approx(expected, rel=1e-10)


def test_ssim_grayscale_and_worse_is_lower(rng: np.random.Generator) -> None:
    ref = rng.random((30, 30))
    mild = np.clip(ref + 0.05 * rng.standard_normal(ref.shape), 0, 1)
    strong = np.clip(ref + 0.3 * rng.standard_normal(ref.shape), 0, 1)
    assert ssim(strong, ref, data_range=1.0) < ssim(mild, ref, data_range=1.0) < 1.0
    assert psnr(strong, ref, data_range=1.0) < psnr(mild, ref, data_range=1.0)


def test_psnr_torch_gives_one_float64_per_image(rng: np.random.Generator) -> None:  # equal to numpy: tests/twins.py
    ref = rng.random((3, 9, 11, 3))
    pred = np.clip(ref + 0.02 * rng.standard_normal(ref.shape), 0, 1)
    pred[1] = ref[1]
    got = psnr_torch(_nchw(pred), _nchw(ref), data_range=1.0)
    assert got.shape == (3,) and got.dtype == torch.float64
    assert math.isinf(float(got[1])) and all(math.isfinite(float(got[i])) for i in (0, 2))


def test_small_images_warn_in_both_twins() -> None:
    a = np.zeros((1, 5, 6, 3))
    b = np.full((1, 5, 6, 3), 0.2)
    with pytest.warns(MetricWarning, match="a 5x5 uniform window"):
        s = ssim(b[0], a[0], data_range=1.0)
    with pytest.warns(MetricWarning, match="a 5x5 uniform window"):
        t = ssim_torch(_nchw(b), _nchw(a), data_range=1.0)
    assert float(t[0]) == pytest.approx(s, rel=1e-12)


@pytest.mark.parametrize(
    ("pred", "ref", "kwargs", "error", "match"),
    [
        (np.zeros((4, 4, 3)), np.zeros((4, 5, 3)), {"data_range": 1.0}, ShapeError, "pred: expected the shape of ref"),
        ([0.0], np.zeros((4, 4, 3)), {"data_range": 1.0}, TypeError, "pred: expected a numpy array"),
        (np.zeros((4, 4, 3)), np.zeros(4), {"data_range": 1.0}, ShapeError, "ref: expected shape"),
        (np.zeros((4, 4, 3)), np.zeros((4, 4, 3)), {"data_range": 0.0}, ValueError, "data_range"),
    ],
)
def test_invalid_inputs_raise(pred: object, ref: object, kwargs: dict, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        psnr(pred, ref, **kwargs)  # type: ignore[arg-type]
    with pytest.raises(error, match=match):
        ssim(pred, ref, **kwargs)  # type: ignore[arg-type]


def test_invalid_window_and_missing_data_range() -> None:
    x = np.zeros((8, 8, 3))
    with pytest.raises(ValueError, match="window: expected one of 'gaussian', 'uniform'"):
        ssim(x, x, data_range=1.0, window="box")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="data_range"):
        psnr(x, x)  # type: ignore[call-arg]
    t = torch.zeros(1, 3, 8, 8)
    with pytest.raises(ShapeError, match="pred: expected the shape of ref"):
        ssim_torch(t, torch.zeros(1, 3, 8, 9), data_range=1.0)
    with pytest.raises(TypeError, match=r"ref: expected a torch\.Tensor"):
        psnr_torch(t, x, data_range=1.0)  # type: ignore[arg-type]
