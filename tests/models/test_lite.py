"""The lite network: folding equals the training form, the parameter budget, identity at initialisation,
ONNX round trip, determinism, checkpoints, and errors."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
import torch

from murk.errors import InputFileError, ShapeError
from murk.models.lite.blocks import RepConv, fold_rep_conv
from murk.models.lite.checkpoint import (
    is_lite_checkpoint,
    load_lite,
    read_lite_checkpoint,
    save_lite_checkpoint,
    slim_lite_checkpoint,
)
from murk.models.lite.network import (
    LiteConfig,
    LiteNet,
    build_lite,
    guided_upsample,
    parameter_count,
    reparameterize,
    work_image,
    work_size,
)

MAX_INFERENCE_PARAMETERS = 100_000
"""The issue's budget for the folded network."""


def _trained_like(variant: str = "base", seed: int = 0) -> LiteNet:
    """A network whose batch norms and head are far from their initial values (as after training), so that
    folding is tested on every term: running statistics, affine BN parameters, identity branches, the head."""
    torch.manual_seed(seed)
    net = build_lite(variant)
    g = torch.Generator().manual_seed(seed)
    with torch.no_grad():
        for m in net.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.copy_(torch.rand(m.num_features, generator=g) - 0.5)
                m.running_var.copy_(0.5 + 1.5 * torch.rand(m.num_features, generator=g))
                m.weight.copy_(0.5 + torch.rand(m.num_features, generator=g))
                m.bias.copy_(0.4 * torch.rand(m.num_features, generator=g) - 0.2)
        net.head.weight.copy_(0.3 * torch.randn(net.head.weight.shape, generator=g))
        net.head.bias.copy_(0.1 * torch.randn(net.head.bias.shape, generator=g))
    return net.eval()


