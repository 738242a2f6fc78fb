"""UDAformer contract: exact names/shapes/parameter counts, golden forwards (incl. the odd-size case),
the official window packing, gradients, batch independence.

Provenance of the pinned values: ``tests/data/udaformer_{state_dict,golden_forward}.json``, produced by the
official UDAformer (class ``UFUformer``, default constructor as in ``test.py``) and copied from the spec folder
(``docs/spec/baselines.md``); the golden forward uses the shared fill rule (``murk.models.golden``).
"""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest
import torch

from murk.errors import ShapeError
from murk.models.golden import fill_golden_, golden_input
from murk.models.udaformer import UDAformer, UDAformerConfig, build_udaformer
from murk.models.udaformer.network import UNUSED_MODULES, join, pack, shifted_window_mask, unpack


@pytest.fixture(scope="module")
def golden_model() -> UDAformer:
    return fill_golden_(build_udaformer().eval())


@pytest.fixture(scope="module")
def spec(tests_data) -> dict:
    return json.loads((tests_data / "udaformer_state_dict.json").read_text())


@pytest.fixture(scope="module")
def golden(tests_data) -> dict:
    return json.loads((tests_data / "udaformer_golden_forward.json").read_text())


def _count(m: torch.nn.Module) -> int:
    return sum(p.numel() for p in m.parameters())


def test_state_dict_names_shapes_dtypes_equal_the_official_fixture(golden_model, spec):
    ours = [
        (k, list(v.shape), str(v.dtype).removeprefix("torch.")) for k, v in sorted(golden_model.state_dict().items())
    ]
    assert len(ours) == spec["num_keys"] == 206
    assert ours == [(k, s, d) for k, s, d in spec["entries"]]
    assert not list(golden_model.buffers())


def test_parameter_counts_match_the_spec(golden_model, spec):
    assert _count(golden_model) == 9_601_422 == spec["num_params"]
    for name, n in spec["params_per_top_level_module"].items():
        assert _count(getattr(golden_model, name)) == n, name
    # per-block formulas of the spec
    m = golden_model

    def catb(c: int) -> int:
        return 13 * c * c + 83 * c

    assert _count(m.encoder_level2[0]) == catb(72) and _count(m.latent[0].csa) == catb(288)
    assert _count(m.encoder_level1[0].pixel) == 33 * 36 * 36 + 110 * 36
    assert _count(m.latent[0].pixel) == 21 * 288 * 288 + 83 * 288
    assert _count(m.encoder_level1[0]) == catb(36) + 33 * 36 * 36 + 110 * 36 + 1


def test_builds_from_a_plain_dict_config():
    model = build_udaformer(config={"dim": 8, "blocks": [1, 1, 1, 1], "refinement_blocks": 1})
    assert isinstance(model, UDAformer) and model.config.dim == 8


@pytest.mark.parametrize("case", ["main_64x96", "odd_size_36x44"])
def test_golden_forward_matches_the_official_outputs(golden_model, golden, case):
    ref = golden if case == "main_64x96" else golden["extra_cases"][case]
    shape = tuple(ref["output_shape"])
    with torch.no_grad():
        y = golden_model(golden_input(shape))
    assert y.dtype == torch.float32 and tuple(y.shape) == shape
    np.testing.assert_allclose(y.numpy().ravel(), np.asarray(ref["output"]), rtol=0, atol=1e-4)
    assert float(y.double().mean()) == pytest.approx(ref["output_mean"], abs=1e-5)
    assert float(y.double().sum()) == pytest.approx(ref["output_sum"], abs=0.05)
    assert float(y.min()) == pytest.approx(ref["output_min"], abs=1e-4)
    assert float(y.max()) == pytest.approx(ref["output_max"], abs=1e-4)
    np.testing.assert_allclose(y.double().mean(dim=(0, 2, 3)).numpy(), ref["channel_mean"], atol=1e-5)


