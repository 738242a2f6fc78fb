"""Never NaN, never a crash: every metric and preset on the edge-case images (uniform gray, all black,
letterboxed, pure red, 1x1, sizes that are not multiples of the block size), numpy and torch.

Documented values where a term is undefined (see the module docstrings and docs/metrics.md):

- ``funie``/``jointid`` on a constant channel: the Sobel rescale 255/max is 0/0 (the original returns NaN);
  murk sets that channel's edge map to 0 -> its EME is 0 -> MetricWarning.
- any UIQM preset on an image smaller than one block: UISM = UIConM = 0 -> MetricWarning.
- any UIQM preset on a 1-pixel image: the trimmed mean keeps no value -> plain mean -> MetricWarning.
- ``panetta2016`` on a flat image: every block has Imin = 0 edge (UISM = 0) and c = 0 contrast (UIConM = 0);
  both are defined by the formulas, so no warning.
- ``cielab_raw`` at L* = 0 pixels: no saturation -> left out (all black: mu_s = 0) -> MetricWarning.
- SSIM on an image smaller than the window: smaller uniform window -> MetricWarning.

Hand-computed expectations are spelled out next to each assertion.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import torch

from murk.metrics import (
    MetricWarning,
    depth_errors,
    psnr,
    psnr_torch,
    ssim,
    ssim_torch,
    uciqe,
    uciqe_torch,
    uiqm,
    uiqm_torch,
)

from .metrics_refdata import edge_image

EDGE_FILES = [
    "gray128_640x480.png",
    "black_640x480.png",
    "letterbox_640x480.png",
    "purered_640x480.png",
    "letterbox_643x481.png",
]
UIQM_PRESETS = ["panetta2016", "funie", "jointid"]
UCIQE_PRESETS = ["uciqe_m", "cielab_raw"]


def _small_images() -> dict[str, np.ndarray]:
    g = np.random.default_rng(7)
    return {
        "1x1": np.array([[[200, 30, 90]]], np.uint8),
        "1x1-black": np.zeros((1, 1, 3), np.uint8),
        "3x2": g.integers(0, 256, (3, 2, 3), dtype=np.uint8),
        "9x13": g.integers(0, 256, (9, 13, 3), dtype=np.uint8),
        "17x23": g.integers(0, 256, (17, 23, 3), dtype=np.uint8),
        "1x40": g.integers(0, 256, (1, 40, 3), dtype=np.uint8),
    }


def _all_images() -> dict[str, np.ndarray]:
    return {**{f: edge_image(f) for f in EDGE_FILES}, **_small_images()}


def _finite(result: object) -> bool:
    return all(math.isfinite(v) for v in result.as_dict().values() if isinstance(v, float))  # type: ignore[attr-defined]


@pytest.mark.parametrize("preset", UIQM_PRESETS)
@pytest.mark.parametrize("name", list(_all_images()))
def test_uiqm_is_finite_numpy_and_torch(name: str, preset: str) -> None:
    image = _all_images()[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MetricWarning)
        r = uiqm(image, data_range=255, preset=preset)
        t = uiqm_torch(torch.from_numpy(np.array(image)).permute(2, 0, 1)[None], data_range=255, preset=preset)
    assert _finite(r)
    for k in ("uiqm", "uicm", "uism", "uiconm"):
        v = float(getattr(t, k)[0])
        assert math.isfinite(v)
        assert v == pytest.approx(getattr(r, k), rel=1e-6, abs=1e-9)


@pytest.mark.parametrize("preset", UCIQE_PRESETS)
@pytest.mark.parametrize("name", list(_all_images()))
def test_uciqe_is_finite_numpy_and_torch(name: str, preset: str) -> None:
    image = _all_images()[name]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MetricWarning)
        r = uciqe(image, data_range=255, preset=preset)
        t = uciqe_torch(torch.from_numpy(np.array(image)).permute(2, 0, 1)[None], data_range=255, preset=preset)
    assert _finite(r)
    for k in ("uciqe", "sigma_c", "con_l", "mu_s"):
        assert float(getattr(t, k)[0]) == pytest.approx(getattr(r, k), rel=1e-9, abs=1e-7)


@pytest.mark.parametrize("preset", ["funie", "jointid"])
@pytest.mark.parametrize("name", ["gray128_640x480.png", "black_640x480.png", "purered_640x480.png"])
def test_funie_constant_channel_warns_and_gives_zero_uism(name: str, preset: str) -> None:
    with pytest.warns(MetricWarning, match="constant"):
        r = uiqm(edge_image(name), data_range=255, preset=preset)
    assert r.uism == 0.0
    assert r.uiconm == 0.0  # every 10x10 block is flat (max = min) -> Michelson term skipped


def test_panetta_flat_images_are_defined_without_warning() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", MetricWarning)
        gray = uiqm(edge_image("gray128_640x480.png"), data_range=255)
        red = uiqm(edge_image("purered_640x480.png"), data_range=255)
    assert (gray.uicm, gray.uism, gray.uiconm, gray.uiqm) == (0.0, 0.0, 0.0, 0.0)
    # Pure red: RG = 255, YB = 127.5 everywhere -> trimmed means 255 and 127.5, variances 0.
    assert red.uicm == pytest.approx(-0.0268 * math.sqrt(255**2 + 127.5**2), rel=1e-12)
    assert red.uiqm == pytest.approx(0.0282 * red.uicm, rel=1e-12)


def test_one_pixel_uiqm_value_and_warnings() -> None:
    image = np.array([[[200, 30, 90]]], np.uint8)
    with pytest.warns(MetricWarning) as caught:
        r = uiqm(image, data_range=255)
    messages = " | ".join(str(w.message) for w in caught)
    assert "1-pixel" in messages and "no whole 8x8 block" in messages
    # RG = 170, YB = 115 - 90 = 25: the means are the values themselves, the variances 0.
    assert r.uicm == pytest.approx(-0.0268 * math.hypot(170, 25), rel=1e-12)
    assert (r.uism, r.uiconm) == (0.0, 0.0)


def test_letterbox_bars_do_not_break_uiqm() -> None:
    """Black bars make many blocks Imin = 0 (EME contribution 0) but the photo's blocks still count."""
    r = uiqm(edge_image("letterbox_640x480.png"), data_range=255)
    assert r.uism > 1.0 and r.uiconm > 0.05