@pytest.mark.parametrize("variant", ["base", "wide", "tiny"])
@pytest.mark.parametrize("hw", [(64, 96), (48, 80), (16, 16)])
def test_folded_equals_training_form_in_eval_mode(variant: str, hw: tuple[int, int]) -> None:
    net = _trained_like(variant)
    folded = reparameterize(net)
    assert folded.folded and not net.folded
    assert not any(isinstance(m, RepConv) for m in folded.modules())
    x = torch.rand(2, 3, *hw, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        ref, out = net(x), folded(x)
        coeffs_ref, coeffs = net.coefficients(x), folded.coefficients(x)
        bilinear_ref = _with_config(net, guide_radius=0, folded=False)(x)
        bilinear = _with_config(folded, guide_radius=0)(x)
    assert (ref - x).abs().max() > 1e-2  # not the identity: the comparison means something
    # The convolutional network (what folding changes) within 1e-5, with either upsampling. The guided
    # upsampling's a = cov / (var + eps) amplifies float differences of the coefficients by up to
    # 1 / (2 sqrt(eps)) = 16x, hence the looser bound on its output. `wide` (twice the channels, longer sums)
    # gets 2e-5 on the coefficients and 16x that on the output: it reaches 8.6e-6 and 7.5e-5 here.
    coeff_bound, out_bound = (2e-5, 3.2e-4) if variant == "wide" else (1e-5, 5e-5)
    assert (coeffs - coeffs_ref).abs().max().item() <= coeff_bound
    assert (bilinear - bilinear_ref).abs().max().item() <= coeff_bound
    assert (out - ref).abs().max().item() <= out_bound


def test_one_block_folds_exactly_with_and_without_identity() -> None:
    g = torch.Generator().manual_seed(3)
    for cin, cout, stride in ((8, 8, 1), (8, 16, 2), (3, 8, 1)):
        block = RepConv(cin, cout, stride)
        with torch.no_grad():
            for bn in (block.bn3, block.bn1, block.bn_id):
                if bn is not None:
                    bn.running_mean.copy_(torch.randn(cout, generator=g))
                    bn.running_var.copy_(torch.rand(cout, generator=g) + 0.1)
                    bn.weight.copy_(torch.randn(cout, generator=g))
        block.eval()
        assert (block.bn_id is not None) == (cin == cout and stride == 1)
        x = torch.randn(2, cin, 12, 20, generator=g)
        with torch.no_grad():
            assert (fold_rep_conv(block)(x) - block(x)).abs().max().item() <= 1e-5


def test_parameter_budget() -> None:
    net = build_lite("base")
    folded = reparameterize(net.eval())
    assert parameter_count(folded) <= MAX_INFERENCE_PARAMETERS
    assert parameter_count(folded) == 90_566  # pinned: the shipped architecture (docs/models.md)
    assert parameter_count(reparameterize(build_lite("wide").eval())) == 489_542  # docs/train.md: "490 K"
    assert parameter_count(net) > parameter_count(folded)  # the training form carries the extra branches


def test_a_fresh_network_is_the_identity() -> None:
    """The head starts at zero: gain 1 and offset 0 everywhere, so training starts from the input."""
    net = build_lite("base").eval()
    x = torch.rand(1, 3, 32, 48)
    with torch.no_grad():
        assert torch.allclose(net(x), x, atol=1e-6)


def test_output_is_deterministic() -> None:
    a, b = _trained_like("base", seed=5), _trained_like("base", seed=5)
    x = torch.rand(1, 3, 48, 64, generator=torch.Generator().manual_seed(2))
    with torch.no_grad():
        ya, yb = reparameterize(a)(x), reparameterize(b)(x)
        again = reparameterize(a)(x)
    assert torch.equal(ya, yb) and torch.equal(ya, again)


def test_every_parameter_gets_a_gradient() -> None:
    torch.manual_seed(0)
    net = build_lite("tiny").train()
    with torch.no_grad():
        net.head.weight.normal_(std=0.1)  # a zero head blocks the gradient to everything before it
    x = torch.rand(2, 3, 32, 32)
    (net(x) - x.flip(-1)).square().mean().backward()
    missing = [n for n, p in net.named_parameters() if p.grad is None or not torch.isfinite(p.grad).all()]
    assert not missing
    assert all(p.grad.abs().sum() > 0 for p in net.parameters())


def test_output_bounds_follow_the_config() -> None:
    """Gain in [exp(-g), exp(g)], offset in [-o, o], however extreme the head."""
    net = build_lite("tiny").eval()
    with torch.no_grad():
        net.head.bias.copy_(torch.tensor([100.0, -100.0, 0.0, 100.0, -100.0, 0.0]))
        c = net.coefficients(torch.rand(1, 3, 32, 32))
    g, o = net.config.max_log_gain, net.config.max_offset
    assert torch.allclose(c[:, 0], torch.full_like(c[:, 0], float(torch.exp(torch.tensor(g)))), rtol=1e-4)
    assert torch.allclose(c[:, 1], torch.full_like(c[:, 1], float(torch.exp(torch.tensor(-g)))), rtol=1e-4)
    assert torch.allclose(c[:, 3], torch.full_like(c[:, 3], o))
    assert torch.allclose(c[:, 4], torch.full_like(c[:, 4], -o))


def test_errors() -> None:
    net = build_lite("tiny")
    with pytest.raises(ShapeError, match="multiples of 16"):
        net(torch.rand(1, 3, 30, 32))
    with pytest.raises(ShapeError, match=r"\(B, 3, H, W\)"):
        net(torch.rand(1, 4, 32, 32))
    with pytest.raises(ValueError, match="variant: expected one of base, wide, tiny"):
        build_lite("small")
    with pytest.raises(ValueError, match="widths"):
        LiteConfig(widths=(8, 0, 16))
    with pytest.raises(ValueError, match=r"config: unknown key\(s\) depth; allowed: blocks, "):
        LiteConfig.from_dict({"depth": 3})
    with pytest.raises(TypeError, match="expected a LiteNet"):
        reparameterize(torch.nn.Conv2d(3, 3, 1))
    assert isinstance(build_lite("tiny"), LiteNet)


# ------------------------------------------------------------------------------------- working resolution


def test_work_size_keeps_the_training_area_and_the_aspect() -> None:
    area = LiteConfig().work_area_px
    assert area == 128 * 160
    assert work_size(128, 160, area) is None and work_size(96, 128, area) is None  # small frames: themselves
    assert work_size(480, 640, area) == (128, 160)
    assert work_size(240, 320, area) == (128, 160)
    assert work_size(720, 1280, area) == (112, 192)
    assert work_size(1080, 1920, area) == (112, 192)
    assert work_size(4000, 20, area) == (2016, 16)  # at least one multiple of 16 per side
    assert work_size(480, 640, 0) is None


def test_a_large_frame_is_seen_at_the_training_scale() -> None:
    """A frame and the same frame at twice the size give the same working image, hence the same coefficients:
    the output at twice the size, reduced back, equals the output at the first size (up to the bilinear
    upsampling of smooth coefficient maps)."""
    net = reparameterize(_trained_like("base"))
    x = torch.rand(1, 3, 256, 320, generator=torch.Generator().manual_seed(3))
    x = torch.nn.functional.avg_pool2d(x, 5, 1, 2, count_include_pad=False)  # some spatial structure
    x2 = torch.nn.functional.interpolate(x, scale_factor=2, mode="nearest")
    w1, w2 = work_image(x, net.config.work_area_px), work_image(x2, net.config.work_area_px)
    assert w1.shape == (1, 3, 128, 160) and torch.allclose(w1, w2, atol=1e-6)
    with torch.no_grad():
        y, y2 = net(x), net(x2)
        assert y2.shape == x2.shape
        assert (torch.nn.functional.avg_pool2d(y2, 2) - y).abs().mean() < 2e-3
        bilinear = _with_config(net, guide_radius=0)
        direct = torch.nn.functional.interpolate(
            net.coefficients(work_image(x, net.config.work_area_px)), size=(256, 320), mode="bilinear"
        )
        assert torch.allclose(bilinear(x), direct[:, 3:] + direct[:, :3] * x, atol=1e-6)
        # Without a working resolution the same network sees the large frame at its own scale: another output.
        assert (_with_config(net, work_area_px=0)(x2) - y2).abs().mean() > 1e-2


def _with_config(net: LiteNet, folded: bool = True, **changes: object) -> LiteNet:
    """A copy of ``net`` (folded or training form, as ``net``) with the same weights and other (weight-free)
    configuration values."""
    other = LiteNet(LiteConfig.from_dict({**net.config.to_dict(), **changes}), folded=folded)
    other.load_state_dict(net.state_dict())
    return other.eval()


def test_guided_upsampling_follows_the_frame_edges() -> None:
    """Coefficients that are a linear function of the (pooled) luma are reproduced at full resolution with the
    frame's sharp edge; bilinear upsampling smears the step over several pixels."""
    guide = torch.full((1, 1, 64, 64), 0.2)
    guide[..., 30:] = 0.8  # a vertical edge, off the 4-pixel grid
    guide_lo = torch.nn.functional.avg_pool2d(guide, 4)
    coeffs = torch.cat([1.0 + 2.0 * guide_lo, 0.5 - guide_lo], dim=1)
    exact = torch.cat([1.0 + 2.0 * guide, 0.5 - guide], dim=1)
    guided = guided_upsample(coeffs, guide_lo, guide, radius=2, eps=1e-8)
    bilinear = guided_upsample(coeffs, guide_lo, guide, radius=0, eps=1e-3)
    assert (guided - exact).abs().max() < 1e-3
    assert (bilinear - exact).abs().max() > 0.3
    flat = guided_upsample(torch.full((1, 2, 16, 16), 0.7), guide_lo, guide, radius=2, eps=1e-3)
    assert torch.allclose(flat, torch.full_like(flat, 0.7), atol=1e-6)  # constant maps stay constant
    with pytest.raises(ValueError, match="guide_radius"):
        LiteConfig(guide_radius=-1)
    with pytest.raises(ValueError, match="guide_eps"):
        LiteConfig(guide_eps=0.0)


def test_a_large_frame_of_any_size_needs_no_padding() -> None:
    net = _trained_like("tiny")
    x = torch.rand(2, 3, 150, 211)
    with torch.no_grad():
        assert net(x).shape == x.shape
    with pytest.raises(ShapeError, match="working image"):
        net(x, torch.rand(2, 3, 40, 50))
    with pytest.raises(ValueError, match="work_area_px"):
        LiteConfig(work_area_px=100)


# --------------------------------------------------------------------------------------------- checkpoints


def test_checkpoint_round_trip_loads_weights_only(tmp_path: Path) -> None:
    net = _trained_like("tiny")
    path = save_lite_checkpoint(net, tmp_path / "lite.pt", step=3, metrics={"val_psnr": 20.5})
    obj = torch.load(path, weights_only=True)
    assert obj["format"] == "murk.lite" and obj["variant"] == "tiny"
    state, info = read_lite_checkpoint(path)
    assert info.variant == "tiny" and info.meta["step"] == 3
    assert all(torch.equal(state[k], v) for k, v in net.state_dict().items())
    folded, training = load_lite(path), load_lite(path, fold=False)
    assert folded.folded and not training.folded and not training.training
    x = torch.rand(1, 3, 32, 48)
    with torch.no_grad():
        assert (folded.coefficients(x) - net.coefficients(x)).abs().max() <= 1e-5
        assert (folded(x) - net(x)).abs().max() <= 5e-5 and torch.equal(training(x), net(x))  # see the fold test
    assert is_lite_checkpoint(path)
    slim = slim_lite_checkpoint(path, tmp_path / "slim.pt", source="test")
    assert read_lite_checkpoint(slim)[1].meta == {"source": "test"}


def test_checkpoint_errors(tmp_path: Path) -> None:
    from murk.models.jointid import build_jointid, save_checkpoint

    with pytest.raises(ValueError, match="folded"):
        save_lite_checkpoint(reparameterize(build_lite("tiny").eval()), tmp_path / "f.pt")
    jid = save_checkpoint(build_jointid("tiny"), tmp_path / "jointid.pt")
    assert not is_lite_checkpoint(jid) and not is_lite_checkpoint(tmp_path / "missing.pt")
    with pytest.raises(InputFileError, match="--method jointid"):
        read_lite_checkpoint(jid)
    with pytest.raises(InputFileError, match="not found"):
        load_lite(tmp_path / "missing.pt")
    bad = save_lite_checkpoint(build_lite("tiny"), tmp_path / "bad.pt")
    obj = torch.load(bad, weights_only=True)
    obj["config"]["widths"] = [8, 8, 32]
    torch.save(obj, bad)
    with pytest.raises(InputFileError, match="shape mismatches"):
        read_lite_checkpoint(bad)


# ---------------------------------------------------------------------------------------------------- ONNX


def test_onnx_round_trip(tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime")
    onnx = pytest.importorskip("onnx")
    from murk.models.lite.graph import restore_reference
    from murk.models.lite.onnx_export import OnnxLite, export_lite_onnx

    net = _trained_like("base")
    path = export_lite_onnx(net, tmp_path / "lite.onnx")
    model = onnx.load(str(path))
    ops = {n.op_type for n in model.graph.node}
    for node in model.graph.node:
        ops |= {n.op_type for a in node.attribute if a.type == a.GRAPH for n in a.g.node}
    assert not ops & {"DepthToSpace", "SpaceToDepth", "ConvTranspose"}  # no sub-pixel grids
    assert "BatchNormalization" not in ops  # exported folded
    runner = OnnxLite(path, threads=1)
    folded = reparameterize(net)
    folded.keep_exposure = True  # an export keeps the input's exposure by default, as the lite method does
    assert runner.work_area_px == net.config.work_area_px and runner.keep_exposure  # stored in the metadata
    # dynamic height and width: small frames of any size (their own working image, padded in the graph) and
    # large ones (a downsampled working image)
    for hw in ((64, 96), (48, 80), (96, 32), (37, 53), (150, 211), (480, 640)):
        x = torch.rand(2, 3, *hw, generator=torch.Generator().manual_seed(hw[0]))
        with torch.no_grad():
            assert (runner(x) - restore_reference(folded, x)).abs().max().item() <= 1e-4
    with pytest.raises(ValueError, match="opset: expected >= 13"):
        export_lite_onnx(net, tmp_path / "x.onnx", opset=12)
    from murk.enhance.lite_restorer import LiteRestorer

    own = OnnxLite(export_lite_onnx(net, tmp_path / "own.onnx", keep_exposure=False), threads=1)
    folded.keep_exposure = False
    x = torch.rand(1, 3, 150, 211, generator=torch.Generator().manual_seed(5))
    with torch.no_grad():
        assert not own.keep_exposure and (own(x) - restore_reference(folded, x)).abs().max().item() <= 1e-4
        assert (own(x) - runner(x)).abs().max().item() > 1e-3  # the step changes this network's output
    assert LiteRestorer(own).keep_exposure is False and LiteRestorer(runner, exposure="input").keep_exposure
    with pytest.raises(ValueError, match=r"exposure: .*own\.onnx was exported with exposure network.*--exposure input"):
        LiteRestorer(own, exposure="input")

    with pytest.raises(ValueError, match="temporal: needs the torch network"):
        LiteRestorer(runner, temporal=0.5)
    # Exports of earlier murks are refused with what to do: the first one (one input, frames of multiples of 16,
    # no murk.format metadata) and the second one (a second input, the working image).
    old = tmp_path / "old.onnx"
    older = tmp_path / "older.onnx"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(folded, (torch.zeros(1, 3, 32, 32),), str(older), dynamo=False, input_names=["image"],
                          output_names=["enhanced"])  # fmt: skip
        torch.onnx.export(folded, (torch.zeros(1, 3, 32, 32), torch.zeros(1, 3, 16, 16)), str(old), dynamo=False,
                          input_names=["image", "work"], output_names=["enhanced"])  # fmt: skip
    with pytest.raises(InputFileError, match=r"no 'murk\.format'.*export it again"):
        OnnxLite(older)
    with pytest.raises(InputFileError, match=r"the working image.*export it again"):
        OnnxLite(old)


def test_keep_exposure_scales_the_whole_restoration_to_the_inputs_mean_luma() -> None:
    import torch.nn.functional as F

    from murk.models.lite.network import POOL, apply_maps, keep_exposure
    from murk.restore_ops.exposure import MAX_EXPOSURE_GAIN, mean_luma_torch

    net = reparameterize(_trained_like("base", seed=2))
    assert not net.keep_exposure  # off in training
    x = 0.1 + 0.6 * torch.rand(2, 3, 128, 160, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        own = net(x)
        maps = net.maps(x)
        kept_maps = keep_exposure(maps, x)
        net.keep_exposure = True
        kept = net(x)
    assert torch.equal(net.maps(x), kept_maps)
    k = (kept_maps / maps).flatten(1)
    assert torch.allclose(k, k[:, :1].expand_as(k), rtol=1e-5)  # one gain per frame, on every map
    k = k[:, 0]
    assert (k - 1).abs().min() > 0.01  # this network changes the exposure
    torch.testing.assert_close(kept, own * k[:, None, None, None], rtol=1e-5, atol=1e-6)  # before the clamp
    # The gain is the pooled input's mean luma over that of the restoration at the maps' resolution (clamped)
    lo = F.avg_pool2d(x, POOL)
    have = mean_luma_torch(apply_maps(maps, lo).clamp(0, 1))
    torch.testing.assert_close(k * have, mean_luma_torch(lo), atol=1e-5, rtol=0)
    # The gain is bounded: a black frame is not blown up
    with torch.no_grad():
        dark = keep_exposure(maps, torch.zeros_like(x))
    assert torch.equal(dark, maps / MAX_EXPOSURE_GAIN)
