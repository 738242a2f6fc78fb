"""greyworld, colorbalance, clahe and udcp: the classical restorers, as registered methods and as chains."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from murk.enhance import restorer as restorer_mod
from murk.enhance.classical import clahe_lab, grey_world, udcp
from murk.errors import ShapeError
from murk.restore_ops.affine_transfer import guided_filter
from murk.restore_ops.balance import color_balance


def _cast_scene(rng: np.random.Generator, h: int = 48, w: int = 64) -> np.ndarray:
    """A textured scene seen through green water: J t + A (1 - t), t falling from left to right."""
    j = cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 2.0)
    j = (j - j.min()) / (j.max() - j.min())
    t = np.linspace(0.9, 0.3, w, dtype=np.float32)[None, :, None] * np.array([0.3, 0.8, 0.7], np.float32)
    a = np.array([0.1, 0.6, 0.5], np.float32)
    return np.clip(j * t + a * (1 - t), 0, 1).astype(np.float32)


def test_grey_world_equalises_the_channel_means() -> None:
    img = _cast_scene(np.random.default_rng(0))
    out = grey_world(img)
    m = out.reshape(-1, 3).mean(0)
    assert np.ptp(m) < 0.01 < np.ptp(img.reshape(-1, 3).mean(0))
    np.testing.assert_allclose(grey_world(img, strength=0.0), img, atol=1e-6)


def test_clahe_keeps_chroma_and_raises_local_contrast() -> None:
    img = _cast_scene(np.random.default_rng(1)) * 0.5 + 0.2
    out = clahe_lab(img, clip=2.0, tiles=4)
    lab_in = cv2.cvtColor(np.rint(img * 255).astype(np.uint8), cv2.COLOR_RGB2LAB).astype(float)
    lab_out = cv2.cvtColor(np.rint(out * 255).astype(np.uint8), cv2.COLOR_RGB2LAB).astype(float)
    assert lab_out[..., 0].std() > 1.2 * lab_in[..., 0].std()
    assert np.abs(lab_out[..., 1:] - lab_in[..., 1:]).mean() < 3.0  # a*, b* kept up to 8-bit rounding


def test_udcp_inverts_its_own_image_formation_model() -> None:
    rng = np.random.default_rng(2)
    h, w = 61, 81  # grid rows and columns 0, 5, ..., 60 (80): every window reaches one
    j = np.clip(cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 3.0) * 2 - 0.5, 0, 1)
    j[::5, ::5, 1:] = 0.0  # a dark green/blue pixel in every 7x7 window: the prior holds
    a = np.array([0.1, 0.55, 0.65], np.float32)
    t = np.full((h, w), 0.5, np.float32)
    img = (j * t[..., None] + a * (1 - t[..., None])).astype(np.float32)
    img[:10, :10] = a  # open water (the veil itself) is in view
    out, t_est, a_est = udcp(img, patch=7, omega=1.0)
    np.testing.assert_allclose(a_est, a, atol=0.02)
    assert abs(float(np.median(t_est)) - 0.5) < 0.1
    inner = (slice(10, None), slice(10, None))
    assert np.abs(out - j)[inner].mean() < 0.5 * np.abs(img - j)[inner].mean()


def test_guided_filter_keeps_edges_of_the_guide() -> None:
    guide = np.zeros((40, 40), np.float32)
    guide[:, 20:] = 1.0
    noisy = guide + np.random.default_rng(3).normal(0, 0.2, guide.shape).astype(np.float32)
    out = guided_filter(guide, noisy, 4, 1e-3)
    assert np.abs(out - guide).mean() < 0.5 * np.abs(noisy - guide).mean()


def test_registered_chains_and_options() -> None:
    names = restorer_mod.available()
    assert {"greyworld", "colorbalance", "clahe", "udcp"} <= set(names)
    img = _cast_scene(np.random.default_rng(4))[None]
    chain = restorer_mod.create("greyworld+clahe?clip=3.0,tiles=4")
    np.testing.assert_array_equal(chain(img).images[0], clahe_lab(grey_world(img[0]), 3.0, 4))
    assert restorer_mod.create("udcp?patch=9")(img).depth_m is None
    balanced = restorer_mod.create("colorbalance?low=0.5,high=2")(img).images[0]
    np.testing.assert_array_equal(balanced, color_balance(img[0], 0.5, 2.0))
    assert np.ptp(balanced.reshape(-1, 3).mean(0)) < np.ptp(img[0].reshape(-1, 3).mean(0))  # the cast is smaller


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("clahe?tiles=0", "tiles"),
        ("greyworld?strength=2", "strength"),
        ("udcp?patch=0", "patch"),
        ("clahe?clip=0", "clip"),
        ("colorbalance?low=60", "low"),
        ("colorbalance?high=-1", "high"),
    ],
)
def test_bad_options_are_refused_by_name(spec: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        restorer_mod.create(spec)


def test_wrong_shapes_are_refused() -> None:
    with pytest.raises(ShapeError, match="images"):
        restorer_mod.create("greyworld")(np.zeros((4, 4, 3), np.float32))


@pytest.mark.parametrize("method", ["greyworld", "colorbalance", "clahe", "udcp", "desnow", "post"])
def test_numpy_restorers_share_the_batch_contract(method: str) -> None:
    """One batch check (restorer.as_batch) for every numpy restorer: one image is told to pass images[None], an
    empty batch is refused, a list of equal frames is a batch."""
    r = restorer_mod.create(method)
    with pytest.raises(ShapeError, match=r"got \(8, 8, 3\) \(one image \(H, W, 3\): pass images\[None\]\)"):
        r.restore(np.zeros((8, 8, 3), np.float32))
    with pytest.raises(ShapeError, match=r"got \(0, 8, 8, 3\)"):
        r.restore(np.zeros((0, 8, 8, 3), np.float32))
    frames = [np.full((8, 8, 3), 0.4, np.float32)] * 2
    assert r.restore(frames).images.shape == (2, 8, 8, 3)  # type: ignore[arg-type]
