"""Joint-ID network contract: exact names/shapes/parameter count, golden forward, gradients, determinism."""

from __future__ import annotations

import dataclasses
import json
import math
import re

import numpy as np
import pytest
import torch

from murk.errors import ShapeError
from murk.models.jointid import (
    INPUT_MEAN,
    INPUT_STD,
    JointID,
    JointIDConfig,
    build_jointid,
    fill_golden_,
    golden_input,
    init_weights,
    normalize_input,
    normalize_input_np,
)
from murk.models.jointid.golden import golden_values
from murk.models.jointid.network import VARIANTS


@pytest.fixture(scope="module")
def base_model() -> JointID:
    """The one full-size model of this module (150M parameters; built without the init pass)."""
    torch.manual_seed(0)
    return build_jointid("base", init=False).eval()


@pytest.fixture(scope="module")
def fixture_entries(tests_data) -> list[tuple[str, list[int], str]]:
    return [tuple(e) for e in json.loads((tests_data / "jointid_state_dict.json").read_text())["entries"]]


def _count(module: torch.nn.Module) -> int:
    return sum(p.numel() for p in module.parameters())


def test_parameter_counts_match_spec(base_model):
    # Figures from docs/spec/jointid.md (counted on the official model).
    assert _count(base_model) == 150_248_900
    assert _count(base_model.depth_structure) == 72_040_017
    assert _count(base_model.depth_structure.encoder) == 39_076_032
    assert _count(base_model.depth_structure.decoder) == 32_963_985
    assert _count(base_model.enhanced_structure) == 72_040_307
    joint = sum(_count(m) for n, m in base_model.named_children() if "joint_block" in n)
    assert joint == 6_168_576


def test_state_dict_names_shapes_dtypes_equal_official_fixture(base_model, fixture_entries):
    ours = [
        (f"structure.{k}", list(v.shape), str(v.dtype).removeprefix("torch."))
        for k, v in base_model.state_dict().items()
    ]
    assert len(fixture_entries) == 2100
    assert ours == [(k, list(s), d) for k, s, d in fixture_entries]  # same names, same order, same shapes


@pytest.mark.parametrize("prefix", ["structure.", ""])
def test_fixture_state_dict_loads_strict_with_and_without_prefix(base_model, fixture_entries, prefix):
    # A state dict built from the fixture's names and shapes, each tensor filled with its index as a marker.
    state = {
        prefix + k.removeprefix("structure."): torch.full(shape, float(i))
        for i, (k, shape, _) in enumerate(fixture_entries)
    }
    result = base_model.load_state_dict(state, strict=True)
    assert not result.missing_keys and not result.unexpected_keys
    own = base_model.state_dict()
    for i, (k, _, _) in enumerate(fixture_entries):
        assert float(own[k.removeprefix("structure.")].flatten()[0]) == float(i), k


def test_golden_forward_matches_official_outputs(base_model, tests_data):
    golden = json.loads((tests_data / "jointid_golden_forward.json").read_text())
    fill_golden_(base_model)
    with torch.no_grad():
        out = base_model(golden_input())
    depth = np.asarray(golden["depth"], np.float32).reshape(golden["depth_shape"])
    enhanced = np.asarray(golden["enhanced"], np.float32).reshape(golden["enhanced_shape"])
    assert out.depth_m.shape == (1, 1, 64, 96) and out.enhanced.shape == (1, 3, 64, 96)
    np.testing.assert_allclose(out.depth_m.numpy(), depth, rtol=0, atol=1e-4)
    np.testing.assert_allclose(out.enhanced.numpy(), enhanced, rtol=0, atol=1e-4)
    assert abs(float(out.depth_m.mean()) - golden["depth_mean"]) < 1e-5


