"""UIQM (Eq. (10)): presets against the original codes, the default against hand-computed terms, torch twin.

Provenance of pinned values:

- ``funie``/``jointid`` references: ``tests/data/metrics_reference.json``, produced by running the original
  FUnIE-GAN (python-3 fork, ``uqim_utils.py`` @ d2c8064) and Joint-ID (``uiqm_utils.py`` @ 1e8e7a2) code on
  the committed images (details in ``metrics_refdata.py`` and the file's ``meta``). Required agreement: 1e-4.
- ``panetta2016`` expectations: computed by hand in each test from the formulas of Panetta et al. 2016 as
  written in ``docs/spec/metrics.md`` (the arithmetic is spelled out next to each expected value; none of it
  calls murk).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import torch

from murk.errors import ShapeError
from murk.metrics import MetricWarning, UIQMResult, uiqm, uiqm_torch

from .metrics_refdata import load_reference_image, record_id, records

TOL_ORIGINAL = 1e-4  # issue 4: presets match the original codes within 1e-4
C1, C2, C3 = 0.0282, 0.2953, 3.5753


def _nchw(*images: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.stack([np.array(i) for i in images])).permute(0, 3, 1, 2).contiguous()


# ----------------------------------------------------------------------------------------------------------
# presets == original code


@pytest.mark.parametrize(
    ("preset", "record"),
    [("funie", r) for r in records("uiqm", "funie_py3")] + [("jointid", r) for r in records("uiqm", "jointid")],
    ids=lambda v: v if isinstance(v, str) else record_id(v),
)
def test_preset_matches_original_code(preset: str, record: dict) -> None:
    image = load_reference_image(record["image"], record["size"])
    undefined = record["value"] is None  # the original returned NaN (constant channel: Sobel 0/0)
    if undefined:
        with pytest.warns(MetricWarning, match="Sobel rescale"):
            got = uiqm(image, data_range=255, preset=preset)
    else:
        got = uiqm(image, data_range=255, preset=preset)
    for name, expected in record["components"].items():
        if expected is None:
            assert math.isfinite(getattr(got, name))
            assert getattr(got, name) == 0.0  # documented: constant channels contribute 0 to UISM
        else:
            assert abs(getattr(got, name) - expected) <= TOL_ORIGINAL, name
    if undefined:
        assert math.isfinite(got.uiqm)
        assert got.uiqm == pytest.approx(C1 * got.uicm + C3 * got.uiconm, abs=1e-12)
    else:
        assert abs(got.uiqm - record["value"]) <= TOL_ORIGINAL


def test_jointid_differs_from_funie_only_off_multiples_of_ten() -> None:
    """Joint-ID's float W/10, H/10 block weights: same as FUnIE at 640x480, scaled at 643x481."""
    even = load_reference_image("spec/metric_edge_cases/letterbox_640x480.png", "native")
    odd = load_reference_image("spec/metric_edge_cases/letterbox_643x481.png", "native")
    assert uiqm(even, data_range=255, preset="jointid") == UIQMResult(
        *list(uiqm(even, data_range=255, preset="funie").as_dict().values())[:4], "jointid"
    )
    f, j = uiqm(odd, data_range=255, preset="funie"), uiqm(odd, data_range=255, preset="jointid")
    ratio = (64 * 48) / ((643 / 10) * (481 / 10))  # int block counts vs float W/10 * H/10
    assert j.uicm == f.uicm
    assert j.uism == pytest.approx(f.uism * ratio, rel=1e-12)
    assert j.uiconm == pytest.approx(f.uiconm * ratio, rel=1e-12)


# ----------------------------------------------------------------------------------------------------------
# panetta2016: each term by hand on tiny arrays


