"""The ``jointid_net`` restorer (tiny variant): pad/crop, tiling, batching, precision, ONNX backend, options; and
``jointid``, the preset that blends the shipped ``lite`` into it."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch

from murk.data import sample_underwater_images
from murk.enhance.jointid_restorer import JointIDRestorer
from murk.enhance.restorer import Blend, available, create, weights_used
from murk.errors import InputFileError, ShapeError
from murk.io import read_rgb
from murk.models.jointid import JointID, build_jointid, normalize_input, save_checkpoint


@pytest.fixture(scope="module")
def tiny() -> JointID:
    torch.manual_seed(0)
    return build_jointid("tiny").eval()


@pytest.fixture(scope="module")
def tiny_ckpt(tmp_path_factory, tiny):
    return save_checkpoint(tiny, tmp_path_factory.mktemp("ckpt") / "tiny.pt")


@pytest.fixture(scope="module")
def underwater() -> np.ndarray:
    """A real underwater sample (SUIM), cropped to 240x300 (neither side a multiple of 32)."""
    path = next(p for p in sample_underwater_images() if p.name == "d_r_47_.jpg")
    return read_rgb(path)[:240, :300]


def test_registered_and_created_from_a_checkpoint_rejecting_unknown_options(tiny_ckpt):
    assert {"jointid", "jointid_net"} <= set(available())
    r = create("jointid_net", checkpoint=tiny_ckpt, device="cpu", precision="fp32", shared={"he": "rgb", "lam": 0.1})
    assert isinstance(r, JointIDRestorer) and r.name == "jointid" and r.model.config.depths == (1, 1, 2, 1)
    blended = create("jointid", checkpoint=tiny_ckpt, precision="fp32", shared={"he": "rgb", "lam": 0.1})
    assert isinstance(blended, Blend) and blended.name == "jointid" and isinstance(blended.left, JointIDRestorer)
    with pytest.raises(ValueError, match=r"unknown option 'strength'; options of jointid: batch, checkpoint, "):
        create("jointid", checkpoint=tiny_ckpt, strength=0.7)
    with pytest.raises(ValueError, match=r"unknown option 'tiles' \(did you mean 'tile'\?\)"):
        create(f"jointid?tiles=64,checkpoint={tiny_ckpt}")
    r = create(f"jointid?tile=64,overlap=16,checkpoint={tiny_ckpt}", tile=128).left  # the spec's options win
    assert (r.tile, r.overlap) == (64, 16)
    with pytest.raises(ValueError, match=r"method jointid: option tile: expected int \| None, got 'big'"):
        create(f"jointid?tile=big,checkpoint={tiny_ckpt}")
    assert create("jointid", checkpoint=tiny_ckpt, device=torch.device("cpu")).device == torch.device("cpu")


def test_factory_defaults_to_shipped_weights_and_reports_bad_files(tmp_path, monkeypatch):
    from murk.data import shipped_jointid_weights

    assert create("jointid_net").weights == str(shipped_jointid_weights())  # no checkpoint: the shipped model
    assert weights_used(create("jointid")).weights == str(shipped_jointid_weights())
    monkeypatch.setattr("murk.data.shipped_jointid_weights", lambda: tmp_path / "absent.pt")
    with pytest.raises(ValueError, match=r"shipped weights .* are missing.*--checkpoint"):
        create("jointid")
    with pytest.raises(InputFileError, match="checkpoint not found"):
        create("jointid", checkpoint=tmp_path / "missing.pt")
    with pytest.raises(ValueError, match="one of them"):
        create("jointid", checkpoint="a.pt", onnx="b.onnx")


def test_odd_sizes_are_padded_and_cropped_not_resized(tiny):
    rgb = np.random.default_rng(0).random((2, 45, 70, 3), dtype=np.float32)
    out = JointIDRestorer(tiny, refine=0.0).restore(rgb)  # the network's own output
    assert out.images.shape == (2, 45, 70, 3) and out.images.dtype == np.float32
    assert out.depth_m.shape == (2, 45, 70) and out.depth_m.dtype == np.float32
    assert 0 <= out.images.min() and out.images.max() <= 1 and 0 < out.depth_m.min() and out.depth_m.max() < 15
    # The same by hand: normalise, reflect-pad 45x70 -> 64x96 (9/10 rows, 13/13 columns), forward, crop.
    x = normalize_input(torch.from_numpy(rgb).permute(0, 3, 1, 2))
    x = torch.nn.functional.pad(x, (13, 13, 9, 10), mode="reflect")
    with torch.no_grad():
        ref = tiny(x)
    np.testing.assert_allclose(out.depth_m, ref.depth_m[:, 0, 9:54, 13:83].numpy(), rtol=0, atol=1e-6)
    np.testing.assert_allclose(out.images, ref.enhanced[:, :, 9:54, 13:83].permute(0, 2, 3, 1).numpy(), atol=1e-6)


def test_multiple_of_32_frames_pass_through_unpadded(tiny):
    rgb = torch.rand(1, 3, 64, 96, generator=torch.Generator().manual_seed(4))
    out = JointIDRestorer(tiny, refine=0.0).restore_tensor(rgb)
    with torch.no_grad():
        ref = tiny(normalize_input(rgb))
    assert torch.equal(out.depth_m, ref.depth_m) and torch.equal(out.images, ref.enhanced)


@pytest.mark.parametrize("hw", [(1, 1), (3, 200), (33, 31)])
def test_any_size_works(tiny, hw):
    out = JointIDRestorer(tiny).restore(np.full((1, *hw, 3), 0.4, np.float32))
    assert out.images.shape == (1, *hw, 3) and out.depth_m.shape == (1, *hw)
    assert np.isfinite(out.images).all() and np.isfinite(out.depth_m).all()


def test_tiled_inference_approximates_whole_frame_inference(tiny, underwater):
    # Joint-ID has global context (attention, per-image RLN statistics), so tiles cannot be exact. Stated
    # tolerance (tiny variant, seed 0, this 240x300 crop, tile 128 / overlap 64), measured 2026-11-23:
    # enhanced mean |diff| 0.0048 (max 0.046), depth mean |diff| 0.071 m (max 0.54 m). For scale, the output
    # for the vertically flipped frame differs from the original's by 0.016 (enhanced) and 0.29 m (depth).
    whole = JointIDRestorer(tiny).restore(underwater[None])
    tiled = JointIDRestorer(tiny, tile=128, overlap=64).restore(underwater[None])
    d_img = np.abs(tiled.images - whole.images)
    d_depth = np.abs(tiled.depth_m - whole.depth_m)
    assert d_img.mean() < 0.008 and d_img.max() < 0.08
    assert d_depth.mean() < 0.12 and d_depth.max() < 1.0
    # A tile as large as the frame is exactly whole-frame inference.
    big = JointIDRestorer(tiny, tile=512, overlap=64).restore(underwater[None])
    assert np.array_equal(big.images, whole.images) and np.array_equal(big.depth_m, whole.depth_m)
    off = JointIDRestorer(tiny, tile=0, overlap=None)  # CLI-style "no tiling", default overlap
    assert off.tile is None and off.overlap == 64


def test_mixed_sizes_in_one_run_give_each_size_its_own_output(tiny):
    # A folder of mixed sizes goes through one restorer, shape after shape (issue 29): nothing kept from one
    # shape (oneDNN primitives, allocations) may change another's output. Each odd size restored alone in a fresh
    # restorer, and again after the others in a shared one, must be the same bit for bit.
    rng = np.random.default_rng(3)
    images = [rng.random((1, h, w, 3), dtype=np.float32) for h, w in ((37, 50), (64, 96), (101, 33), (37, 50))]
    shared = JointIDRestorer(tiny)
    for img in images:
        alone = JointIDRestorer(tiny).restore(img)
        mixed = shared.restore(img)
        assert np.array_equal(mixed.images, alone.images) and np.array_equal(mixed.depth_m, alone.depth_m)


def test_batch_option_and_determinism(tiny):
    rgb = np.random.default_rng(1).random((3, 40, 50, 3), dtype=np.float32)
    a = JointIDRestorer(tiny).restore(rgb)
    b = JointIDRestorer(tiny, batch=1).restore(rgb)
    c = JointIDRestorer(tiny).restore(rgb)
    np.testing.assert_allclose(a.images, b.images, atol=1e-5)
    np.testing.assert_allclose(a.depth_m, b.depth_m, atol=1e-4)
    assert np.array_equal(a.images, c.images) and np.array_equal(a.depth_m, c.depth_m)


def test_bf16_autocast_on_cpu_is_close_to_fp32(tiny):
    rgb = np.random.default_rng(2).random((1, 64, 64, 3), dtype=np.float32)
    fp32 = JointIDRestorer(tiny).restore(rgb)
    bf16 = JointIDRestorer(tiny, precision="bf16").restore(rgb)
    mse = float(np.mean((fp32.images - bf16.images) ** 2))
    assert 0 < mse and 10 * np.log10(1 / mse) > 30  # PSNR > 30 dB (bf16 has 8 mantissa bits)


def test_onnx_backend_matches_torch(tmp_path, tiny, tiny_ckpt):
    pytest.importorskip("onnxruntime")
    from murk.models.jointid.onnx_export import export_onnx

    path = export_onnx(tiny, tmp_path / "tiny.onnx")
    rgb = np.random.default_rng(3).random((2, 45, 70, 3), dtype=np.float32)
    for options in ({}, {"tile": 64, "overlap": 32}):
        ref = JointIDRestorer(tiny, exposure="input", **options).restore(rgb)  # the network alone (refine 0)
        out = create("jointid", checkpoint=path, refine=0.0, lite_blend=0, **options).restore(
            rgb
        )  # .onnx -> ONNX Runtime; the exposure step after the graph, as after the torch network
        np.testing.assert_allclose(out.images, ref.images, rtol=0, atol=2e-5)
        np.testing.assert_allclose(out.depth_m, ref.depth_m, rtol=0, atol=1e-4)
    assert "OnnxJointID" in repr(create("jointid", onnx=path))
    with pytest.raises(ValueError, match="ONNX models run in fp32"):
        create("jointid", checkpoint=path, precision="bf16")


def test_onnx_backend_of_balanced_weights_matches_torch_at_any_size(tmp_path, tiny):
    """Weights trained on balanced input: the export balances each whole frame inside its graph, before padding,
    as the torch restorer does (the restorer used to pad first, so the graph took its levels from the padding
    too: 0.011 off at 50x70 with the shipped weights)."""
    pytest.importorskip("onnxruntime")
    from murk.models.jointid.onnx_export import export_onnx

    balanced = copy.deepcopy(tiny)
    balanced.input_balance_pct = 0.5
    path = export_onnx(balanced, tmp_path / "balanced.onnx")
    for hw in ((45, 70), (64, 96)):  # padded and not
        rgb = (0.2 + 0.5 * np.random.default_rng(hw[0]).random((2, *hw, 3))).astype(np.float32)
        ref = JointIDRestorer(balanced, exposure="input").restore(rgb)  # the exposure of the balanced frame
        out = create("jointid", checkpoint=path, refine=0.0, lite_blend=0).restore(rgb)
        np.testing.assert_allclose(out.images, ref.images, rtol=0, atol=2e-5)
        np.testing.assert_allclose(out.depth_m, ref.depth_m, rtol=0, atol=1e-4)


def test_invalid_options_are_rejected(tiny):
    with pytest.raises(ValueError, match="precision"):
        JointIDRestorer(tiny, precision="int8")
    with pytest.raises(ValueError, match="tile: expected None or a positive multiple of 32"):
        JointIDRestorer(tiny, tile=100)
    with pytest.raises(ValueError, match="overlap"):
        JointIDRestorer(tiny, tile=64, overlap=64)
    with pytest.raises(ValueError, match="batch"):
        JointIDRestorer(tiny, batch=0)
    with pytest.raises(ValueError, match="cuda_graph: needs device cuda"):
        JointIDRestorer(tiny, cuda_graph=True)
    with pytest.raises(TypeError, match="JointID or an OnnxJointID"):
        JointIDRestorer("model.pt")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="CUDA is not available"):
            JointIDRestorer(tiny, device="cuda")


def test_restore_tensor_validates_input(tiny):
    r = JointIDRestorer(tiny)
    with pytest.raises(ShapeError, match=r"\(B, 3, H, W\)"):
        r.restore_tensor(torch.zeros(1, 1, 32, 32))
    with pytest.raises(TypeError, match="float tensor"):
        r.restore_tensor(torch.zeros(1, 3, 32, 32, dtype=torch.uint8))


@pytest.mark.slow
def test_compiled_restorer_equals_eager(tiny):
    rgb = np.random.default_rng(5).random((1, 64, 96, 3), dtype=np.float32)
    ref = JointIDRestorer(tiny).restore(rgb)
    out = JointIDRestorer(tiny, compile=True).restore(rgb)
    np.testing.assert_allclose(out.images, ref.images, rtol=0, atol=1e-5)
    np.testing.assert_allclose(out.depth_m, ref.depth_m, rtol=0, atol=1e-4)


needs_cuda = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs CUDA")


@pytest.mark.gpu
@needs_cuda
def test_cuda_matches_cpu_and_cuda_graph_matches_eager(tiny, underwater):
    model = copy.deepcopy(tiny)  # the restorer moves its model to the device in place
    cpu = JointIDRestorer(tiny).restore(underwater[None])
    cuda = JointIDRestorer(model, device="cuda").restore(underwater[None])
    np.testing.assert_allclose(cuda.images, cpu.images, rtol=0, atol=5e-3)  # cuDNN may use TF32
    np.testing.assert_allclose(cuda.depth_m, cpu.depth_m, rtol=0, atol=5e-2)
    eager = JointIDRestorer(model, device="cuda", precision="bf16")
    graph = JointIDRestorer(model, device="cuda", precision="bf16", cuda_graph=True)
    x = torch.from_numpy(underwater).permute(2, 0, 1)[None].cuda()
    for frame in (x, x.flip(-1), x * 0.5):  # replays must use the new frame, not the captured one
        a, b = eager.restore_tensor(frame), graph.restore_tensor(frame)
        torch.testing.assert_close(b.images, a.images, rtol=0, atol=2e-3)
        torch.testing.assert_close(b.depth_m, a.depth_m, rtol=0, atol=3e-2)


@pytest.mark.gpu
@needs_cuda
def test_refine_on_cuda_runs_the_torch_twins_on_the_device(tiny, underwater):
    from murk.restore_ops import affine_transfer as at

    x = torch.from_numpy(underwater).permute(2, 0, 1)[None].cuda()
    net = JointIDRestorer(copy.deepcopy(tiny), device="cuda").restore_tensor(x).images  # refine 0
    out = JointIDRestorer(copy.deepcopy(tiny), device="cuda", refine=0.125).restore_tensor(x).images
    assert out.device.type == "cuda"
    i_hwc, r_hwc = underwater.astype(np.float32), net[0].permute(1, 2, 0).cpu().numpy()
    want = at.affine_transfer(i_hwc, r_hwc, 38, step=3)
    want = at.guard_particle_removal(i_hwc, want, r_hwc, 0.04, at.guard_size_px(240, 300))
    np.testing.assert_allclose(out[0].permute(1, 2, 0).cpu().numpy(), np.clip(want, 0, 1), rtol=0, atol=1e-5)


@pytest.mark.gpu
@needs_cuda
def test_lite_blend_on_cuda_runs_lite_on_the_device(tiny_ckpt, underwater):
    x = torch.from_numpy(underwater).permute(2, 0, 1)[None].cuda()
    blended = create("jointid", checkpoint=tiny_ckpt, device="cuda")
    assert blended.right.name == "lite" and blended.right.device.type == "cuda"
    alone = create("jointid", checkpoint=tiny_ckpt, device="cuda", lite_blend=0).restore_tensor(x).images
    lite = blended.right.restore_tensor(x).images
    out = blended.restore_tensor(x).images
    assert out.device.type == "cuda"
    torch.testing.assert_close(out, 0.5 * alone + 0.5 * lite, rtol=0, atol=1e-5)


@pytest.mark.gpu
@needs_cuda
def test_bf16_base_model_stays_within_40_db_of_fp32(underwater):
    torch.manual_seed(0)
    model = build_jointid("base").eval()
    rgb = np.ascontiguousarray(np.pad(underwater, ((0, 48), (0, 212), (0, 0)), mode="reflect")[:288, :512])
    fp32 = JointIDRestorer(model, device="cuda").restore(rgb[None])
    bf16 = JointIDRestorer(model, device="cuda", precision="bf16").restore(rgb[None])
    mse = float(np.mean((fp32.images - bf16.images) ** 2))
    assert 10 * np.log10(1 / mse) >= 40


def test_refine_transfers_the_restoration_onto_the_input_and_leaves_depth(tiny_ckpt, underwater):
    from murk.restore_ops.affine_transfer import (
        affine_transfer,
        guard_particle_removal,
        guard_size_px,
        transfer_radius_px,
        transfer_step,
    )

    x = underwater[None].astype(np.float32)
    plain = create("jointid", checkpoint=tiny_ckpt, refine=0.0, lite_blend=0, exposure="network").restore(x)
    default = create("jointid", checkpoint=tiny_ckpt, lite_blend=0, exposure="network").restore(x)  # blend: next
    radius = transfer_radius_px(240, 300, 0.125)
    assert (radius, transfer_step(radius)) == (38, 3)  # the fast guided filter's subsample: every third pixel
    transfer = affine_transfer(x[0], plain.images[0], radius, 1e-4, step=3)
    guarded = guard_particle_removal(x[0], transfer, plain.images[0], 0.04, guard_size_px(240, 300))
    # The default: refine=0.125 with the particle guard at 0.04.
    np.testing.assert_allclose(default.images[0], np.clip(guarded, 0, 1), atol=1e-6)
    refined = create(
        f"jointid?refine=0.125,refine_eps=0.001,refine_guard=0,lite_blend=0,exposure=network,checkpoint={tiny_ckpt}"
    ).restore(x)
    expected = np.clip(affine_transfer(x[0], plain.images[0], radius, 1e-3, step=3), 0, 1)
    np.testing.assert_allclose(refined.images[0], expected, atol=1e-6)
    assert np.abs(refined.images - plain.images).max() > 0.01  # it does change the output
    assert np.array_equal(refined.depth_m, plain.depth_m) and np.array_equal(default.depth_m, plain.depth_m)
    with pytest.raises(ValueError, match=r"refine: expected a fraction of the long side in \[0, 1\]"):
        create("jointid", checkpoint=tiny_ckpt, refine=2.0)
    with pytest.raises(ValueError, match="refine_eps: expected > 0"):
        create("jointid", checkpoint=tiny_ckpt, refine=0.1, refine_eps=0.0)
    with pytest.raises(ValueError, match=r"refine_guard: expected a top-hat luma in \[0, 1\)"):
        create("jointid", checkpoint=tiny_ckpt, refine_guard=-0.1)


def test_lite_blend_averages_the_shipped_lite_in_and_leaves_depth(tiny, tiny_ckpt, underwater):
    from murk.data import shipped_lite_weights
    from murk.enhance.run import weights_line

    x = np.stack([underwater, 0.6 * underwater]).astype(np.float32)
    alone_restorer, blended = (
        create("jointid", checkpoint=tiny_ckpt, lite_blend=0),
        create("jointid", checkpoint=tiny_ckpt),
    )
    alone = alone_restorer.restore(x)
    lite = create("lite").restore(x).images  # the shipped lite, as the default blends it
    default = blended.restore(x)  # lite_blend 0.5
    # The weights an output came from: Joint-ID's file, and the lite blended in
    assert weights_used(alone_restorer).weights == str(tiny_ckpt)
    used = weights_used(blended)
    assert used.weights == str(tiny_ckpt) and used.blended_weights == str(shipped_lite_weights())
    assert weights_used(alone_restorer).blended_weights is None
    assert weights_line(blended, shipped=False) == (
        f"jointid weights: {tiny_ckpt}; with lite's restoration blended in (lite_blend 0.5): {shipped_lite_weights()}"
    )
    np.testing.assert_allclose(default.images, 0.5 * alone.images + 0.5 * lite, atol=1e-6)
    assert np.abs(default.images - alone.images).max() > 0.01  # it does change the output
    assert np.array_equal(default.depth_m, alone.depth_m)  # depth is Joint-ID's alone
    quarter = create(f"jointid?lite_blend=0.25,checkpoint={tiny_ckpt}").restore(x).images
    np.testing.assert_allclose(quarter, 0.75 * alone.images + 0.25 * lite, atol=1e-6)
    np.testing.assert_allclose(create("jointid", checkpoint=tiny_ckpt, lite_blend=1).restore(x).images, lite, atol=1e-6)
    for bad in (-0.1, 1.5):
        with pytest.raises(ValueError, match=r"lite_blend: expected a number in \[0.0, 1.0\], got"):
            create("jointid", checkpoint=tiny_ckpt, lite_blend=bad)
    with pytest.raises(ValueError, match=r"lite_blend: expected a number in \[0.0, 1.0\], got nan"):
        create("jointid", checkpoint=tiny_ckpt, lite_blend=float("nan"))
    with pytest.raises(ValueError, match=r"option lite_blend: expected float, got True"):
        create("jointid", checkpoint=tiny_ckpt, lite_blend=True)
    with pytest.raises(ValueError, match=r"option lite_blend: expected float, got '0.5x'"):
        create(f"jointid?lite_blend=0.5x,checkpoint={tiny_ckpt}")
    with pytest.raises(TypeError, match=r"lite_blend"):  # the blend is the spec's, not the network restorer's
        JointIDRestorer(copy.deepcopy(tiny), lite_blend=0.5)


def test_refine_on_a_batch_equals_frame_by_frame_and_leaves_the_inputs_alone(tiny_ckpt, underwater):
    from murk.enhance.refine import RefineSettings, refine_restoration

    frames = np.stack([underwater, underwater[::-1].copy(), 0.5 * underwater]).astype(np.float32)
    r = create("jointid", checkpoint=tiny_ckpt)
    batch = r.restore(frames).images
    for i in range(3):
        np.testing.assert_allclose(batch[i], r.restore(frames[i : i + 1]).images[0], atol=2e-5)
    images = torch.from_numpy(frames).permute(0, 3, 1, 2)
    enhanced = (images * 0.7 + 0.2).contiguous()
    before = (images.clone(), enhanced.clone())
    out = refine_restoration(images, enhanced, RefineSettings(0.125))
    assert out.shape == images.shape and torch.equal(images, before[0]) and torch.equal(enhanced, before[1])
    assert refine_restoration(images, enhanced, RefineSettings(0.0)) is enhanced  # off: untouched


def test_the_jointid_preset_gives_the_bytes_of_the_blend_it_replaced(tiny_ckpt, underwater):
    """``jointid`` (the preset ``jointid_net|lite@lite_blend``) computes what JointIDRestorer computed inside itself
    before the blend moved into the spec grammar: ``torch.lerp`` of the refined network output and ``lite``'s
    restoration of the same input tensor, bit for bit; ``lite_blend=0`` is ``jointid_net`` itself."""
    x = np.stack([underwater, 0.6 * underwater]).astype(np.float32)
    net, lite = create("jointid_net", checkpoint=tiny_ckpt), create("lite")
    for w in (0.5, 0.3):
        xt = torch.from_numpy(x).permute(0, 3, 1, 2).to(torch.float32)
        with torch.inference_mode():
            enhanced = net.restore_tensor(xt).images
            before = torch.lerp(enhanced, lite.restore_tensor(xt).images, w).permute(0, 2, 3, 1).numpy()
        now = create(f"jointid?lite_blend={w}", checkpoint=tiny_ckpt).restore(x)
        assert np.array_equal(now.images, before)
        assert np.array_equal(now.depth_m, net.restore(x).depth_m)
    alone = create("jointid?lite_blend=0", checkpoint=tiny_ckpt)
    assert isinstance(alone, JointIDRestorer) and np.array_equal(alone.restore(x).images, net.restore(x).images)


def _mean_luma(images: np.ndarray) -> np.ndarray:
    return (images * np.array([0.299, 0.587, 0.114], np.float32)).sum(-1).mean(axis=(1, 2))


def test_exposure_keeps_the_balanced_inputs_mean_luma_and_nothing_else(tiny, tiny_ckpt, underwater):
    from murk.restore_ops.balance import color_balance

    balanced = copy.deepcopy(tiny)
    balanced.input_balance_pct = 1.0
    x = np.stack([underwater, 0.5 * underwater]).astype(np.float32)
    own = JointIDRestorer(balanced).restore(x)  # the default of a restorer built around a network: its own output
    kept = JointIDRestorer(balanced, exposure="input").restore(x)
    target = _mean_luma(np.stack([color_balance(f, 1.0, 1.0) for f in x]))
    k = target / _mean_luma(own.images)
    assert np.abs(k - 1).min() > 0.01  # the tiny network changes the exposure: there is something to keep
    # One gain per frame: what the step adds is exactly that gain (clamped), and the mean luma is the input's
    np.testing.assert_allclose(kept.images, np.clip(own.images * k[:, None, None, None], 0, 1), atol=2e-6)
    np.testing.assert_allclose(_mean_luma(kept.images), target, atol=2e-3)  # the clamp takes a little back
    assert np.array_equal(kept.depth_m, own.depth_m)
    # The method keeps it by default; exposure=network is the network's own
    net = create("jointid", checkpoint=tiny_ckpt, lite_blend=0, refine=0.0)
    assert net.keep_exposure
    own_net = create("jointid", checkpoint=tiny_ckpt, lite_blend=0, refine=0.0, exposure="network").restore(x)
    np.testing.assert_array_equal(own_net.images, JointIDRestorer(tiny).restore(x).images)
    with pytest.raises(ValueError, match="exposure: expected input or network"):
        JointIDRestorer(tiny, exposure="camera")  # type: ignore[arg-type]


def test_an_export_without_its_balance_recorded_runs_with_the_networks_exposure(tmp_path, tiny):
    pytest.importorskip("onnxruntime")
    import onnx

    from murk.models.jointid.onnx_export import BALANCE_KEY, export_onnx

    path = export_onnx(tiny, tmp_path / "tiny.onnx")
    graph = onnx.load(str(path))
    kept = [p for p in graph.metadata_props if p.key != BALANCE_KEY]
    del graph.metadata_props[:]
    graph.metadata_props.extend(kept)
    old = tmp_path / "old.onnx"
    onnx.save(graph, str(old))
    restorer = create("jointid", checkpoint=old, lite_blend=0)
    assert not restorer.keep_exposure
    with pytest.raises(ValueError, match=r"exposure: input needs to know the balance .*old\.onnx.*murk export"):
        create("jointid", checkpoint=old, lite_blend=0, exposure="input")


def test_depth_pass_size_keeps_the_aspect_in_multiples_of_32_and_runs_only_at_half_the_pixels():
    from murk.enhance.jointid_restorer import depth_pass_size

    assert depth_pass_size(480, 640, 76800) == (256, 320)
    assert depth_pass_size(360, 480, 76800) == (256, 320)  # 2.25x the area: still a pass
    assert depth_pass_size(480, 360, 76800) == (320, 256)
    assert depth_pass_size(720, 1280, 76800) == (192, 384)
    assert depth_pass_size(1080, 1920, 76800) == (192, 384)
    assert depth_pass_size(240, 320, 76800) is None  # no larger than the area: its own pass
    assert depth_pass_size(128, 160, 76800) is None  # smaller frames are never enlarged
    assert depth_pass_size(480, 640, 0) is None  # off
    # A pass with more than half the frame's pixels would cost nearly another full pass: none (the review's cases)
    for hw in ((256, 320), (288, 288), (241, 320), (300, 400), (30, 4000), (1, 100_000)):
        assert depth_pass_size(*hw, 76800) is None, hw
    assert depth_pass_size(3, 900, 1024) is None


def test_depth_area_gives_a_larger_frame_the_depth_of_a_pass_at_that_area(tiny, tiny_ckpt, underwater):
    import torch.nn.functional as F

    from murk.enhance.choices import DEFAULT_DEPTH_AREA_PX

    x = np.stack([underwater, 0.6 * underwater]).astype(np.float32)  # 240x300: 72,000 pixels
    full = JointIDRestorer(tiny).restore(x)
    small = JointIDRestorer(tiny, depth_area=64 * 64).restore(x)
    # The enhanced image is the full pass's, bit for bit; the depth is the pass on the frame shrunk to 64x64
    np.testing.assert_array_equal(small.images, full.images)
    shrunk = F.interpolate(torch.from_numpy(x).permute(0, 3, 1, 2), size=(64, 64), mode="area")
    low = JointIDRestorer(tiny).restore(shrunk.permute(0, 2, 3, 1).numpy()).depth_m
    assert low.shape == (2, 64, 64)
    expected = F.interpolate(torch.from_numpy(low)[:, None], size=(240, 300), mode="bilinear", align_corners=False)
    np.testing.assert_allclose(small.depth_m, expected[:, 0].numpy(), rtol=1e-6, atol=1e-6)
    assert small.depth_m.shape == full.depth_m.shape
    assert np.abs(small.depth_m - full.depth_m).max() > 1e-3  # another pass, another map
    # A frame no larger than the area keeps its own pass's depth
    same = JointIDRestorer(tiny, depth_area=240 * 300).restore(x)
    np.testing.assert_array_equal(same.depth_m, full.depth_m)
    # The methods default to it; 0 turns it off
    assert create("jointid_net", checkpoint=tiny_ckpt).depth_area == DEFAULT_DEPTH_AREA_PX
    off = create("jointid", checkpoint=tiny_ckpt, depth_area=0, lite_blend=0, refine=0.0, exposure="network")
    np.testing.assert_array_equal(off.restore(x).depth_m, full.depth_m)
    for bad in (-1, True, 2.5):
        with pytest.raises(ValueError, match=r"depth_area: expected 0 \(off\) or a number of pixels"):
            JointIDRestorer(tiny, depth_area=bad)  # type: ignore[arg-type]
    # The depth pass runs whole when the frame runs in tiles: each tile would see a part of the scene
    tiled = JointIDRestorer(tiny, depth_area=64 * 64, tile=64, overlap=16).restore(x)
    np.testing.assert_allclose(tiled.depth_m, small.depth_m, rtol=0, atol=1e-6)
    # ... and it runs the network's depth alone (JointID.depth), not the whole forward
    counted = copy.deepcopy(tiny)
    calls: list[tuple[int, ...]] = []
    whole_depth = counted.depth
    counted.depth = lambda t: calls.append(tuple(t.shape)) or whole_depth(t)  # type: ignore[method-assign]
    again = JointIDRestorer(counted, depth_area=64 * 64).restore(x)
    assert calls == [(2, 3, 64, 64)]
    whole = JointIDRestorer(tiny, depth_area=64 * 64)
    whole._depth_backend = None  # the whole forward as the pass: what ONNX, compile and cuda_graph run
    np.testing.assert_array_equal(again.depth_m, whole.restore(x).depth_m)
    calls.clear()
    JointIDRestorer(counted, depth_area=64 * 64, batch=1).restore(x)
    assert calls == [(1, 3, 64, 64)] * 2


def test_depth_area_leaves_the_methods_images_alone(tmp_path, tiny):
    """With the method's defaults (refine, the exposure step) and a network that balances its input, the images
    of a frame that gets a depth pass are those without it, byte for byte: only the depth changes."""
    balanced = copy.deepcopy(tiny)
    balanced.input_balance_pct = 1.0
    ckpt = save_checkpoint(balanced, tmp_path / "balanced.pt")
    x = (0.15 + 0.6 * np.random.default_rng(5).random((1, 400, 500, 3))).astype(np.float32)  # 200,000 pixels
    on = create("jointid_net", checkpoint=ckpt).restore(x)
    off = create("jointid_net", checkpoint=ckpt, depth_area=0).restore(x)
    np.testing.assert_array_equal(on.images, off.images)
    assert on.depth_m.dtype == np.float32 and on.depth_m.shape == (1, 400, 500)
    assert np.abs(on.depth_m - off.depth_m).max() > 1e-3


def test_depth_area_runs_the_onnx_export_as_the_torch_network(tmp_path, tiny, underwater):
    pytest.importorskip("onnxruntime")
    from murk.models.jointid.onnx_export import export_onnx

    path = export_onnx(tiny, tmp_path / "tiny.onnx")
    x = underwater[None].astype(np.float32)
    ref = JointIDRestorer(tiny, exposure="input", depth_area=64 * 64).restore(x)
    out = create("jointid_net", checkpoint=path, refine=0.0, depth_area=64 * 64).restore(x)
    np.testing.assert_allclose(out.images, ref.images, rtol=0, atol=2e-5)
    np.testing.assert_allclose(out.depth_m, ref.depth_m, rtol=0, atol=1e-4)
