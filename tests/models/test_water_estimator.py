"""The water estimator (murk.models.water): the numpy network equals training's torch network, the file round trip,
clear errors, and the shipped weights."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from torch import nn

from murk.data import shipped_water_weights
from murk.errors import InputFileError
from murk.models.water import WaterEstimator, load_water_estimator, water_from_outputs
from murk.restore_ops.water import FEATURES, visibility_m, water_features
from murk.train.water import _water_torch, water_network


def _estimator(seed: int = 0) -> tuple[WaterEstimator, nn.Sequential]:
    torch.manual_seed(seed)
    net = water_network()
    layers = [m for m in net if isinstance(m, nn.Linear)]
    arrays = {"mu": np.zeros(FEATURES), "sd": np.ones(FEATURES)}
    for k, layer in enumerate(layers, 1):
        arrays[f"w{k}"] = layer.weight.detach().numpy().T.astype(np.float64)
        arrays[f"b{k}"] = layer.bias.detach().numpy().astype(np.float64)
    return WaterEstimator(arrays), net


def test_numpy_network_equals_the_torch_network() -> None:
    est, net = _estimator()
    x = np.random.default_rng(0).normal(size=(5, FEATURES)).astype(np.float32)
    with torch.no_grad():
        out_t = net(torch.from_numpy(x))
        veil_t, att_t = _water_torch(out_t)
    np.testing.assert_allclose(est.outputs(x), out_t.numpy(), atol=1e-5)
    veil, att = water_from_outputs(est.outputs(x))
    np.testing.assert_allclose(veil, veil_t.numpy(), atol=1e-5)
    np.testing.assert_allclose(att, att_t.numpy(), rtol=1e-4)


def test_estimate_is_the_network_read_on_the_features() -> None:
    est, net = _estimator(1)
    rng = np.random.default_rng(1)
    image = rng.uniform(0, 1, (30, 40, 3)).astype(np.float32)
    dist = rng.uniform(1, 5, (30, 40)).astype(np.float32)
    water = est.estimate(image, dist)
    with torch.no_grad():
        veil, att = _water_torch(net(torch.from_numpy(water_features(image, dist))[None]))
    np.testing.assert_allclose(water.veil, veil[0].numpy(), atol=1e-5)
    np.testing.assert_allclose(water.attenuation_per_m, att[0].numpy(), rtol=1e-4)
    assert water.visibility_m == pytest.approx(visibility_m(att[0].numpy()), rel=1e-4)
    assert set(water.as_dict()) == {"veil_rgb", "attenuation_per_m", "visibility_m"}


def test_save_and_load_round_trip(tmp_path: Path) -> None:
    est, _ = _estimator(2)
    path = tmp_path / "water.npz"
    WaterEstimator(est.arrays, meta={"steps": 3}).save(path)
    back = load_water_estimator(path)
    assert back.meta == {"steps": 3} and back.source == str(path)
    x = np.random.default_rng(2).normal(size=(2, FEATURES))
    np.testing.assert_allclose(back.outputs(x), est.outputs(x), atol=1e-5)


def test_bad_files_name_the_file(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="not found") as missing:
        load_water_estimator(tmp_path / "none.npz")
    assert "none.npz" in str(missing.value)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not an npz")
    with pytest.raises(InputFileError, match=r"junk\.npz"):
        load_water_estimator(junk)
    partial = tmp_path / "partial.npz"
    np.savez(partial, mu=np.zeros(FEATURES))
    with pytest.raises(InputFileError, match="needs"):
        load_water_estimator(partial)


def test_the_shipped_estimator_loads_and_records_its_training() -> None:
    est = load_water_estimator()
    assert Path(est.source) == shipped_water_weights()
    assert est.meta and est.meta["depth_method"] == "jointid_net" and est.meta["scenes"] >= 1000


def test_a_text_file_is_not_an_archive(tmp_path: Path) -> None:
    text = tmp_path / "text.npz"
    text.write_text("junk\n")
    with pytest.raises(InputFileError, match=r"not an \.npz archive"):
        load_water_estimator(text)