def _channels(r: np.ndarray, g: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.stack([r, g, b], axis=-1).astype(np.float64)


def test_uicm_trimmed_mean_and_variance_by_hand() -> None:
    # K = 10 pixels: T_L = ceil(1.0) = 1, T_R = floor(1.0) = 1.
    r = np.arange(10, 101, 10, dtype=np.float64).reshape(2, 5)  # 10, 20, ..., 100
    zero = np.zeros_like(r)
    with pytest.warns(MetricWarning, match="no whole 8x8 block"):
        got = uiqm(_channels(r, zero, zero), data_range=255)
    # RG = R; YB = R/2. Trimmed mean of RG: mean(20..90) = 55; of YB: 27.5.
    # Variance over ALL pixels: mean((R - 55)^2) = 2 (45^2 + 35^2 + 25^2 + 15^2 + 5^2) / 10 = 825; YB: 825/4.
    expected = -0.0268 * math.sqrt(55**2 + 27.5**2) + 0.1586 * math.sqrt(825 + 825 / 4)
    assert got.uicm == pytest.approx(expected, rel=1e-12)


def test_uicm_trims_asymmetrically() -> None:
    # K = 11: T_L = ceil(1.1) = 2 lowest dropped, T_R = floor(1.1) = 1 highest dropped.
    r = np.arange(1, 12, dtype=np.float64).reshape(1, 11)
    zero = np.zeros_like(r)
    with pytest.warns(MetricWarning):
        got = uiqm(_channels(r, zero, zero), data_range=255)
    # mu_RG = mean(3..10) = 6.5 (a symmetric trim would give 6); mu_YB = 3.25.
    # s2_RG = mean(k^2) - 2 * 6.5 * mean(k) + 6.5^2 = 46 - 78 + 42.25 = 10.25; s2_YB = 10.25 / 4.
    expected = -0.0268 * math.sqrt(6.5**2 + 3.25**2) + 0.1586 * math.sqrt(10.25 + 10.25 / 4)
    assert got.uicm == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize(("channel", "weight"), [(0, 0.299), (1, 0.587), (2, 0.114)])
def test_uism_eme_by_hand(channel: int, weight: float) -> None:
    # 8 x 19 image; one channel is a horizontal ramp v = 10 + 10 col, the others a nonzero constant.
    # Sobel (reflect border): Gx = 4 (v[c+1] - v[c-1]) = 80 inside, 4 * 10 = 40 at column 0; Gy = 0.
    # Edge map = |Gx| * v. Whole 8x8 blocks: columns 0-7 and 8-15 (columns 16-18 are a partial block, dropped).
    #   block 1: min 40 * 10 = 400 (col 0), max 80 * 80 = 6400 (col 7)   -> ln(16)
    #   block 2: min 80 * 90 = 7200 (col 8), max 80 * 160 = 12800 (col 15) -> ln(16/9)
    # Constant channels: edge map 0, Imin = 0 in every block -> contribute 0.
    # EME = 2 / (k1 k2) * sum = 2 / 2 * (ln 16 + ln 16/9).
    ramp = np.tile(10.0 + 10.0 * np.arange(19), (8, 1))
    planes = [np.full((8, 19), 50.0)] * 3
    planes[channel] = ramp
    got = uiqm(np.stack(planes, axis=-1), data_range=255)
    assert got.uism == pytest.approx(weight * (math.log(16) + math.log(16 / 9)), rel=1e-12)


def _plip_add(a: float, b: float) -> float:
    return a + b - a * b / 1026.0


def _plip_sub(a: float, b: float) -> float:
    return 1026.0 * (a - b) / (1026.0 - b)


def _plip_scalar(c: float, a: float) -> float:
    return 1026.0 - 1026.0 * (1.0 - a / 1026.0) ** c


def test_uiconm_plip_log_amee_by_hand() -> None:
    # Gray 8 x 24 image, three 8x8 blocks with (min, max) intensity (50, 200), (100, 100) and (10, 250).
    blocks = [(50.0, 200.0), (100.0, 100.0), (10.0, 250.0)]
    gray = np.zeros((8, 24))
    for i, (lo, hi) in enumerate(blocks):
        gray[:, 8 * i : 8 * i + 8] = lo
        gray[:4, 8 * i : 8 * i + 8] = hi
    got = uiqm(np.stack([gray] * 3, axis=-1), data_range=255)
    # Literal PLIP evaluation: c = (max (-) min) / (max (+) min); term c ln c (0 for c = 0); PLIP sum of the
    # terms; PLIP scalar product with 1/(k1 k2) = 1/3. Eq. (9) is that value (<= 0); UIConM is its negation.
    total = 0.0
    for lo, hi in blocks:
        c = _plip_sub(hi, lo) / _plip_add(hi, lo)
        total = _plip_add(total, c * math.log(c) if c > 0 else 0.0)
    log_amee = _plip_scalar(1 / 3, total)
    assert log_amee < 0
    assert got.uiconm == pytest.approx(-log_amee, rel=1e-12)


def test_uiqm_is_eq10_of_its_terms() -> None:
    image = load_reference_image("data/underwater/suim/n_l_52_.jpg", "native")
    for preset in ("panetta2016", "funie", "jointid"):
        r = uiqm(image, data_range=255, preset=preset)
        assert r.preset == preset
        assert r.uiqm == pytest.approx(C1 * r.uicm + C2 * r.uism + C3 * r.uiconm, rel=1e-14)
        assert r.as_dict() == {"uiqm": r.uiqm, "uicm": r.uicm, "uism": r.uism, "uiconm": r.uiconm, "preset": preset}


def test_result_is_frozen() -> None:
    r = uiqm(np.full((8, 8, 3), 0.5), data_range=1.0)
    with pytest.raises(AttributeError):
        r.uiqm = 1.0  # type: ignore[misc]


def test_data_range_scales_the_input() -> None:
    u8 = load_reference_image("data/underwater/funie_euvp/3.jpg", "native")
    ref = uiqm(u8, data_range=255)
    as_float = uiqm(u8.astype(np.float64) / 255.0, data_range=1.0)
    as_u16 = uiqm(u8.astype(np.uint16) * 257, data_range=65535)
    for other in (as_float, as_u16):
        for k in ("uiqm", "uicm", "uism", "uiconm"):
            assert getattr(other, k) == pytest.approx(getattr(ref, k), rel=1e-9, abs=1e-12)


def test_default_differs_from_the_funie_code() -> None:
    """The presets are not aliases: blocks, weights and UIConM differ."""
    image = load_reference_image("data/underwater/suim/n_l_52_.jpg", "native")
    default, funie = uiqm(image, data_range=255), uiqm(image, data_range=255, preset="funie")
    assert abs(default.uism - funie.uism) > 0.1
    assert abs(default.uiconm - funie.uiconm) > 0.05


# ----------------------------------------------------------------------------------------------------------
# torch twin


def test_torch_equals_numpy_panetta2016() -> None:
    names = [
        "data/underwater/suim/n_l_52_.jpg",
        "data/underwater/ufen_gan/EASI.png",
        "data/underwater/stsr/gmn_5015up.jpg",
    ]
    imgs = [load_reference_image(n, "native") for n in names]
    got = uiqm_torch(_nchw(*imgs), data_range=255)
    assert got.uiqm.dtype == torch.float64 and got.uiqm.shape == (3,)
    for i, img in enumerate(imgs):
        ref = uiqm(img, data_range=255)
        for k in ("uiqm", "uicm", "uism", "uiconm"):
            assert float(getattr(got, k)[i]) == pytest.approx(getattr(ref, k), rel=1e-10, abs=1e-12)


@pytest.mark.parametrize("preset", ["funie", "jointid"])
def test_torch_funie_presets_match_the_original(preset: str) -> None:
    """The torch twin reproduces the original's sequential float32 trimmed-mean sum too (pure red is the
    case where an exact sum would be off by 0.108 in UICM, see the reference file's numerical notes)."""
    impl = "funie_py3" if preset == "funie" else "jointid"
    recs = [r for r in records("uiqm", impl) if r["size"] == "640x480"]
    batch = _nchw(*(load_reference_image(r["image"], r["size"]) for r in recs))
    with pytest.warns(MetricWarning, match="constant"):  # gray, black and pure red are in the batch
        got = uiqm_torch(batch, data_range=255, preset=preset)
    for i, r in enumerate(recs):
        for k, expected in r["components"].items():
            if expected is None:
                assert float(getattr(got, k)[i]) == 0.0
            else:
                assert abs(float(getattr(got, k)[i]) - expected) <= 1e-6, (r["image"], k)
        if r["value"] is not None:
            assert abs(float(got.uiqm[i]) - r["value"]) <= 1e-6
        else:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", MetricWarning)
                ref = uiqm(batch[i].permute(1, 2, 0).numpy(), data_range=255, preset=preset)
            assert float(got.uiqm[i]) == pytest.approx(ref.uiqm, abs=1e-12)


# ----------------------------------------------------------------------------------------------------------
# validation


def test_data_range_is_required() -> None:
    with pytest.raises(TypeError, match="data_range"):
        uiqm(np.zeros((8, 8, 3), np.uint8))  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="data_range"):
        uiqm_torch(torch.zeros(1, 3, 8, 8))  # type: ignore[call-arg]


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"image": [[0, 0, 0]], "data_range": 255}, TypeError, "image: expected a numpy array"),
        ({"image": np.zeros((8, 8), np.uint8), "data_range": 255}, ShapeError, r"image: expected shape \(H, W, 3\)"),
        ({"image": np.zeros((8, 8, 4), np.uint8), "data_range": 255}, ShapeError, "got \\(8, 8, 4\\)"),
        ({"image": np.zeros((0, 8, 3), np.uint8), "data_range": 255}, ShapeError, "H, W >= 1"),
        ({"image": np.zeros((8, 8, 3), bool), "data_range": 255}, TypeError, "dtype bool"),
        ({"image": np.full((8, 8, 3), np.nan), "data_range": 1.0}, ValueError, "NaN or inf"),
        ({"image": np.full((8, 8, 3), 200.0), "data_range": 1.0}, ValueError, "pass data_range=255"),
        ({"image": np.full((8, 8, 3), -0.5), "data_range": 1.0}, ValueError, "min -0.5"),
        ({"image": np.zeros((8, 8, 3)), "data_range": 0}, ValueError, "data_range: expected a finite number > 0"),
        ({"image": np.zeros((8, 8, 3)), "data_range": math.inf}, ValueError, "data_range"),
        ({"image": np.zeros((8, 8, 3)), "data_range": "255"}, TypeError, "data_range: expected a number"),
        ({"image": np.zeros((8, 8, 3)), "data_range": True}, TypeError, "data_range"),
        ({"image": np.zeros((8, 8, 3)), "data_range": 1.0, "preset": "matlab"}, ValueError, "preset: expected one of"),
        ({"image": np.zeros((8, 8, 3)), "data_range": 1.0, "preset": 3}, TypeError, "preset"),
    ],
)
def test_invalid_inputs_raise(kwargs: dict, error: type[Exception], match: str) -> None:
    image = kwargs.pop("image")
    with pytest.raises(error, match=match):
        uiqm(image, **kwargs)


