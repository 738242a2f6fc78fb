"""Eq. (9) post-processing: invariants, OpenCV references, numpy == torch, the ``post`` restorer."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch

from murk.enhance import restorer as restorer_mod
from murk.enhance.equalize import _clahe_torch, equalize, equalize_lut, equalize_torch
from murk.enhance.log_filter import laplacian_of_gaussian, laplacian_of_gaussian_torch, log_kernels
from murk.enhance.post import (
    PostParams,
    PostRestorer,
    post_process,
    post_process_torch,
)
from murk.errors import ShapeError

# numpy (OpenCV) vs torch: the equalisation is defined op by op in float32 and is bitwise equal; the LoG sums are
# accumulated in a different order (cv2.sepFilter2D vs conv2d), measured <= 6e-8. Tolerance:
TWIN_ATOL = 1e-6


def _smooth_image(rng: np.random.Generator, h: int, w: int) -> np.ndarray:
    img = cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 2.0)
    img = (img - img.min()) / (img.max() - img.min())
    return (0.1 + 0.6 * img).astype(np.float32)  # low contrast, like murky water


def _t(img: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(img)).permute(2, 0, 1)[None]


def _n(t: torch.Tensor) -> np.ndarray:
    return t[0].permute(1, 2, 0).numpy()


# --- LoG ------------------------------------------------------------------------------------------------------


def test_log_of_a_constant_image_is_zero() -> None:
    const = np.full((20, 30, 3), 0.37, np.float32)
    assert np.abs(laplacian_of_gaussian(const)).max() < 1e-6
    assert laplacian_of_gaussian_torch(_t(const)).abs().max().item() < 1e-6
    g, g2 = log_kernels(1.0)
    assert g.size == 9 and abs(float(g.sum()) - 1.0) < 1e-6 and abs(float(g2.sum())) < 1e-6


def test_log_of_a_quadratic_is_its_laplacian() -> None:
    # f = ((x-20)^2 + (y-25)^2) / 400 has Laplacian 4/400 everywhere; Gaussian smoothing does not change it.
    yy, xx = np.mgrid[0:40, 0:50].astype(np.float32)
    f = ((xx - 20) ** 2 + (yy - 25) ** 2) / 400
    inner = laplacian_of_gaussian(f, 1.0)[6:-6, 6:-6] * 400
    np.testing.assert_allclose(inner, 4.0, rtol=2e-3)  # sampled Gaussian moments are within 0.1 % at sigma = 1


def test_log_matches_scipy_gaussian_laplace(rng: np.random.Generator) -> None:
    # Independent reference: scipy 1.17 ndimage.gaussian_laplace (truncate 4, mode 'mirror' = reflect-101). Ours
    # makes the 2nd-derivative kernel exactly zero-sum, scipy's is not: measured max difference 9.7e-5.
    from scipy import ndimage

    img = _smooth_image(rng, 60, 80)[:, :, 0]
    ref = ndimage.gaussian_laplace(img.astype(np.float64), 1.0, mode="mirror")
    assert np.abs(laplacian_of_gaussian(img, 1.0) - ref).max() < 2e-4
    assert np.abs(ref).max() > 0.02  # the comparison is not between two near-zero maps


def test_post_sharpens_a_step_edge() -> None:
    # a vertical luminance ramp (so equalisation keeps mid-tones) with a step at column 12
    yy, xx = np.mgrid[0:32, 0:24].astype(np.float32)
    img = np.repeat((0.3 + 0.2 * yy / 31 + 0.2 * (xx >= 12))[:, :, None], 3, axis=2).astype(np.float32)
    he = equalize(img, "y")
    out = post_process(img, lam=0.3)
    rows = slice(8, 24)  # away from the top/bottom border
    assert (out[rows, 12] > he[rows, 12] + 0.01).all()  # overshoot on the bright side: minus the LoG, Eq. (9)
    assert (out[rows, 11] < he[rows, 11] - 0.01).all()  # undershoot on the dark side
    np.testing.assert_allclose(out[rows, :4], he[rows, :4], atol=2e-3)  # far from the edge: nearly unchanged


# --- histogram equalisation -------------------------------------------------------------------------------------


def test_equalize_lut_equals_opencv_equalizehist(rng: np.random.Generator) -> None:
    for _ in range(50):
        h, w = rng.integers(1, 60, 2)
        lo, hi = sorted(rng.integers(0, 256, 2))
        img = rng.integers(lo, hi + 1, (h, w)).astype(np.uint8)
        lut = equalize_lut(np.bincount(img.ravel(), minlength=256))
        assert np.array_equal(lut[img].astype(np.uint8), cv2.equalizeHist(img))


def test_lambda_zero_gives_pure_he_equal_to_opencv_on_grey(rng: np.random.Generator) -> None:
    grey8 = cv2.GaussianBlur(rng.integers(40, 160, (40, 50)).astype(np.uint8), (0, 0), 1.5)
    img = np.repeat(grey8[:, :, None], 3, axis=2).astype(np.float32) / 255
    out = post_process(img, lam=0.0)
    np.testing.assert_array_equal(out, equalize(img, "y"))
    # grey: Y == the channel, so Y-equalisation is cv2.equalizeHist of the 8-bit image (up to float rounding)
    np.testing.assert_allclose(out * 255, np.repeat(cv2.equalizeHist(grey8)[:, :, None], 3, axis=2), atol=1e-3)


def test_y_equalisation_matches_the_opencv_ycrcb_route(rng: np.random.Generator) -> None:
    # Reference: OpenCV 5.0.0 uint8 RGB -> YCrCb, equalizeHist(Y), -> RGB. OpenCV's fixed-point Y rounds
    # differently, so pixels near bin boundaries change bin and shift the CDF: measured max 5.0 levels, mean <= 1.4
    # over five such images.
    u8 = (_smooth_image(rng, 48, 64) * 255 + 0.5).astype(np.uint8)
    ycc = cv2.cvtColor(u8, cv2.COLOR_RGB2YCrCb)
    ycc[:, :, 0] = cv2.equalizeHist(ycc[:, :, 0])
    ref = cv2.cvtColor(ycc, cv2.COLOR_YCrCb2RGB).astype(np.float32)
    d = np.abs(equalize(u8.astype(np.float32) / 255, "y") * 255 - ref)
    assert d.max() <= 6.0 and d.mean() < 2.0


def _hue_ramp() -> np.ndarray:
    hue = np.linspace(0, 360, 180, endpoint=False, dtype=np.float32)
    val = np.linspace(0.25, 0.6, 40, dtype=np.float32)
    hsv = np.stack(np.broadcast_arrays(hue[None, :], np.float32(0.35), val[:, None]), axis=-1)
    return cv2.cvtColor(np.ascontiguousarray(hsv, dtype=np.float32), cv2.COLOR_HSV2RGB)


def _hue_shift_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ha = cv2.cvtColor(np.ascontiguousarray(a), cv2.COLOR_RGB2HSV)[:, :, 0]
    hb = cv2.cvtColor(np.ascontiguousarray(b), cv2.COLOR_RGB2HSV)[:, :, 0]
    d = np.abs(ha - hb) % 360
    return np.minimum(d, 360 - d)


def test_he_on_y_keeps_the_hue_of_a_colour_ramp() -> None:
    ramp = _hue_ramp()
    out = equalize(ramp, "y")
    shift = _hue_shift_deg(out, ramp)
    unclipped = (out > 0).all(-1) & (out < 1).all(-1)
    assert unclipped.mean() > 0.8
    assert shift[unclipped].max() < 0.01  # exact up to float: the same offset is added to R, G and B
    assert np.median(shift) < 0.01 and np.percentile(shift, 95) < 5.0  # only clipped pixels move
    assert np.median(_hue_shift_deg(post_process(ramp), ramp)) < 0.01
    # per-channel HE is the contrast case: it does shift hues
    assert np.median(_hue_shift_deg(equalize(ramp, "rgb"), ramp)) > 1.0


def test_constant_image_is_unchanged(rng: np.random.Generator) -> None:
    const = np.empty((12, 10, 3), np.float32)
    const[:] = rng.random(3).astype(np.float32)
    for he in ("y", "rgb"):  # equalisation is the identity on a constant channel; the LoG of a constant is 0
        np.testing.assert_allclose(post_process(const, he=he), const, atol=1e-6)
    clahe = post_process(const, he="clahe")  # OpenCV's CLAHE moves a constant, but uniformly
    assert np.ptp(clahe.reshape(-1, 3), axis=0).max() < 1e-6


def test_sixteen_bit_precision_is_kept() -> None:
    ramp16 = np.linspace(0.3, 0.4, 4000, dtype=np.float32)  # a 16-bit-like ramp spanning ~25 8-bit levels
    img = np.repeat(np.repeat(ramp16[None, :, None], 4, axis=0), 3, axis=2)
    out = equalize(img, "y")
    assert np.unique(out[0, :, 0]).size > 1000  # interpolated mapping: no banding to 8-bit levels
    assert np.all(np.diff(out[0, :, 0]) >= 0)  # monotone


def test_clahe_torch_twin_equals_opencv_exactly(rng: np.random.Generator) -> None:
    # Pinned against OpenCV 5.0.0 cv2.createCLAHE(...).apply on uint8: sizes divisible and not by the grid
    # (OpenCV then pads reflect-101 on both axes), several clip limits and grids.
    cases = [((64, 64), (8, 8), 2.0), ((50, 37), (8, 8), 2.0), ((48, 30), (4, 3), 40.0), ((33, 91), (5, 2), 0.5)]
    cases += [((17, 19), (1, 1), 1.0), ((100, 64), (8, 8), 4.0)]
    for (h, w), tiles, clip in cases:
        img = cv2.normalize(
            cv2.GaussianBlur(rng.integers(0, 256, (h, w)).astype(np.uint8), (0, 0), 3), None, 0, 255, cv2.NORM_MINMAX
        )
        ref = cv2.createCLAHE(clipLimit=clip, tileGridSize=tiles).apply(img)
        mine = _clahe_torch(torch.from_numpy(img.astype(np.int64))[None], clip, tiles)[0].numpy()
        assert np.array_equal(mine, ref), ((h, w), tiles, clip)


def test_output_is_clipped_to_unit_range(rng: np.random.Generator) -> None:
    img = rng.random((32, 32, 3)).astype(np.float32)  # noise: strong LoG response
    out = post_process(img, lam=3.0)
    assert out.min() == 0.0 and out.max() == 1.0
    assert out.dtype == np.float32 and out.shape == img.shape


def test_validation_errors(rng: np.random.Generator) -> None:
    img = rng.random((8, 8, 3)).astype(np.float32)
    with pytest.raises(ValueError, match="sigma_px"):
        post_process(img, sigma_px=0.0)
    with pytest.raises(ValueError, match="lam"):
        post_process(img, lam=-0.1)
    with pytest.raises(ValueError, match="he: expected one of y, rgb, clahe"):
        post_process(img, he="hsv")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="clahe_clip"):
        post_process(img, he="clahe", clahe_clip=0.0)
    with pytest.raises(ValueError, match="clahe_tiles"):
        post_process(img, he="clahe", clahe_tiles=0)
    with pytest.raises(TypeError, match="clahe_tiles"):
        PostParams(clahe_tiles="8")  # type: ignore[arg-type]
    with pytest.raises(ShapeError, match=r"image: expected shape \(H, W, 3\)"):
        post_process(img[:, :, :2])
    with pytest.raises(TypeError, match="image: expected a float image"):
        post_process((img * 255).astype(np.uint8))
    with pytest.raises(ShapeError, match=r"images: expected shape \(B, 3, H, W\)"):
        post_process_torch(torch.rand(3, 8, 8))
    with pytest.raises(TypeError, match="images: expected a float tensor"):
        post_process_torch(torch.zeros(1, 3, 8, 8, dtype=torch.uint8))
    with pytest.raises(ShapeError, match=r"hist: expected shape \(256,\)"):
        equalize_lut(np.ones(255))


# --- the "post" restorer ---------------------------------------------------------------------------------------


def test_post_is_registered_and_takes_its_declared_options(rng: np.random.Generator) -> None:
    assert "post" in restorer_mod.available()
    assert set(restorer_mod.options_of("post")) == {
        "device",
        "sigma_px",
        "lam",
        "he",
        "clahe_clip",
        "clahe_tiles",
        "temporal",
        "preset",
        "he_strength",
    }
    assert str(restorer_mod.options_of("post")["lam"]) == "lam: float | None = None"  # the preset's, unless given
    assert str(restorer_mod.options_of("post")["preset"]) == "preset: PostPreset = 'real'"
    shared = {"checkpoint": "x.pt", "tile": 512, "precision": "bf16", "batch": 4}  # a command's settings for others
    r = restorer_mod.create("post", device="cpu", he="rgb", lam=0.1, shared=shared)
    assert isinstance(r, PostRestorer) and r.params == PostParams(lam=0.1, he="rgb", he_strength=0.3)
    assert restorer_mod.create("post?he=rgb,lam=0.1").params == r.params  # the same options written in the spec
    batch = np.stack([_smooth_image(rng, 20, 24) for _ in range(2)])
    out = r.restore(batch)
    assert out.depth_m is None and out.images.shape == batch.shape
    np.testing.assert_array_equal(out.images[1], post_process(batch[1], he="rgb", lam=0.1, he_strength=0.3))


def test_misspelt_and_foreign_options_are_errors_naming_the_valid_ones() -> None:
    valid = "options of post: clahe_clip, clahe_tiles, device, he, he_strength, lam, preset, sigma_px, temporal"
    with pytest.raises(ValueError, match=rf"unknown option 'lamda' \(did you mean 'lam'\?\); {valid}"):
        restorer_mod.create("post?lamda=0.9")
    with pytest.raises(ValueError, match=rf"unknown option 'lamda' \(did you mean 'lam'\?\); {valid}"):
        restorer_mod.create("post", lamda=0.9)
    with pytest.raises(ValueError, match=rf"method post: unknown option 'checkpoint'; {valid}"):
        restorer_mod.create("post", checkpoint="x.pt")  # an option of other methods, given to post explicitly
    no_method = r"shared setting 'devise' \(did you mean 'device'\?\) is an option of no registered method"
    with pytest.raises(ValueError, match=no_method):
        restorer_mod.create("post", shared={"devise": "cpu"})  # a shared setting no method declares
    # A shared setting the user set explicitly (``given``) must be taken by some stage; unset ones are ignored.
    foreign = r"--tile is an option of jointid, jointid_net, udaformer, ursct, not of the method 'post'"
    with pytest.raises(ValueError, match=foreign):
        restorer_mod.create("post", shared={"device": "cpu", "tile": 256}, given={"tile": "--tile"})
    assert restorer_mod.create("post", shared={"device": "cpu", "tile": 256}).params.lam == 0.1  # preset real
    chain = restorer_mod.create("lite+post", shared={"lam": 0.5}, given={"lam": "--lambda"})
    assert chain.stages[1].params.lam == 0.5  # type: ignore[attr-defined]
    with pytest.raises(ValueError, match=r"method post: option lam: expected float \| None, got 'abc'"):
        restorer_mod.create("post?lam=abc")  # values are checked against the declared types
    with pytest.raises(ValueError, match=r"method post: option he: expected one of 'y', 'rgb', 'clahe', got 'hsv'"):
        restorer_mod.create("post", he="hsv")
    assert restorer_mod.create("post?lam=1,sigma_px=2").params.lam == 1  # an int is a valid float
    with pytest.raises(ValueError, match=r"method: unknown 'pots' \(did you mean 'post'\?\); available: "):
        restorer_mod.create("jointid+pots")
    with pytest.raises(ValueError, match="option 'lam' given twice"):
        restorer_mod.create("post?lam=0.1,lam=0.2")
    with pytest.raises(TypeError, match=r"\*\*kwargs would swallow misspelt options"):
        restorer_mod.register("sloppy")(lambda **kwargs: PostRestorer())
    assert "sloppy" not in restorer_mod.available()


def test_post_restorer_tensor_path_and_chain(rng: np.random.Generator) -> None:
    r = restorer_mod.create("post")
    batch = np.stack([_smooth_image(rng, 20, 24) for _ in range(2)])
    t = r.restore_tensor(torch.from_numpy(batch).permute(0, 3, 1, 2))
    assert np.abs(t.images.permute(0, 2, 3, 1).numpy() - r.restore(batch).images).max() <= TWIN_ATOL
    chain = restorer_mod.create("post+post", lam=0.0, preset="paper")
    twice = chain.restore(batch).images
    np.testing.assert_allclose(twice[0], equalize(equalize(batch[0]), "y"), atol=1e-6)


def test_post_restorer_rejects_bad_batches() -> None:
    r = PostRestorer()
    with pytest.raises(ShapeError, match=r"images: expected shape \(B, H, W, 3\)"):
        r.restore(np.zeros((8, 8, 3), np.float32))
    with pytest.raises(TypeError, match="images: expected a float array"):
        r.restore(np.zeros((1, 8, 8, 3), np.uint8))


def test_half_way_luma_values_fall_in_the_even_bin_as_in_the_torch_twin() -> None:
    # The OpenCV path quantises with cv2.convertScaleAbs, the twin with torch.round: both round half to even.
    # Grey pixels whose 255 * value lies exactly half-way between two bins exercise the tie.
    levels = np.array([0.5, 1.5, 2.5, 100.5, 127.5, 128.5, 253.5, 254.5], np.float32) / np.float32(255.0)
    grey = np.repeat(np.tile(levels, 4)[None, :, None], 3, axis=2).astype(np.float32)
    y255 = (grey[:, :, 0] * np.float32(0.299) + grey[:, :, 1] * np.float32(0.587)) + grey[:, :, 2] * np.float32(0.114)
    assert np.any(np.abs(y255 * 255 - np.floor(y255 * 255) - 0.5) < 1e-4)  # the ties are really there
    np.testing.assert_array_equal(equalize(grey, "y"), _n(equalize_torch(_t(grey), "y")))
    np.testing.assert_array_equal(equalize(grey, "rgb"), _n(equalize_torch(_t(grey), "rgb")))