def test_every_used_parameter_gets_a_gradient(base_model):
    base_model.zero_grad(set_to_none=True)
    g = torch.Generator().manual_seed(3)
    x = normalize_input(torch.rand(1, 3, 64, 96, generator=g))
    out = base_model(x)
    (out.depth_m.mean() + out.enhanced.mean()).backward()
    unused = 0
    for name, p in base_model.named_parameters():
        if ".norm_layer_2." in name:  # the decoder LayerNorm the official ConvMix defines and never uses
            assert p.grad is None, name
            unused += p.numel()
        else:
            assert p.grad is not None, name
            assert torch.isfinite(p.grad).all(), name
    assert unused == 12_288  # spec: 12,288 parameters without gradient
    base_model.zero_grad(set_to_none=True)


def test_eval_forward_is_deterministic(base_model):
    x = normalize_input(torch.rand(2, 3, 32, 64, generator=torch.Generator().manual_seed(1)))
    with torch.no_grad():
        a = base_model(x)
        b = base_model(x)
    assert torch.equal(a.depth_m, b.depth_m) and torch.equal(a.enhanced, b.enhanced)


def test_depth_alone_is_the_forwards_depth_bit_for_bit(base_model):
    """``JointID.depth`` skips what only the enhanced image needs (the ``depth_area`` pass of the restorer runs it)."""
    tiny = build_jointid("tiny").eval()
    small = build_jointid("small").eval()  # the shipped variant: residual output, shuffle smoothing
    coloured = JointID(dataclasses.replace(VARIANTS["tiny"], global_colour=True)).eval()
    for net, hw in ((base_model, (32, 64)), (tiny, (64, 96)), (small, (64, 96)), (coloured, (64, 64))):
        x = normalize_input(torch.rand(2, 3, *hw, generator=torch.Generator().manual_seed(2)))
        with torch.no_grad():
            assert torch.equal(net.depth(x), net(x).depth_m)
    with pytest.raises(ShapeError, match=r"multiples of 32"):
        tiny.depth(torch.zeros(1, 3, 48, 64))


def _pattern(key: str) -> str:
    return re.sub(r"(block\d|_layer)\.\d+\.", r"\1.N.", key)  # block/layer indices -> N


def test_tiny_variant_has_the_same_structure():
    tiny = build_jointid("tiny")
    with torch.device("meta"):
        base = JointID()
    assert {_pattern(k) for k in tiny.state_dict()} == {_pattern(k) for k in base.state_dict()}
    assert _count(tiny) < 5_000_000
    with torch.no_grad():
        out = tiny(normalize_input(torch.rand(2, 3, 64, 96, generator=torch.Generator().manual_seed(0))))
    assert out.depth_m.shape == (2, 1, 64, 96) and out.enhanced.shape == (2, 3, 64, 96)
    assert 0 < float(out.depth_m.min()) and float(out.depth_m.max()) < 15.0  # 15 * sigmoid
    assert 0 < float(out.enhanced.min()) and float(out.enhanced.max()) < 1.0


def test_build_is_deterministic_under_a_seed():
    torch.manual_seed(5)
    a = build_jointid("tiny").state_dict()
    torch.manual_seed(5)
    b = build_jointid("tiny").state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)


@torch.no_grad()
def test_init_weights_follows_the_training_recipe():
    torch.manual_seed(0)
    m = init_weights(JointID(JointIDConfig(embed_dims=(32, 64, 160, 256), depths=(1, 1, 1, 1), decoder_blocks=1)))
    enc = m.depth_structure.encoder
    conv = enc.block2[0].mlp.dwconv.dwconv  # fan_out = 3*3*256/256 = 9
    assert abs(float(conv.weight.std()) - math.sqrt(2 / 9)) < 0.05 * math.sqrt(2 / 9)
    assert torch.equal(enc.block1[0].norm1.meta1.bias, torch.zeros(32))  # RLN meta conv overwritten: bias 0
    assert abs(float(enc.block1[0].norm1.meta1.weight.std()) - math.sqrt(2 / 32)) < 0.1
    lin = enc.block3[0].mlp.fc1
    assert abs(float(lin.weight.std()) - 0.02) < 0.001 and torch.equal(lin.bias, torch.zeros_like(lin.bias))
    dec = m.depth_structure.decoder.up_skip_conv
    bound = math.sqrt(6 / (dec.in_channels * 9 + dec.out_channels * 9))  # Xavier-uniform
    assert float(dec.weight.abs().max()) <= bound and torch.equal(dec.bias, torch.zeros_like(dec.bias))
    joint = m.decoder_de_joint_block_1.joint_layer2
    assert float(joint.bias.abs().max()) > 0  # PyTorch default init kept (non-zero bias)
    assert torch.equal(enc.block1[0].norm1.weight, torch.ones(1, 32, 1, 1))


