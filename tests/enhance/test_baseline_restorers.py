"""The ``udaformer`` and ``ursct`` restorers: both input policies, any size, no batch coupling, registry options
and errors. Small configurations of the exact architectures keep this fast (the restorers take any instance);
the full-size networks run in ``tests/report/test_compare_baselines.py``."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import torch

from murk.enhance.baseline import BaselineRestorer
from murk.enhance.restorer import available
from murk.enhance.restorer import create as create_restorer
from murk.enhance.udaformer_restorer import UDAFORMER
from murk.enhance.ursct_restorer import URSCT_SESR
from murk.errors import ShapeError
from murk.models.udaformer import UDAformer, UDAformerConfig
from murk.models.ursct_sesr import URSCT, URSCTConfig


@pytest.fixture(scope="module")
def uda() -> UDAformer:
    torch.manual_seed(0)
    return UDAformer(UDAformerConfig(dim=8, blocks=(1, 1, 1, 1), refinement_blocks=1)).eval()


@pytest.fixture(scope="module")
def ursct() -> URSCT:
    torch.manual_seed(0)
    return URSCT(URSCTConfig(embed_dim=8, depths=(1, 1, 1, 1))).eval()


def _images(b: int, h: int, w: int, seed: int = 0) -> np.ndarray:
    """8-bit-valued float RGB images, as read from files."""
    return (np.random.default_rng(seed).integers(0, 256, (b, h, w, 3)) / 255.0).astype(np.float32)


def test_registered():
    assert {"udaformer", "ursct"} <= set(available())


def test_udaformer_native_is_the_network_on_bgr_at_the_input_size(uda):
    imgs = _images(2, 24, 40)  # multiples of 8: no padding
    out = BaselineRestorer(UDAFORMER, uda).restore(imgs)
    assert out.images.shape == imgs.shape and out.depth_m is None and out.images.dtype == np.float32
    x = torch.from_numpy(imgs).permute(0, 3, 1, 2).flip(1)
    with torch.no_grad():
        ref = uda(x).flip(1).clamp(0, 1).permute(0, 2, 3, 1).numpy()
    np.testing.assert_allclose(out.images, ref, rtol=0, atol=1e-6)


def test_udaformer_with_a_zero_head_is_the_identity_at_any_size():
    model = UDAformer(UDAformerConfig(dim=4, blocks=(1, 1, 1, 1), refinement_blocks=0))
    with torch.no_grad():
        model.output.weight.zero_()
    r = BaselineRestorer(UDAFORMER, model)
    for h, w in ((13, 29), (1, 5), (40, 24)):
        imgs = _images(1, h, w, seed=h)
        np.testing.assert_array_equal(r.restore(imgs).images, imgs)  # padding, BGR flips and crop undone
    tiled = BaselineRestorer(UDAFORMER, model, tile=16, overlap=8)
    imgs = _images(1, 37, 50)
    np.testing.assert_allclose(tiled.restore(imgs).images, imgs, rtol=0, atol=1e-6)


def test_udaformer_official_policy_reproduces_test_py(uda):
    imgs = _images(1, 60, 90)
    out = BaselineRestorer(UDAFORMER, uda, policy="official").restore(imgs)
    assert out.images.shape == (1, 256, 256, 3)
    u8 = np.rint(imgs[0] * 255).astype(np.uint8)
    bgr = cv2.resize(u8[..., ::-1], (256, 256), interpolation=cv2.INTER_LINEAR)  # cv2.imread is BGR
    x = torch.from_numpy(bgr.transpose(2, 0, 1).copy()).float()[None] / 255.0
    with torch.no_grad():
        y = uda(x)[0].numpy().transpose(1, 2, 0)
    expected = np.clip(np.rint(y * 255), 0, 255)[..., ::-1] / 255.0  # cv2.imwrite: saturate + round half even
    np.testing.assert_allclose(out.images[0], expected, rtol=0, atol=1e-6)
    t = BaselineRestorer(UDAFORMER, uda, policy="official").restore_tensor(torch.from_numpy(imgs).permute(0, 3, 1, 2))
    np.testing.assert_allclose(t.images[0].permute(1, 2, 0).numpy(), out.images[0], atol=0)


def test_ursct_native_tiles_any_size_and_equals_the_network_on_one_tile(ursct):
    r = BaselineRestorer(URSCT_SESR, ursct)
    assert r.tile == 256
    imgs = _images(1, 256, 256)
    x = torch.from_numpy(imgs).permute(0, 3, 1, 2)
    with torch.no_grad():
        ref = ursct(x).clamp(0, 1).permute(0, 2, 3, 1).numpy()
    np.testing.assert_allclose(r.restore(imgs).images, ref, rtol=0, atol=1e-6)
    for shape in ((2, 50, 70), (1, 300, 130)):
        out = r.restore(_images(*shape))
        assert out.images.shape == (*shape, 3) and 0 <= out.images.min() and out.images.max() <= 1


def test_ursct_official_policy_reproduces_enh_eval(ursct):
    imgs = _images(1, 100, 160)
    out = BaselineRestorer(URSCT_SESR, ursct, policy="official").restore(imgs)
    assert out.images.shape == (1, 256, 256, 3)
    x = torch.nn.functional.interpolate(
        torch.from_numpy(imgs).permute(0, 3, 1, 2), size=(256, 256), mode="bilinear", align_corners=False
    )
    with torch.no_grad():
        y = ursct(x).clamp(0, 1)
    expected = (torch.floor(y * 255 + 0.5) / 255).permute(0, 2, 3, 1).numpy()  # save_image: +0.5, truncate
    np.testing.assert_allclose(out.images, expected, rtol=0, atol=1e-6)
    assert np.allclose(out.images * 255, np.round(out.images * 255), atol=1e-4)


@pytest.mark.parametrize("which", ["udaformer", "ursct"])
def test_an_image_does_not_change_when_batched_with_another(which, uda, ursct):
    network, model = (UDAFORMER, uda) if which == "udaformer" else (URSCT_SESR, ursct)
    r = BaselineRestorer(network, model)
    a, b = _images(1, 64, 96, seed=1), _images(1, 64, 96, seed=2)
    alone = r.restore(a).images[0]
    for pair, i in ((np.concatenate([a, b]), 0), (np.concatenate([b, a]), 1)):
        np.testing.assert_allclose(r.restore(pair).images[i], alone, rtol=0, atol=1e-5)
    chunked = BaselineRestorer(network, model, batch=1).restore(np.concatenate([b, a]))
    np.testing.assert_allclose(chunked.images[1], alone, rtol=0, atol=1e-5)


def test_bf16_precision_runs_close_to_fp32(ursct):
    imgs = _images(1, 64, 64)
    a = BaselineRestorer(URSCT_SESR, ursct).restore(imgs).images
    b = BaselineRestorer(URSCT_SESR, ursct, precision="bf16").restore(imgs).images
    assert b.dtype == np.float32 and np.abs(a - b).mean() < 0.05


def test_options_are_validated(uda, ursct):
    with pytest.raises(ValueError, match="policy: expected 'native' or 'official', got 'paper'"):
        BaselineRestorer(UDAFORMER, uda, policy="paper")
    with pytest.raises(ValueError, match=r"tile: expected None or a positive multiple of 8 pixels \(UDAformer\)"):
        BaselineRestorer(UDAFORMER, uda, tile=20)
    with pytest.raises(ValueError, match=r"tile: expected None or a positive multiple of 128 pixels \(URSCT-SESR\)"):
        BaselineRestorer(URSCT_SESR, ursct, tile=320)
    with pytest.raises(ValueError, match=r"overlap: expected 0 <= overlap < tile \(256\)"):
        BaselineRestorer(URSCT_SESR, ursct, overlap=256)
    with pytest.raises(ValueError, match="precision"):
        BaselineRestorer(URSCT_SESR, ursct, precision="int8")
    with pytest.raises(ValueError, match="batch"):
        BaselineRestorer(UDAFORMER, uda, batch=0)
    with pytest.raises(TypeError, match="expected a URSCT"):
        BaselineRestorer(URSCT_SESR, uda)
    with pytest.raises(ShapeError, match=r"\(B, 3, H, W\)"):
        BaselineRestorer(URSCT_SESR, ursct).restore_tensor(torch.zeros(1, 4, 8, 8))
    with pytest.raises(TypeError, match="float tensor"):
        BaselineRestorer(UDAFORMER, uda).restore_tensor(torch.zeros(1, 3, 8, 8, dtype=torch.uint8))


@pytest.mark.parametrize("method", ["udaformer", "ursct"])
def test_factories_need_user_supplied_weights(method):
    with pytest.raises(
        ValueError, match=rf"{method} needs its weights file, which murk does not bundle.*drive\.google"
    ):
        create_restorer(method)
    with pytest.raises(ValueError, match=rf"x\.onnx is an ONNX file; the {method} restorer runs the torch network"):
        create_restorer(method, onnx="x.onnx")


def test_factories_load_files_and_chain_with_post(tmp_path, ursct):
    torch.save({"model": UDAformer().state_dict()}, tmp_path / "uda.pt")
    r = create_restorer(
        "udaformer+post", checkpoint=str(tmp_path / "uda.pt"), policy="native", tile=64, overlap=16, he="y"
    )
    assert r.name == "udaformer+post" and r.stages[0].tile == 64 and r.stages[0].weights == str(tmp_path / "uda.pt")
    out = r.restore(_images(1, 20, 28))
    assert out.images.shape == (1, 20, 28, 3)
    torch.save({"state_dict": URSCT().state_dict()}, tmp_path / "ursct.pth")
    s = create_restorer("ursct", checkpoint=str(tmp_path / "ursct.pth"), policy="official", tile=None)
    assert s.policy == "official" and s.run.model.config.img_size == 256


def test_padding_up_to_a_minimum_size_for_fixed_size_tiles():
    from murk.enhance.tiling import Padding, pad_to_multiple, padding_for

    assert padding_for(50, 300, 8, min_size=256) == Padding(103, 103, 2, 2)
    assert padding_for(256, 264, 8, min_size=256) == Padding(0, 0, 0, 0)
    assert padding_for(45, 70) == Padding(9, 10, 13, 13)  # default unchanged (Joint-ID)
    x = torch.rand(1, 3, 20, 30, generator=torch.Generator().manual_seed(0))
    padded, pad = pad_to_multiple(x, 8, min_size=128)  # reflection repeated: the pad exceeds the size
    assert padded.shape == (1, 3, 128, 128) and torch.equal(pad.crop(padded), x)
    with pytest.raises(ValueError, match="min_size: expected a positive integer"):
        padding_for(5, 5, min_size=0)