def test_no_coupling_across_the_batch(golden_model):
    """Spec: batch-2 vs batch-1 difference 0.0 in float64 (float32 BLAS differs in the last bits only)."""
    m = copy.deepcopy(golden_model).double()
    a = golden_input((1, 3, 36, 44)).double()
    b = torch.rand(1, 3, 36, 44, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    with torch.no_grad():
        alone = m(a)
        both = m(torch.cat([b, a]))
    torch.testing.assert_close(both[1:], alone, rtol=0, atol=1e-10)


def test_pack_is_the_official_channel_major_split_and_unpack_inverts_it():
    b, c, h, w = 2, 5, 20, 27  # pads to 24 x 32: nh = 3, nw = 4, L = 12
    x = torch.arange(b * c * h * w, dtype=torch.float64).view(b, c, h, w)
    p, geo = pack(x)
    assert p.shape == (b * 12, c, 8, 8)
    torch.testing.assert_close(unpack(p, geo), x, rtol=0, atol=0)
    xp = torch.nn.functional.pad(x, (0, 5, 0, 4))
    for q in (0, 7, 13, 23):
        for j in range(c):
            f = q * c + j  # tile number f = ((b*C + c)*nh + a)*nw + e
            e, a = f % 4, (f // 4) % 3
            bc = f // 12
            ib, ic = divmod(bc, c)
            torch.testing.assert_close(p[q, j], xp[ib, ic, 8 * a : 8 * a + 8, 8 * e : 8 * e + 8], rtol=0, atol=0)


def test_shift_mask_regions():
    m = shifted_window_mask(16, 24)  # 2 x 3 tiles
    assert m.shape == (6, 64, 64)
    assert torch.all(m[0] == 0)  # top-left tile: one region
    last = m[-1]  # bottom-right tile: rows 8..15 are region 1 below 13, 2 from 13 (columns 16..23 likewise)
    assert last[0, 0] == 0 and last[0, 63] == -100 and last[63, 63] == 0
    assert set(last.unique().tolist()) == {0.0, -100.0}


def test_join_pads_or_crops_floor_half_first():
    up, skip = torch.ones(1, 1, 6, 6), torch.zeros(1, 2, 5, 7)
    out = join(up, skip)  # dy = -1: crop the top row; dx = +1: 0 left, 1 right
    assert out.shape == (1, 3, 5, 7)
    assert torch.equal(out[0, 2, :, :6], torch.ones(5, 6)) and torch.equal(out[0, 2, :, 6], torch.zeros(5))


def test_every_used_parameter_gets_a_gradient_and_outputs_are_finite():
    torch.manual_seed(0)
    m = build_udaformer(UDAformerConfig(dim=8, blocks=(1, 1, 1, 1), refinement_blocks=1))
    y = m(torch.rand(2, 3, 21, 30))  # odd sizes: every padding path
    assert y.shape == (2, 3, 21, 30) and torch.isfinite(y).all()
    y.square().mean().backward()
    for name, p in m.named_parameters():
        if name.split(".")[0] in UNUSED_MODULES:
            assert p.grad is None, name
        else:
            assert p.grad is not None and torch.isfinite(p.grad).all() and p.grad.abs().sum() > 0, name


def test_zero_output_projection_returns_the_input_and_forward_is_deterministic():
    m = build_udaformer(UDAformerConfig(dim=8, blocks=(1, 1, 1, 1))).eval()
    x = torch.rand(1, 3, 17, 9, generator=torch.Generator().manual_seed(1))
    with torch.no_grad():
        assert torch.equal(m(x), m(x))
        m.output.weight.zero_()
        assert torch.equal(m(x), x)  # global residual, no activation, no clamp


def test_errors():
    m = build_udaformer(UDAformerConfig(dim=4, blocks=(1, 1, 1, 1), refinement_blocks=0))
    with pytest.raises(ShapeError, match=r"\(B, 3, H, W\).*\(1, 4, 8, 8\)"):
        m(torch.zeros(1, 4, 8, 8))
    with pytest.raises(TypeError, match=r"torch\.Tensor"):
        m(np.zeros((1, 3, 8, 8)))
    with pytest.raises(ValueError, match="dim: expected an even"):
        UDAformerConfig(dim=3)
    with pytest.raises(ValueError, match="blocks"):
        UDAformerConfig(blocks=(1, 1, 1))
    with pytest.raises(ValueError, match=r"config: unknown key\(s\) width; allowed: blocks, dim, "):
        build_udaformer({"width": 3})
    with pytest.raises(TypeError, match="UDAformerConfig"):
        build_udaformer(3)