def test_a_01_float_image_scored_as_255_is_flagged() -> None:
    image = np.full((8, 8, 3), 0.5)
    image[0, 0] = 0.2
    with pytest.warns(MetricWarning, match="pass data_range=1.0"):
        uiqm(image, data_range=255)
    with pytest.warns(MetricWarning, match="pass data_range=1.0"):
        uiqm_torch(torch.from_numpy(image).permute(2, 0, 1)[None], data_range=255)


@pytest.mark.parametrize(
    ("images", "error", "match"),
    [
        (np.zeros((1, 3, 8, 8)), TypeError, "images: expected a torch.Tensor"),
        (torch.zeros(3, 8, 8), ShapeError, r"images: expected shape \(B, 3, H, W\)"),
        (torch.zeros(1, 8, 8, 3), ShapeError, "got \\(1, 8, 8, 3\\)"),
        (torch.zeros(1, 3, 8, 8, dtype=torch.bool), TypeError, "dtype torch.bool"),
        (torch.full((1, 3, 8, 8), math.nan), ValueError, "NaN or inf"),
        (torch.full((1, 3, 8, 8), 2.0), ValueError, "values in \\[0, data_range=1\\]"),
    ],
)
def test_torch_invalid_inputs_raise(images: object, error: type[Exception], match: str) -> None:
    with pytest.raises(error, match=match):
        uiqm_torch(images, data_range=1.0)  # type: ignore[arg-type]


@pytest.mark.parametrize("preset", ["panetta2016", "funie", "jointid"])
def test_uiqm_does_not_depend_on_the_dtype(preset: str) -> None:
    """The same 8-bit picture scores the same as uint8, uint16, float32 and float64 in [0, 1] (numpy and torch):
    float32 rounding of k/255 used to add UISM +0.28 / UIQM +0.08 (issue 13)."""
    import torch

    from murk.data import sample_underwater_images
    from murk.io import read_image

    u8, _ = read_image(sample_underwater_images()[0])
    ref = uiqm(u8, data_range=255, preset=preset).uiqm
    assert uiqm(u8.astype(np.uint16) * 257, data_range=65535, preset=preset).uiqm == pytest.approx(ref, abs=1e-9)
    for dtype in (np.float32, np.float64):
        assert uiqm(u8.astype(dtype) / 255, data_range=1.0, preset=preset).uiqm == pytest.approx(ref, abs=1e-9)
    t = torch.from_numpy(u8.astype(np.float32) / 255).permute(2, 0, 1)[None]
    assert float(uiqm_torch(t, data_range=1.0, preset=preset).uiqm[0]) == pytest.approx(ref, abs=1e-6)