def test_cielab_raw_all_black_warns_and_is_zero() -> None:
    with pytest.warns(MetricWarning, match="undefined everywhere"):
        r = uciqe(edge_image("black_640x480.png"), data_range=255, preset="cielab_raw")
    assert (r.sigma_c, r.con_l, r.mu_s, r.uciqe) == (0.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("name", list(_all_images()))
def test_reference_metrics_on_edge_cases(name: str) -> None:
    image = _all_images()[name]
    if image.shape[0] >= 80:  # a 64x64 crop of the 640x480 cases keeps their content (letterbox edge: row 48)
        image = np.ascontiguousarray(image[16:80, :64])
    other = np.ascontiguousarray(255 - image)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MetricWarning)
        assert psnr(image, image, data_range=255) == math.inf
        assert ssim(image, image, data_range=255) == pytest.approx(1.0, abs=1e-12)
        p, s = psnr(other, image, data_range=255), ssim(other, image, data_range=255)
        tp = psnr_torch(
            torch.from_numpy(other).permute(2, 0, 1)[None],
            torch.from_numpy(np.array(image)).permute(2, 0, 1)[None],
            data_range=255,
        )
        ts = ssim_torch(
            torch.from_numpy(other).permute(2, 0, 1)[None],
            torch.from_numpy(np.array(image)).permute(2, 0, 1)[None],
            data_range=255,
        )
    assert math.isfinite(p) and math.isfinite(s)
    assert float(tp[0]) == pytest.approx(p, rel=1e-12)
    assert float(ts[0]) == pytest.approx(s, rel=1e-9, abs=1e-12)


def test_ssim_small_image_warns() -> None:
    a = np.array([[[200, 30, 90]]], np.uint8)
    b = np.array([[[100, 30, 90]]], np.uint8)
    with pytest.warns(MetricWarning, match="smaller than the 11x11 SSIM window"):
        s = ssim(a, b, data_range=255)
    # 1x1 window: variances 0 -> SSIM = mean over channels of (2 x y + C1) / (x^2 + y^2 + C1).
    c1 = (0.01 * 255) ** 2
    expected = ((2 * 200 * 100 + c1) / (200**2 + 100**2 + c1) + 1 + 1) / 3
    assert s == pytest.approx(expected, rel=1e-12)


def test_depth_errors_on_one_pixel() -> None:
    e = depth_errors(np.array([[2.0]]), np.array([[2.5]]))
    assert all(math.isfinite(v) for v in e.as_dict().values())
    assert e.silog == 0.0  # one pixel: the scale-invariant variance is 0
    assert e.abs_rel == pytest.approx(0.5 / 2.5)
