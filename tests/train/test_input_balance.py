"""``model.input_balance_pct`` and ``data.scene_balance_pct`` (issue 27): a network trained on colour-balanced
inputs records it in its checkpoints, and every restorer of the checkpoint balances its input the same way."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from murk.cli.main import app
from murk.enhance.restorer import create
from murk.models.checkpoint_io import input_balance_of
from murk.models.jointid import build_jointid, save_checkpoint
from murk.models.jointid.checkpoint import load_checkpoint, slim_checkpoint
from murk.models.lite.checkpoint import load_lite, save_lite_checkpoint, slim_lite_checkpoint
from murk.models.lite.network import build_lite
from murk.restore_ops.balance import color_balance
from murk.train.config import DataConfig, ModelConfig
from murk.train.scenes_source import SceneDataset
from tests.train._cli import train_cli

runner = CliRunner()


def _murky(n: int = 2, h: int = 40, w: int = 56) -> np.ndarray:
    rng = np.random.default_rng(3)
    return rng.random((n, h, w, 3), dtype=np.float32) * np.float32([0.2, 0.4, 0.35]) + np.float32([0.05, 0.3, 0.3])


def test_a_lite_checkpoint_carries_the_balance_and_its_restorer_applies_it(tmp_path: Path) -> None:
    torch.manual_seed(0)
    net = build_lite("tiny")
    with torch.no_grad():
        net.head.weight.normal_(std=0.3)
    plain = save_lite_checkpoint(net, tmp_path / "plain.pt")
    net.input_balance_pct = 1.0
    balanced = save_lite_checkpoint(net, tmp_path / "balanced.pt")
    assert load_lite(balanced).input_balance_pct == 1.0 and load_lite(plain).input_balance_pct is None
    slim = slim_lite_checkpoint(balanced, tmp_path / "slim.pt", source="test")  # the shipping step keeps it
    assert load_lite(slim).input_balance_pct == 1.0
    imgs = _murky()
    pre = np.stack([color_balance(im, 1.0, 1.0) for im in imgs])
    want = create("lite", checkpoint=str(plain)).restore(pre).images
    got = create("lite", checkpoint=str(balanced)).restore(imgs).images
    np.testing.assert_allclose(got, want, atol=2e-5)
    assert np.abs(got - create("lite", checkpoint=str(plain)).restore(imgs).images).mean() > 0.02


def test_a_jointid_checkpoint_carries_the_balance_and_its_restorer_applies_it(tmp_path: Path) -> None:
    torch.manual_seed(0)
    net = build_jointid("tiny").eval()
    plain = save_checkpoint(net, tmp_path / "plain.pt")
    net.input_balance_pct = 2.0
    balanced = slim_checkpoint(save_checkpoint(net, tmp_path / "balanced.pt"), tmp_path / "slim.pt")
    assert load_checkpoint(balanced).input_balance_pct == 2.0
    imgs = _murky(1, 32, 64)
    pre = np.stack([color_balance(im, 2.0, 2.0) for im in imgs])
    # refine=0: the network's output (the transfer after it takes the raw input as its guide, not the balanced one)
    want = create("jointid", checkpoint=str(plain), refine=0.0, lite_blend=0).restore(pre)
    got = create("jointid", checkpoint=str(balanced), refine=0.0, lite_blend=0).restore(imgs)
    np.testing.assert_allclose(got.images, want.images, atol=1e-3)  # the slim copy holds fp16 weights
    assert got.depth_m is not None


def test_the_balance_is_read_from_the_training_configuration() -> None:
    assert input_balance_of({"config": {"model": {"input_balance_pct": 0.5}}}) == 0.5
    assert input_balance_of({"input_balance_pct": 1, "config": {"model": {"input_balance_pct": 0.5}}}) == 1.0
    assert input_balance_of({"config": {"model": {}}}) is None and input_balance_of({}) is None
    with pytest.raises(ValueError, match="input_balance_pct"):
        input_balance_of({"input_balance_pct": "yes"})


def test_balanced_scenes_span_the_range_in_every_channel() -> None:
    plain = SceneDataset([5], (32, 64), seed=1)[0]["clean"].numpy()
    balanced = SceneDataset([5], (32, 64), seed=1, balance_pct=0.5)[0]["clean"].numpy()
    np.testing.assert_allclose(balanced, color_balance(plain.transpose(1, 2, 0), 0.5, 0.5).transpose(2, 0, 1))
    assert all(np.percentile(balanced[c], 99) > 0.95 and np.percentile(balanced[c], 1) < 0.05 for c in range(3))


def test_bad_balance_settings_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="input_balance_pct"):
        ModelConfig(input_balance_pct=60.0)
    with pytest.raises(ValueError, match="scene_balance_pct"):
        DataConfig(source="scenes", crop_hw=(32, 64), scene_balance_pct=-1.0)


def test_murk_train_with_a_balanced_input_writes_checkpoints_that_restore_balanced(tmp_path: Path) -> None:
    cfg = {
        "model": {"kind": "lite", "variant": "tiny", "input_balance_pct": 1.0},
        "data": {
            "source": "scenes",
            "scenes_count": 6,
            "crop_hw": [32, 64],
            "workers": 0,
            "val_fraction": 0.34,
            "scene_balance_pct": 0.5,
        },
        "eval": {"every": 4, "val_batches": 1, "real": None},
        "steps": 4,
        "batch": 2,
        "log_every": 2,
    }
    train_cli(tmp_path, cfg)
    for name in ("latest.pt", "best.pt"):
        assert load_lite(tmp_path / "run" / name).input_balance_pct == 1.0
    restorer = create("lite", checkpoint=str(tmp_path / "run" / "latest.pt"))
    assert restorer.input_balance_pct == 1.0  # type: ignore[attr-defined]


@pytest.mark.parametrize("kind", ["lite", "jointid"])
def test_an_onnx_export_of_a_balanced_network_balances_inside_its_graph(kind: str, tmp_path: Path) -> None:
    """The one-input ONNX contract holds: a plain onnxruntime user feeds the frame as it is."""
    pytest.importorskip("onnxruntime")
    torch.manual_seed(0)
    if kind == "lite":
        net = build_lite("tiny")
        with torch.no_grad():
            net.head.weight.normal_(std=0.3)
        net.input_balance_pct = 1.0
        ckpt = save_lite_checkpoint(net, tmp_path / "net.pt")
    else:
        net = build_jointid("tiny").eval()
        net.input_balance_pct = 1.0
        ckpt = save_checkpoint(net, tmp_path / "net.pt")
    r = runner.invoke(app, ["export", "--checkpoint", str(ckpt), "--out", str(tmp_path / "net.onnx")])
    assert r.exit_code == 0, r.output
    method = "jointid_net" if kind == "jointid" else kind  # the network alone (jointid blends the shipped lite in)
    torch_restorer = create(method, checkpoint=str(ckpt))
    onnx_restorer = create(method, checkpoint=str(tmp_path / "net.onnx"))
    assert onnx_restorer.input_balance_pct is None  # type: ignore[attr-defined]  # not applied twice
    for h, w in [(37, 53), (96, 128), (200, 300)]:
        imgs = _murky(1, h, w)
        got, want = onnx_restorer.restore(imgs).images, torch_restorer.restore(imgs).images
        np.testing.assert_allclose(got, want, atol=1e-4 if kind == "lite" else 1e-3)  # murk export --verify's bounds


def test_in_a_video_the_balance_levels_are_averaged_with_the_temporal_weight(tmp_path: Path) -> None:
    """A per-frame balance flickers when the scene's extremes move; --temporal averages its levels as it averages
    lite's maps (frame 0 as on its own, later frames pulled towards the earlier levels)."""
    from murk.restore_ops.balance import apply_levels, balance_levels

    torch.manual_seed(0)
    net = build_lite("tiny")
    net.input_balance_pct = 1.0
    ckpt = save_lite_checkpoint(net, tmp_path / "net.pt")
    frames = _murky(2)
    frames[1] = np.clip(frames[1] * 1.3, 0, 1)  # the second frame's levels move
    smooth = create("lite", checkpoint=str(ckpt), temporal=0.8)
    plain = create("lite", checkpoint=str(ckpt))
    with smooth.sequence():
        video = [smooth.restore(f[None]).images[0] for f in frames]
    alone = [plain.restore(f[None]).images[0] for f in frames]
    np.testing.assert_allclose(video[0], alone[0], atol=1e-6)  # the first frame: nothing to average with
    assert np.abs(video[1] - alone[1]).mean() > 1e-3
    # the levels the second frame used: 0.8 of the first frame's + 0.2 of its own (the maps averaged likewise)
    lv = [balance_levels(f, 1.0, 1.0) for f in frames]
    mixed = np.float32(0.8) * lv[0] + np.float32(0.2) * lv[1]
    assert np.abs(apply_levels(frames[1], mixed) - apply_levels(frames[1], lv[1])).mean() > 1e-3
    assert np.array_equal(smooth.restore(frames[1][None]).images[0], alone[1])  # outside a video: per frame
