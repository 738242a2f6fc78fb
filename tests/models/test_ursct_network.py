"""URSCT-SESR contract: exact names/shapes/parameter counts, float64 golden forwards (reduced-depth end to end
and the four release-depth encoder taps), the batch coupling of the official code vs murk's per-image grids,
buffers rebuilt per size, gradients, errors.

Provenance of the pinned values: ``tests/data/ursct_sesr_{state_dict,golden_forward}.json``, produced by the
official URSCT (``model/URSCT_model.py``, ``configs/Enh_opt.yaml``) and copied from the spec folder
(``docs/spec/baselines.md``); weights from the shared fill rule (``murk.models.golden``; learnable parameters
only), filled in float32, then ``.double()``; input built in float32, then cast to float64. Tolerance 2e-6.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from murk.errors import ShapeError
from murk.models.golden import fill_golden_, golden_input
from murk.models.ursct_sesr import URSCT, URSCTConfig, build_ursct
from murk.models.ursct_sesr.network import (
    BUFFER_SUFFIXES,
    TAP_NAMES,
    UNUSED_PARAMETERS,
    relative_position_index,
    shift_mask,
)

TOL = 2e-6


@pytest.fixture(scope="module")
def spec(tests_data) -> dict:
    return json.loads((tests_data / "ursct_sesr_state_dict.json").read_text())


@pytest.fixture(scope="module")
def golden(tests_data) -> dict:
    return json.loads((tests_data / "ursct_sesr_golden_forward.json").read_text())


def _golden_model(depths: tuple[int, int, int, int]) -> URSCT:
    """As the fixture was made: float32 model, filled (rounded to float32), then converted to float64."""
    model = URSCT(URSCTConfig(depths=depths)).eval()
    return fill_golden_(model).double()


def _count(m: torch.nn.Module) -> int:
    return sum(p.numel() for p in m.parameters())


def _module(model: torch.nn.Module, name: str) -> torch.nn.Module:
    for part in name.split("."):
        model = model[int(part)] if part.isdigit() else getattr(model, part)
    return model


def test_names_shapes_dtypes_equal_the_official_fixture(spec):
    with torch.device("meta"):
        model = URSCT()
    params = [(k, list(v.shape), str(v.dtype).removeprefix("torch.")) for k, v in model.named_parameters()]
    buffers = [(k, list(v.shape), str(v.dtype).removeprefix("torch.")) for k, v in model.named_buffers()]
    assert len(params) == spec["num_learnable_parameter_keys"] == 899 and len(buffers) == spec["num_buffer_keys"] == 84
    assert sorted(params + buffers) == [(k, s, d) for k, s, d in spec["entries"]]
    # buffers are rebuilt per input size, so murk's state dict holds the learnable tensors only
    assert sorted(model.state_dict()) == sorted(k for k, _, _ in params)
    assert all(k.endswith(BUFFER_SUFFIXES) for k, _, _ in buffers)
    assert sum(v.numel() for v in model.buffers()) == spec["num_buffer_elements"]


def test_parameter_counts_match_the_spec(spec):
    with torch.device("meta"):
        model = URSCT()
    assert _count(model) == 11_362_057 == spec["num_params"]
    for name, n in spec["params_per_top_level_module"].items():
        if name != "pos_drop":  # a parameter-free dropout of the official model, not built here
            assert _count(_module(model, name)) == n, name
    for i, c in enumerate((32, 64, 128, 256)):  # one Swin block = 12C^2 + 43C + 1800
        assert _count(model.layers[i].blocks[0]) == 12 * c * c + 43 * c + 1800
    assert _count(model.layers[0].downsample) == 8 * 32 * 32 + 8 * 32
    assert _count(model.layers_up[0]) == int(4.25 * 256 * 256) + 256 + 2


def test_builds_from_a_plain_dict_config():
    model = build_ursct(config={"img_size": 128, "depths": [1, 1, 1, 1]}, init=False)
    assert isinstance(model, URSCT) and model.config.img_size == 128


def test_golden_end_to_end_reduced_depth_float64(golden):
    ref = golden["main_end_to_end_depth2"]
    model = _golden_model((2, 2, 2, 2))
    x = golden_input((1, 3, 256, 256)).double()
    with torch.no_grad():
        y = model(x)
    stats = ref["output_stats"]
    assert y.dtype == torch.float64 and list(y.shape) == stats["shape"]
    flat = y.numpy().ravel()
    np.testing.assert_allclose(flat[::17], ref["output"]["values"], rtol=0, atol=TOL)
    np.testing.assert_allclose(y[0, :, 120:136, 120:136].numpy().ravel(), ref["output_crop"]["values"], atol=TOL)
    assert float(y.mean()) == pytest.approx(stats["mean"], abs=1e-9)
    assert float(y.std()) == pytest.approx(stats["std"], abs=1e-9)
    assert float(y.abs().sum()) == pytest.approx(stats["abs_sum"], abs=1e-4)
    assert float(y.min()) == pytest.approx(stats["min"], abs=TOL) and float(y.max()) == pytest.approx(
        stats["max"], abs=TOL
    )
    np.testing.assert_allclose(y.mean(dim=(0, 2, 3)).numpy(), ref["channel_mean"], atol=1e-9)


def test_golden_release_depth_encoder_taps_float64(golden):
    ref = golden["release_config_taps"]
    model = _golden_model((8, 8, 8, 8))
    with torch.no_grad():
        taps = model.encoder_taps(golden_input((1, 3, 256, 256)).double())
    assert tuple(taps) == TAP_NAMES
    for name, tap in taps.items():
        r = ref["taps"][name]
        assert list(tap.shape) == r["shape"], name
        np.testing.assert_allclose(tap.numpy().ravel()[::97], r["values"], rtol=0, atol=TOL, err_msg=name)
        assert float(tap.mean()) == pytest.approx(r["mean"], abs=1e-9), name
        assert float(tap.std()) == pytest.approx(r["std"], abs=1e-8), name
        assert float(tap.min()) == pytest.approx(r["min"], abs=TOL) and float(tap.max()) == pytest.approx(
            r["max"], abs=TOL
        )


def _block0(model: URSCT, x: torch.Tensor) -> torch.Tensor:
    return model.layers[0].blocks[0](model.patch_embed(model.conv_first(x)))


def test_batch_coupling_official_quirk_vs_murk_per_image_grids(golden):
    """The official conv over the window grid couples the last window of image 0 with the first of image 1;
    ``batch_coupled=True`` reproduces exactly the fixture's changed tokens, murk's default changes none."""
    native = _golden_model((2, 2, 2, 2))
    coupled = URSCT(URSCTConfig(depths=(2, 2, 2, 2), batch_coupled=True)).double().eval()
    coupled.load_state_dict(native.state_dict())
    a = golden_input((1, 3, 256, 256)).double()
    i, j = np.meshgrid(np.arange(256), np.arange(256), indexing="ij")
    b = torch.from_numpy(np.stack([np.cos(j / 7 + c) * np.sin(i / 5 - c) for c in range(3)])[None]).double()
    fixture = golden["batch_coupling"]
    with torch.no_grad():
        alone = _block0(native, a)[0]
        for position, key in ((0, "as_first_of_two"), (1, "as_second_of_two")):
            pair = torch.cat([a, b]) if position == 0 else torch.cat([b, a])
            torch.testing.assert_close(_block0(native, pair)[position], alone, rtol=0, atol=1e-12)  # murk: none
            change = (_block0(coupled, pair)[position] - alone).abs().amax(dim=-1)
            tokens = torch.nonzero(change > 1e-9).flatten()
            rows, cols = tokens // 128, tokens % 128
            ref = fixture[key]
            assert len(tokens) == ref["changed_tokens"] == 64
            assert [int(rows.min()), int(rows.max())] == ref["rows"] and [int(cols.min()), int(cols.max())] == ref[
                "cols"
            ]
            assert float(change.max()) > 1.0  # O(1) like the fixture's 3.3 (its other input is not specified)


def test_buffers_follow_the_formulas_and_other_sizes_are_rebuilt():
    idx = relative_position_index(8)
    assert idx.shape == (64, 64) and int(idx[0, 0]) == 7 * 15 + 7 and int(idx[0, 63]) == 0 and int(idx.max()) == 224
    m = shift_mask(16, 8, 4)
    assert m.shape == (4, 64, 64) and torch.all(m[0] == 0) and float(m[3].min()) == -100.0
    small = URSCT(URSCTConfig(img_size=128, embed_dim=8, depths=(2, 2, 2, 2))).eval()
    assert small.layers[3].blocks[1].attn_mask is None  # stage 3 at 8x8 tokens: one unshifted window
    big = URSCT(URSCTConfig(img_size=256, embed_dim=8, depths=(2, 2, 2, 2))).eval()
    big.load_state_dict(small.state_dict())
    x = torch.rand(1, 3, 256, 256, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        torch.testing.assert_close(small(x), big(x), rtol=0, atol=1e-5)  # masks built on demand == buffers
        assert small(torch.rand(2, 3, 128, 128)).shape == (2, 3, 128, 128)


def test_every_used_parameter_gets_a_gradient():
    torch.manual_seed(0)
    model = build_ursct(URSCTConfig(img_size=128, embed_dim=8, depths=(2, 1, 1, 1)))
    y = model(torch.rand(2, 3, 128, 128))
    assert torch.isfinite(y).all()
    y.square().mean().backward()
    for name, p in model.named_parameters():
        if name in UNUSED_PARAMETERS:
            assert p.grad is None, name
        else:
            assert p.grad is not None and torch.isfinite(p.grad).all(), name


def test_official_initialisation():
    torch.manual_seed(0)
    model = build_ursct(URSCTConfig(img_size=128, depths=(1, 1, 1, 1)))
    fc1 = model.layers[2].blocks[0].mlp.fc1
    assert abs(float(fc1.weight.detach().std()) - 0.02) < 0.002 and not fc1.bias.detach().any()
    assert float(model.prelu.weight.detach()) == pytest.approx(0.25)
    table = model.layers[0].blocks[0].attn.relative_position_bias_table
    assert abs(float(table.detach().std()) - 0.02) < 0.005


def test_errors():
    model = URSCT(URSCTConfig(img_size=128, embed_dim=8, depths=(1, 1, 1, 1)))
    with pytest.raises(ShapeError, match=r"square input whose side is a multiple of 128, got 128x256"):
        model(torch.zeros(1, 3, 128, 256))
    with pytest.raises(ShapeError, match=r"multiple of 128, got 200x200"):
        model(torch.zeros(1, 3, 200, 200))
    with pytest.raises(ShapeError, match=r"\(B, 3, S, S\)"):
        model(torch.zeros(1, 1, 128, 128))
    with pytest.raises(TypeError, match=r"torch\.Tensor"):
        model(np.zeros((1, 3, 128, 128)))
    with pytest.raises(ValueError, match="img_size: expected a positive multiple of 128"):
        URSCTConfig(img_size=200)
    with pytest.raises(ValueError, match=r"config: unknown key\(s\) window; allowed: .*depths"):
        build_ursct({"window": 7})
