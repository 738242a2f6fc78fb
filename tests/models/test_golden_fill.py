"""The ONE golden fill rule (murk.models.golden), checked on its own against every fixture's ``fill_check``.

Provenance: ``tests/data/{udaformer,ursct_sesr}_golden_forward.json`` (copied from the project's spec folder,
``docs/spec/baselines.md``): the first values of parameters k = 0, 1, 2 and the last, and the float64 sum of
every filled value, as produced by the official models filled with this rule. The rule enumerates the
learnable parameters only (URSCT-SESR's buffers take no index).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch

from murk.models.golden import fill_golden_, golden_input, golden_keys, golden_values
from murk.models.jointid import golden as jointid_golden
from murk.models.udaformer import UDAformer
from murk.models.ursct_sesr import URSCT, URSCTConfig


def _meta(cls, *args):
    with torch.device("meta"):
        return cls(*args)


CASES = {
    "udaformer": (lambda: _meta(UDAformer), "fill_check", "fill_param_sum_float64"),
    "ursct_sesr": (lambda: _meta(URSCT), "fill_check", ("release_config_taps", "fill_param_sum_float64")),
    "ursct_sesr_depth2": (
        lambda: _meta(URSCT, URSCTConfig(depths=(2, 2, 2, 2))),
        None,
        ("main_end_to_end_depth2", "fill_param_sum_float64"),
    ),
}


def _get(doc: dict, path) -> object:
    for p in (path,) if isinstance(path, str) else path:
        doc = doc[p]
    return doc


@pytest.mark.parametrize("case", sorted(CASES))
def test_fill_rule_reproduces_the_fixture_checks(tests_data, case):
    build, check_key, sum_path = CASES[case]
    golden = json.loads((tests_data / f"{case.removesuffix('_depth2')}_golden_forward.json").read_text())
    model = build()
    params = dict(model.named_parameters())
    keys = golden_keys(model)
    if check_key:
        check = golden[check_key]
        assert check["num_filled_parameters"] == len(keys)
        for ex in check["examples"]:
            k = ex["k"] if ex["k"] >= 0 else len(keys) + ex["k"]
            assert keys[k] == ex["key"] and list(params[keys[k]].shape) == ex["shape"]
            values = golden_values(k, tuple(ex["shape"]), ex["key"]).ravel()
            np.testing.assert_allclose(
                values[: len(ex["first_values_float64"])], ex["first_values_float64"], atol=1e-15
            )
    total = sum(float(golden_values(k, tuple(params[key].shape), key).sum()) for k, key in enumerate(keys))
    assert total == pytest.approx(_get(golden, sum_path), abs=1e-9)


def test_fill_counts_learnable_parameters_only_and_keeps_buffers():
    model = URSCT(URSCTConfig(img_size=128, embed_dim=8, depths=(2, 1, 1, 1)))
    buffers = {k: v.clone() for k, v in model.named_buffers()}
    assert any(k.endswith("attn_mask") for k in buffers) and any(k.endswith("position_index") for k in buffers)
    fill_golden_(model)
    for k, v in model.named_buffers():
        assert torch.equal(v, buffers[k]), k  # untouched, no index taken
    keys = golden_keys(model)
    assert not any(k.endswith(("attn_mask", "relative_position_index")) for k in keys)
    first = dict(model.named_parameters())[keys[0]]
    expected = torch.from_numpy(golden_values(0, tuple(first.shape), keys[0])).float()
    assert torch.equal(first.detach(), expected)
    # the consequences the spec lists: 1-D weight -> 1 + 0.1u, relative tables (2-D) -> u*sqrt(3/8)
    prelu = model.prelu.weight
    assert 0.9 <= float(prelu.detach()) <= 1.1
    table = model.layers[0].blocks[0].attn.relative_position_bias_table.detach()
    assert float(table.abs().max()) <= math.sqrt(3 / 8) + 1e-6 and float(table.abs().max()) > 0.5


def test_jointid_keeps_its_golden_helpers():
    """Joint-ID's module re-exports the shared rule; its input is the (1, 3, 64, 96) golden input."""
    assert jointid_golden.fill_golden_ is fill_golden_ and jointid_golden.golden_values is golden_values
    assert torch.equal(jointid_golden.golden_input(), golden_input((1, 3, 64, 96)))
    x = golden_input((1, 3, 5, 9))
    assert float(x[0, 1, 2, 3]) == pytest.approx(math.sin(3 / 7 + 1) * math.cos(2 / 5 - 1), abs=1e-7)