def test_golden_values_match_an_independent_integer_implementation():
    # Provenance: the spec's hash re-computed with Python integers (no numpy), element 5 of key index 7.
    def h(i: int, k: int) -> float:
        m = 0xFFFFFFFF
        v = (i * 0x9E3779B1 + (k + 1) * 0x85EBCA77) & m
        v ^= v >> 15
        v = (v * 0x2C1B3C6D) & m
        v ^= v >> 12
        v = (v * 0x297A2D39) & m
        v ^= v >> 15
        return v / 2**32 * 2 - 1

    assert golden_values(7, (4, 3), "w")[1, 2] == pytest.approx(h(5, 7) * math.sqrt(3 / 3), abs=1e-15)
    assert golden_values(7, (6,), "a.weight")[5] == pytest.approx(1 + 0.1 * h(5, 7), abs=1e-15)
    assert golden_values(7, (6,), "a.bias")[5] == pytest.approx(0.02 * h(5, 7), abs=1e-15)


def test_forward_rejects_sizes_that_are_not_multiples_of_32():
    tiny = build_jointid("tiny")
    with pytest.raises(ShapeError, match=r"multiples of 32.*48x64"):
        tiny(torch.zeros(1, 3, 48, 64))
    with pytest.raises(ShapeError, match=r"\(B, 3, H, W\)"):
        tiny(torch.zeros(1, 4, 64, 64))
    with pytest.raises(TypeError, match=r"torch\.Tensor"):
        tiny(np.zeros((1, 3, 64, 64)))


def test_build_rejects_unknown_variants():
    with pytest.raises(ValueError, match="variant: expected one of"):
        build_jointid("huge")
    with pytest.raises(TypeError, match="variant"):
        build_jointid(3)


def test_config_round_trip_and_unknown_keys():
    cfg = JointIDConfig(decoder_blocks=2)
    assert JointIDConfig.from_dict(cfg.to_dict()) == cfg
    assert isinstance(cfg.to_dict()["embed_dims"], list)
    with pytest.raises(ValueError, match=r"config: unknown key\(s\) width; allowed: decoder_blocks, "):
        JointIDConfig.from_dict({"width": 3})


def test_normalize_input_torch_equals_numpy_twin():
    rgb = np.random.default_rng(0).random((2, 5, 7, 3), dtype=np.float32)
    t = normalize_input(torch.from_numpy(rgb).permute(0, 3, 1, 2)).permute(0, 2, 3, 1).numpy()
    np.testing.assert_allclose(t, normalize_input_np(rgb), rtol=0, atol=1e-6)
    mean_img = np.broadcast_to(np.asarray(INPUT_MEAN, np.float32), (1, 2, 2, 3))
    np.testing.assert_allclose(normalize_input_np(mean_img), 0, atol=1e-6)
    one_std = mean_img + np.asarray(INPUT_STD, np.float32)
    np.testing.assert_allclose(normalize_input_np(one_std), 1, atol=1e-5)
    with pytest.raises(ShapeError, match="H, W, 3"):
        normalize_input_np(np.zeros((4, 4, 4)))
    with pytest.raises(ShapeError, match="3, H, W"):
        normalize_input(torch.zeros(4, 4, 4))


