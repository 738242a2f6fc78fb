"""The ``lite`` and ``lite+post`` restorers: any frame size, folded network, ONNX backend, shipped-weights
fallback, and errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from murk.enhance.post import post_process
from murk.enhance.restorer import Chain, available, create, weights_used
from murk.models.lite.checkpoint import save_lite_checkpoint
from murk.models.lite.network import build_lite


@pytest.fixture(scope="module")
def lite_ckpt(tmp_path_factory: pytest.TempPathFactory) -> Path:
    torch.manual_seed(0)
    net = build_lite("tiny")
    with torch.no_grad():
        net.head.weight.normal_(std=0.3)  # not the identity
        net.head.bias.normal_(std=0.1)
    return save_lite_checkpoint(net, tmp_path_factory.mktemp("lite") / "lite.pt", step=0)


def _images(n: int = 2, h: int = 37, w: int = 53) -> np.ndarray:
    return np.random.default_rng(7).random((n, h, w, 3), dtype=np.float32)


def test_lite_restores_any_size_without_depth(lite_ckpt: Path) -> None:
    assert {"lite", "post"} <= set(available())
    r = create("lite", checkpoint=str(lite_ckpt))
    assert r.model is not None and r.model.folded  # re-parameterised for inference
    assert weights_used(r).weights == str(lite_ckpt)
    imgs = _images()
    out = r.restore(imgs)
    assert out.images.shape == imgs.shape and out.depth_m is None
    assert out.images.dtype == np.float32 and 0.0 <= out.images.min() and out.images.max() <= 1.0
    assert np.abs(out.images - imgs).mean() > 1e-3  # it changed the images
    t = r.restore_tensor(torch.from_numpy(imgs).permute(0, 3, 1, 2))
    assert np.array_equal(t.images.permute(0, 2, 3, 1).numpy(), out.images)
    assert np.array_equal(r.restore(imgs).images, out.images)  # deterministic
    per_frame = np.concatenate([create("lite", checkpoint=str(lite_ckpt), batch=1).restore(imgs).images])
    # Batched and single-frame convolutions round differently; the guided upsampling's a = cov / (var + eps)
    # scales that float noise up a little.
    np.testing.assert_allclose(per_frame, out.images, atol=2e-5)


def test_lite_plus_post_is_post_after_lite(lite_ckpt: Path) -> None:
    chain = create("lite+post", checkpoint=str(lite_ckpt), lam=0.3)
    assert isinstance(chain, Chain) and [s.name for s in chain.stages] == ["lite", "post"]
    imgs = _images(1, 48, 64)
    lite = create("lite", checkpoint=str(lite_ckpt)).restore(imgs).images[0]
    out = chain.restore(imgs)
    assert out.depth_m is None
    np.testing.assert_allclose(out.images[0], post_process(lite, lam=0.3, he_strength=0.3), atol=1e-6)  # preset real


def test_onnx_backend_matches_torch(lite_ckpt: Path, tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime")
    from murk.models.lite.checkpoint import load_lite
    from murk.models.lite.onnx_export import export_lite_onnx

    onnx_path = export_lite_onnx(load_lite(lite_ckpt), tmp_path / "lite.onnx")
    imgs = _images()
    ref = create("lite", checkpoint=str(lite_ckpt)).restore(imgs).images
    via_onnx = create("lite", checkpoint=str(onnx_path), threads=1)
    assert via_onnx.model is None and weights_used(via_onnx).weights == str(onnx_path)
    np.testing.assert_allclose(via_onnx.restore(imgs).images, ref, atol=1e-4)
    np.testing.assert_allclose(create("lite", onnx=str(onnx_path)).restore(imgs).images, ref, atol=1e-4)
    large = _images(1, 150, 211)  # above the working area: a downsampled working image, no padding
    ref = create("lite", checkpoint=str(lite_ckpt)).restore(large).images
    assert ref.shape == large.shape
    np.testing.assert_allclose(via_onnx.restore(large).images, ref, atol=1e-4)


def test_without_checkpoint_uses_the_shipped_file_or_says_there_is_none(
    lite_ckpt: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import murk.data

    monkeypatch.setattr(murk.data, "shipped_lite_weights", lambda: tmp_path / "absent" / "lite.pt")
    with pytest.raises(ValueError, match=r"no shipped lite weights.*--checkpoint"):
        create("lite")
    monkeypatch.setattr(murk.data, "shipped_lite_weights", lambda: lite_ckpt)
    r = create("lite+post")
    assert weights_used(r).weights == str(lite_ckpt)


def test_errors(lite_ckpt: Path, tmp_path: Path) -> None:
    from murk.errors import InputFileError
    from murk.models.jointid import build_jointid, save_checkpoint

    with pytest.raises(ValueError, match="fp32 only"):
        create("lite", checkpoint=str(lite_ckpt), precision="bf16")
    with pytest.raises(ValueError, match="not both"):
        create("lite", checkpoint=str(lite_ckpt), onnx="x.onnx")
    with pytest.raises(ValueError, match="batch"):
        create("lite", checkpoint=str(lite_ckpt), batch=0)
    jid = save_checkpoint(build_jointid("tiny"), tmp_path / "j.pt")
    with pytest.raises(InputFileError, match="--method jointid"):
        create("lite", checkpoint=str(jid))
    r = create("lite", checkpoint=str(lite_ckpt))
    with pytest.raises(TypeError, match="float tensor"):
        r.restore_tensor(torch.zeros(1, 3, 8, 8, dtype=torch.uint8))
    from murk.errors import ShapeError

    with pytest.raises(ShapeError, match=r"\(B, 3, H, W\)"):
        r.restore_tensor(torch.zeros(3, 8, 8))
    with pytest.raises(ShapeError, match=r"got \(8, 8, 3\) \(one image \(H, W, 3\): pass images\[None\]\)"):
        r.restore(np.zeros((8, 8, 3), np.float32))  # the numpy path names the batch shape too
    with pytest.raises(ShapeError, match=r"got \(1, 1\)"):
        r.restore([[0.0]])  # type: ignore[arg-type]
    frames = [np.full((8, 8, 3), 0.5, np.float32)] * 2  # a list of equal frames is a batch, as before
    assert r.restore(frames).images.shape == (2, 8, 8, 3)  # type: ignore[arg-type]
    with pytest.raises(ShapeError, match=r"got \(0, 8, 8, 3\)"):
        r.restore(np.zeros((0, 8, 8, 3), np.float32))


@pytest.mark.parametrize("hw", [(37, 53), (150, 211), (480, 640)])
def test_the_opencv_upsampling_path_equals_the_network(lite_ckpt: Path, hw: tuple[int, int]) -> None:
    """On the CPU the restorer upsamples the coefficient maps with OpenCV; the result equals the torch network's
    forward (bilinear, half-pixel centres) to float rounding (the interpolation weights round differently)."""
    from murk.models.lite.checkpoint import load_lite
    from murk.models.padding import pad_to_multiple

    net = load_lite(lite_ckpt)
    net.keep_exposure = True  # the method's default (exposure=input): the maps keep the input's exposure
    imgs = _images(2, *hw)
    got = create("lite", checkpoint=str(lite_ckpt)).restore(imgs).images
    x = torch.from_numpy(imgs).permute(0, 3, 1, 2)
    with torch.no_grad():
        if hw[0] * hw[1] <= net.config.work_area_px:
            xp, pad = pad_to_multiple(x, 16, "reflect")
            ref = pad.crop(net(xp))
        else:
            ref = net(x)
    np.testing.assert_allclose(got, ref.clamp(0, 1).permute(0, 2, 3, 1).numpy(), atol=5e-5)


def test_refine_is_an_option_after_the_network_for_torch_and_onnx(lite_ckpt: Path, tmp_path: Path) -> None:
    from murk.restore_ops import affine_transfer as at

    imgs = _images(1, 150, 211)
    plain = create("lite", checkpoint=str(lite_ckpt)).restore(imgs).images  # refine is off by default
    refined = create(f"lite?refine=0.125,checkpoint={lite_ckpt}").restore(imgs).images
    radius = at.transfer_radius_px(150, 211, 0.125)
    want = at.affine_transfer(imgs[0], plain[0], radius, step=at.transfer_step(radius))
    want = at.guard_particle_removal(imgs[0], want, plain[0], 0.04, at.guard_size_px(150, 211))
    np.testing.assert_allclose(refined[0], np.clip(want, 0, 1), atol=1e-6)
    assert np.abs(refined - plain).max() > 0.01
    pytest.importorskip("onnxruntime")
    from murk.models.lite.checkpoint import load_lite
    from murk.models.lite.onnx_export import export_lite_onnx

    onnx_path = export_lite_onnx(load_lite(lite_ckpt), tmp_path / "lite.onnx")
    via_onnx = create("lite", checkpoint=str(onnx_path), threads=1, refine=0.125).restore(imgs).images
    np.testing.assert_allclose(via_onnx, refined, atol=5e-4)  # measured 6e-5: the network's 1e-5, through the transfer
    with pytest.raises(ValueError, match="refine_guard: expected a top-hat luma"):
        create("lite", checkpoint=str(lite_ckpt), refine_guard=1.5)


def test_exposure_is_set_on_the_restorers_copy_and_reaches_every_member(lite_ckpt: Path) -> None:
    from murk.enhance.lite_restorer import LiteRestorer
    from murk.models.lite.checkpoint import load_lite

    folded = load_lite(lite_ckpt, fold=True)
    kept = LiteRestorer(folded, exposure="input")
    assert kept.keep_exposure and kept.model is not None and kept.model.keep_exposure
    assert not folded.keep_exposure  # the caller's network keeps its own setting
    assert not LiteRestorer(folded).keep_exposure  # None: as the network holds it
    # A preset passes it to the lite it blends in, and water to the Joint-ID it builds on
    for spec, want in (("jointid", True), ("jointid?exposure=network", False), ("water?exposure=network", False)):
        r = create(spec)
        top = getattr(r, "base", r)
        used = weights_used(top)
        stages = [used.first, *(s for s, _ in used.blended)]
        assert [s.keep_exposure for s in stages] == [want, want], spec