@pytest.mark.parametrize("onnx_path", [False, True])
def test_rln_matches_the_spec_formula(monkeypatch, onnx_path):
    # Reference: the spec's RLN written out in float64 numpy (mu, sigma over (C, H, W) per sample).
    from murk.models.jointid.encoder import rln

    if onnx_path:  # the plain-reduction branch used while exporting to ONNX
        monkeypatch.setattr(torch.onnx, "is_in_onnx_export", lambda: True)
    g = torch.Generator().manual_seed(0)
    x = torch.randn(2, 12, 5, generator=g) * 3 + 1
    w, b, sw, sb, hw, hb = (torch.randn(5, generator=g) for _ in range(6))
    y, rescale, rebias = rln(
        x, w.view(1, 5, 1, 1), b.view(1, 5, 1, 1), sw.view(5, 1, 1, 1), sb, hw.view(5, 1, 1, 1), hb
    )
    xn = x.double().numpy()
    mu = xn.mean(axis=(1, 2), keepdims=True)
    sigma = np.sqrt(((xn - mu) ** 2).mean(axis=(1, 2), keepdims=True) + 1e-5)
    np.testing.assert_allclose(y.numpy(), (xn - mu) / sigma * w.numpy() + b.numpy(), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(rescale.numpy(), sigma * sw.numpy() + sb.numpy(), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(rebias.numpy(), mu * hw.numpy() + hb.numpy(), rtol=1e-5, atol=1e-6)


def test_small_variant_size_and_residual_identity() -> None:
    """'small' ships in the package (<= 10 MB in fp16) and, with a zero head, returns its input exactly."""
    from murk.models.jointid.network import RESIDUAL_EPS

    model = build_jointid("small")
    n = sum(p.numel() for p in model.parameters())
    assert n * 2 <= 10 * 2**20, n
    assert model.config.residual_output and not build_jointid("base", init=False).config.residual_output
    with torch.no_grad():
        model.enhanced_structure.decoder.linear_pred1.weight.zero_()
        model.enhanced_structure.decoder.linear_pred1.bias.zero_()
    x = torch.rand(2, 3, 64, 96, generator=torch.Generator().manual_seed(0))
    out = model(normalize_input(x)).enhanced
    torch.testing.assert_close(out, x.clamp(RESIDUAL_EPS, 1 - RESIDUAL_EPS), atol=2e-5, rtol=0)


def test_icnr_init_gives_no_subpixel_grid() -> None:
    """After icnr_init_, every conv feeding a pixel shuffle yields identical r x r sub-pixels (no grid)."""
    import torch.nn.functional as F

    from murk.models.jointid.network import icnr_init_

    model = icnr_init_(build_jointid("small"))
    dec = model.enhanced_structure.decoder
    g = torch.Generator().manual_seed(0)
    with torch.no_grad():
        y = F.pixel_shuffle(dec.up_skip_conv(torch.randn(1, dec.up_skip_conv.in_channels, 4, 4, generator=g)), 4)
        for i in range(4):
            for j in range(4):
                torch.testing.assert_close(y[..., i::4, j::4], y[..., 0::4, 0::4], rtol=0, atol=1e-6)
        y = F.pixel_shuffle(dec.up_channels_c4(torch.randn(1, dec.up_channels_c4.in_channels, 3, 3, generator=g)), 2)
        torch.testing.assert_close(y[..., 1::2, 1::2], y[..., 0::2, 0::2], rtol=0, atol=1e-6)
        assert not torch.equal(y[:, 0], y[:, 1])  # channels still differ


@pytest.mark.parametrize("r", [2, 4, 8])
def test_smooth_shuffled_removes_every_subpixel_pattern(r: int) -> None:
    """A shuffle of r*r DIFFERENT constant channels is a period-r grid; the triangle filter makes it flat
    (interior), keeps a constant map constant, and does not shift a ramp (symmetric kernel)."""
    import torch.nn.functional as F

    from murk.models.jointid.decoder import smooth_shuffled, triangle_kernel

    assert triangle_kernel(r).sum().item() == pytest.approx(1.0)
    levels = torch.randn(1, r * r, 1, 1, generator=torch.Generator().manual_seed(r))
    grid = F.pixel_shuffle(levels.expand(1, r * r, 6, 6).contiguous(), r)
    assert grid.std() > 0.1
    flat = smooth_shuffled(grid, r)
    assert flat.shape == grid.shape
    inner = flat[..., r:-r, r:-r]
    torch.testing.assert_close(inner, torch.full_like(inner, levels.mean().item()), rtol=0, atol=1e-5)
    ramp = torch.arange(6 * r, dtype=torch.float32).view(1, 1, 1, -1).expand(1, 1, 6 * r, 6 * r)
    torch.testing.assert_close(smooth_shuffled(ramp, r)[..., r:-r, r:-r], ramp[..., r:-r, r:-r], rtol=0, atol=1e-4)


def test_shuffle_smoothing_keeps_the_state_dict_and_flattens_a_flat_input() -> None:
    """shuffle_smoothing adds no parameter; on a flat grey input a random small model draws sub-pixel grids
    without it and a (nearly) flat picture with it (interior, away from the padded borders)."""
    from dataclasses import replace

    from murk.metrics.fidelity import artefact_energy
    from murk.models.jointid.network import VARIANTS, JointID

    torch.manual_seed(0)
    plain = build_jointid(replace(VARIANTS["small"], residual_output=False, shuffle_smoothing=False))
    smooth = JointID(replace(plain.config, shuffle_smoothing=True))
    assert set(smooth.state_dict()) == set(plain.state_dict())
    smooth.load_state_dict(plain.state_dict())
    x = normalize_input(torch.full((1, 3, 128, 128), 0.4))
    with torch.no_grad():
        a = plain(x).enhanced[0, :, 32:-32, 32:-32]
        b = smooth(x).enhanced[0, :, 32:-32, 32:-32]
    assert a.std() > 5 * b.std(), (a.std().item(), b.std().item())
    ea = artefact_energy(a.permute(1, 2, 0).numpy().astype(np.float32)).periodic
    eb = artefact_energy(b.permute(1, 2, 0).numpy().astype(np.float32)).periodic
    assert ea > 10 * eb, (ea, eb)


@pytest.mark.parametrize("r", [2, 4, 8])
def test_smooth_shuffled_equals_the_separable_triangle_convolution(r: int) -> None:
    import torch.nn.functional as F

    from murk.models.jointid.decoder import smooth_shuffled, triangle_kernel

    x = torch.randn(2, 3, 5 * r, 7 * r, generator=torch.Generator().manual_seed(r))
    k = triangle_kernel(r)
    ref = F.pad(x, (r - 1, r - 1, r - 1, r - 1), mode="replicate")
    ref = F.conv2d(ref, k.view(1, 1, 1, -1).expand(3, 1, 1, -1), groups=3)
    ref = F.conv2d(ref, k.view(1, 1, -1, 1).expand(3, 1, -1, 1), groups=3)
    torch.testing.assert_close(smooth_shuffled(x, r), ref, rtol=0, atol=1e-6)  # OpenCV (plain CPU inference)
    y = x.clone().requires_grad_(True)  # torch's pooling: a gradient follows
    out = smooth_shuffled(y, r)
    assert out.grad_fn is not None
    torch.testing.assert_close(out.detach(), ref, rtol=0, atol=1e-6)


def test_smooth_shuffled_takes_opencv_only_in_plain_cpu_inference(monkeypatch: pytest.MonkeyPatch) -> None:
    """The dispatch: OpenCV's twin for float32 CPU inference; torch's pooling with a gradient and under
    ``torch.compile`` (a call to OpenCV there would break the graph)."""
    import murk.models.jointid.decoder as decoder

    calls: list[int] = []
    twin = decoder._smooth_shuffled_opencv

    def spy(x: torch.Tensor, r: int) -> torch.Tensor:
        calls.append(r)
        return twin(x, r)

    monkeypatch.setattr(decoder, "_smooth_shuffled_opencv", spy)
    x = torch.rand(1, 2, 16, 24, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        plain = decoder.smooth_shuffled(x, 4)
    assert calls == [4]
    out = decoder.smooth_shuffled(x.clone().requires_grad_(True), 4)
    assert calls == [4] and out.grad_fn is not None
    compiled = torch.compile(lambda t: decoder.smooth_shuffled(t, 4), backend="eager", fullgraph=True)
    with torch.no_grad():
        torch.testing.assert_close(compiled(x), plain, rtol=0, atol=1e-6)
    assert calls == [4]


@pytest.mark.filterwarnings("ignore:`torch.jit.trace` is deprecated:DeprecationWarning")  # the ONNX exporter traces
@pytest.mark.parametrize(("shape", "r"), [((1, 2, 37, 53), 4), ((2, 4, 16, 24), 8), ((1, 8, 9, 11), 2)])
def test_smooth_shuffled_twins_agree_on_odd_sizes_and_layouts(shape: tuple[int, ...], r: int) -> None:
    """The OpenCV twin (float32 CPU inference) equals torch's pooling on any size and memory layout; bf16, a
    gradient or a trace keep torch's path."""
    from murk.models.jointid.decoder import _plain_cpu_inference, _smooth_shuffled_opencv, smooth_shuffled

    x = torch.rand(shape, generator=torch.Generator().manual_seed(sum(shape)))
    torch_path = smooth_shuffled(x.clone().requires_grad_(True), r).detach()
    for layout in (torch.contiguous_format, torch.channels_last):
        got = _smooth_shuffled_opencv(x.contiguous(memory_format=layout), r)
        torch.testing.assert_close(got, torch_path, rtol=0, atol=5e-7)
    assert _plain_cpu_inference(x)
    assert not _plain_cpu_inference(x.bfloat16())
    assert not _plain_cpu_inference(x.clone().requires_grad_(True))
    with torch.no_grad():
        assert _plain_cpu_inference(x.clone().requires_grad_(True))
    traced = torch.jit.trace(lambda t: smooth_shuffled(t, r), x)  # the torch ops are recorded, not OpenCV's
    torch.testing.assert_close(traced(x + 1), smooth_shuffled(x + 1, r), rtol=0, atol=1e-6)


def test_global_colour_head_starts_at_identity_and_maps_each_channel() -> None:
    """The head adds parameters only when asked, starts as the identity, and then applies (1 + g) * logit + b."""
    from dataclasses import replace

    from murk.models.jointid.network import RESIDUAL_EPS, VARIANTS

    torch.manual_seed(5)
    plain = build_jointid("small")
    headed = build_jointid(replace(VARIANTS["small"], global_colour=True))
    assert not [n for n in plain.state_dict() if "global_colour" in n]
    missing = headed.load_state_dict(plain.state_dict(), strict=False).missing_keys
    assert missing and all(n.startswith("global_colour_head.") for n in missing)
    x = normalize_input(torch.rand(2, 3, 64, 96, generator=torch.Generator().manual_seed(1)))
    with torch.no_grad():
        p, h = plain(x), headed(x)
        assert torch.equal(p.enhanced, h.enhanced) and torch.equal(p.depth_m, h.depth_m)
        head = headed.global_colour_head
        assert head is not None
        head.fc2.bias.copy_(torch.tensor([0.5, 0.0, -1.0, 0.2, 0.0, 0.3]))  # gains 1.5, 1, 0; offsets .2, 0, .3
        out = headed(x).enhanced
    logit = torch.logit(p.enhanced.double(), eps=RESIDUAL_EPS / 10)
    expect = torch.sigmoid(
        logit * torch.tensor([1.5, 1.0, 0.0]).view(1, 3, 1, 1).double()
        + torch.tensor([0.2, 0.0, 0.3]).view(1, 3, 1, 1).double()
    )
    torch.testing.assert_close(out.double(), expect, atol=2e-4, rtol=0)
    assert torch.allclose(out[:, 2], torch.sigmoid(torch.tensor(0.3)))  # gain 0: the offset alone
