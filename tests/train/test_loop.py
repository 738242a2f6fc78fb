from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from murk._config import dump_yaml, merge
from murk.io import discover, read_jsonl
from murk.models.jointid import load_checkpoint, read_checkpoint
from murk.rng import derive_seed
from murk.synth.config import SynthConfig
from murk.synth.runner import run_synthesis
from murk.train.config import TrainConfig
from murk.train.loop import detect_kind, epoch_batches, train
from tests.train._rgbd import write_rgbd

TINY = {
    "model": {"variant": "tiny"},
    "data": {"crop_hw": [32, 64], "workers": 0, "val_fraction": 0.0},
    "eval": {"every": 1000, "val_batches": 1},
    "batch": 2,
    "log_every": 1,
}


@pytest.fixture(scope="module")
def synth_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small murk synth output: 4 clean images x 2 variants, 48x64."""
    root = write_rgbd(tmp_path_factory.mktemp("rgbd"))
    out = tmp_path_factory.mktemp("synth")
    sources, _ = discover(root)
    run_synthesis(sources, out, SynthConfig(variants=2))
    return out


def _config(tmp: Path, source: Path, **over: object) -> TrainConfig:
    cfg = merge(TrainConfig(), TINY)
    cfg = merge(cfg, {"data": {"source": str(source)}, "out": str(tmp)})
    return merge(cfg, dict(over))


def _params(path: Path) -> dict[str, torch.Tensor]:
    state, _ = read_checkpoint(path)
    return state


def test_loss_decreases_on_a_fixed_batch(synth_folder: Path, tmp_path: Path) -> None:
    cfg = _config(
        tmp_path, synth_folder, steps=40, batch=8, augment={"enabled": False}, optim={"lr": 1e-3, "min_lr": 1e-3}
    )
    summary = train(cfg)  # 8 samples, batch 8: the same batch every step
    losses = [r["loss"] for r in read_jsonl(tmp_path / "log.jsonl") if r["kind"] == "train"]
    assert len(losses) == 40 and summary.steps_done == 40
    assert np.mean(losses[-5:]) < 0.8 * np.mean(losses[:5])
    assert all(np.isfinite(losses))


def test_resume_equals_uninterrupted(synth_folder: Path, tmp_path: Path) -> None:
    full = _config(tmp_path / "full", synth_folder, steps=6)
    train(full)
    part = _config(tmp_path / "part", synth_folder, steps=6)
    train(part, stop_after=3)
    assert read_checkpoint(tmp_path / "part" / "latest.pt")[1].meta["step"] == 3
    train(part, resume=True)
    a, b = _params(tmp_path / "full" / "latest.pt"), _params(tmp_path / "part" / "latest.pt")
    assert all(torch.equal(a[k], b[k]) for k in a)
    la = [r["loss"] for r in read_jsonl(tmp_path / "full" / "log.jsonl") if r["kind"] == "train"]
    lb = [r["loss"] for r in read_jsonl(tmp_path / "part" / "log.jsonl") if r["kind"] == "train"]
    assert la == lb  # steps 1-3 from the first invocation, 4-6 from the resumed one: identical losses
    with pytest.raises(ValueError, match="nothing to resume"):
        train(_config(tmp_path / "empty", synth_folder, steps=2), resume=True)
    assert not (tmp_path / "empty").exists()  # refused before anything was written
    from murk.models.jointid import slim_checkpoint  # weights only: no optimiser state, no step

    (tmp_path / "slim").mkdir()
    slim_checkpoint(tmp_path / "full" / "latest.pt", tmp_path / "slim" / "latest.pt")
    with pytest.raises(ValueError, match=r"has no optimizer and no step .* weights only"):
        train(_config(tmp_path / "slim", synth_folder, steps=2), resume=True)


def test_a_run_folder_is_neither_overwritten_nor_resumed_with_other_settings(
    synth_folder: Path, tmp_path: Path
) -> None:
    run = tmp_path / "run"
    cfg = _config(run, synth_folder, steps=4, batch=4)
    first = train(cfg)
    log_before = (run / "log.jsonl").read_bytes()
    with pytest.raises(ValueError, match=r"run: holds an earlier run \(latest\.pt\); pass --resume"):
        train(cfg)  # a new run into the same folder would replace its checkpoints and mix its log
    with pytest.raises(ValueError, match=r"was trained with other settings \(batch 4 -> 2\)"):
        train(merge(cfg, {"batch": 2}), resume=True)
    assert (run / "log.jsonl").read_bytes() == log_before
    # Reporting settings may change; a finished run resumed again keeps its last loss (and summary.json is JSON).
    again = train(merge(cfg, {"log_every": 1}), resume=True)
    assert again.steps_done == 4 and again.last_loss == first.last_loss and np.isfinite(again.last_loss)
    doc = json.loads((run / "summary.json").read_text(), parse_constant=lambda c: pytest.fail(f"{c} in JSON"))
    assert doc["last_loss"] == first.last_loss


def test_checkpoint_loads_for_inference_and_eval_metrics(synth_folder: Path, tmp_path: Path) -> None:
    cfg = _config(
        tmp_path,
        synth_folder,
        steps=2,
        data={"val_fraction": 0.25},
        eval={
            "every": 2,
            "real": str(Path(__file__).resolve().parents[1] / "data" / "metric_edge_cases"),
            "real_max": 2,
            "real_max_side": 64,
        },
    )
    s = train(cfg)
    assert {"val_psnr", "val_ssim", "val_silog", "real_uiqm", "real_uciqe"} <= set(s.last_eval)
    assert s.best["metric"] == "val_psnr" and (tmp_path / "best.pt").exists()
    model = load_checkpoint(tmp_path / "best.pt")
    out = model(torch.rand(1, 3, 32, 64))
    assert out.depth_m.shape == (1, 1, 32, 64)
    doc = json.loads((tmp_path / "summary.json").read_text())
    assert doc["steps_done"] == 2 and "variant: tiny" in (tmp_path / "config.yaml").read_text()
    assert (doc["command"], doc["processed"], doc["skipped"], doc["failed"]) == ("train", 2, 0, 0)
    from murk._config import load_yaml

    assert load_yaml(TrainConfig, tmp_path / "config.yaml") == cfg  # the run's config.yaml reproduces it


def test_a_jointid_trains_on_layout_distance_data_and_scores_no_depth_there(tmp_path: Path) -> None:
    """``murk synth --depth-from layout`` data has no depth target (all invalid): validation scores the images and
    leaves depth out, where it used to stop the run at the first evaluation."""
    import cv2
    from typer.testing import CliRunner

    from murk.cli.main import app

    photos = tmp_path / "photos"
    photos.mkdir()
    rng = np.random.default_rng(0)
    for i in range(4):
        assert cv2.imwrite(str(photos / f"p{i}.png"), rng.integers(0, 256, (48, 64, 3), dtype=np.uint8))
    r = CliRunner().invoke(
        app, ["synth", str(photos), str(tmp_path / "lay"), "--variants", "1", "--depth-from", "layout", "-q"]
    )
    assert r.exit_code == 0, r.output
    cfg = _config(tmp_path / "run", tmp_path / "lay", steps=2, data={"val_fraction": 0.5}, eval={"every": 1})
    s = train(cfg)
    assert "val_psnr" in s.last_eval and not any(k in s.last_eval for k in ("val_abs_rel", "val_silog"))


def test_a_bad_eval_real_folder_stops_the_run_before_the_first_step(synth_folder: Path, tmp_path: Path) -> None:
    from murk.errors import InputFileError

    with pytest.raises(InputFileError, match=r"eval\.real .*not a folder"):
        train(_config(tmp_path / "a", synth_folder, steps=2, eval={"every": 1, "real": str(tmp_path / "nope")}))
    assert not (tmp_path / "a").exists()  # nothing written
    junk = tmp_path / "junk"
    junk.mkdir()
    (junk / "x.png").write_bytes(b"not a png")
    with pytest.raises(InputFileError, match=r"none of its 1 images can be read"):
        train(_config(tmp_path / "j", synth_folder, steps=2, eval={"every": 1, "real": str(junk)}))
    real = tmp_path / "real"
    real.mkdir()
    (real / "bad.jpg").write_bytes(b"\xff\xd8 not a jpeg")
    assert cv2_write(real / "good.png")
    s = train(_config(tmp_path / "b", synth_folder, steps=2, eval={"every": 1, "real": str(real)}))
    assert s.last_eval["real_images"] == 1.0 and s.failed == 1  # the bad image recorded, the run finished
    (record,) = read_jsonl(tmp_path / "b" / "errors.jsonl")
    assert record["input"] == str(real / "bad.jpg") and "left out of the real-image scores" in record["error"]


def test_evaluation_runs_without_autograd(synth_folder: Path, tmp_path: Path, monkeypatch) -> None:
    """Validation keeps no graph: with one, every batch's scores held its activations alive (GPU memory)."""
    from murk.train import networks

    grad_seen: list[bool] = []
    real_run = networks.run_network

    def spy(*args, **kwargs):
        grad_seen.append(torch.is_grad_enabled())
        return real_run(*args, **kwargs)

    monkeypatch.setattr(networks, "run_network", spy)
    train(_config(tmp_path, synth_folder, steps=1, data={"val_fraction": 0.25}, eval={"every": 1}))
    assert grad_seen == [True, False]  # the training step with autograd, the one validation batch without


def cv2_write(path: Path) -> bool:
    import cv2

    return bool(cv2.imwrite(str(path), np.random.default_rng(1).integers(0, 256, (40, 56, 3), dtype=np.uint8)))


def test_epoch_batches_partition_and_shuffle() -> None:
    b0 = epoch_batches(20, 3, epoch=0, seed=1, rank=0, world=2)
    b1 = epoch_batches(20, 3, epoch=0, seed=1, rank=1, world=2)
    flat0, flat1 = [i for b in b0 for i in b], [i for b in b1 for i in b]
    assert len(b0) == len(b1) == 3 and not set(flat0) & set(flat1)
    assert epoch_batches(20, 3, 1, 1, 0, 2) != b0 and epoch_batches(20, 3, 0, 1, 0, 2) == b0


def test_data_kind_detection(synth_folder: Path, tmp_path: Path, small_rgbd: Path) -> None:
    assert detect_kind(str(synth_folder)) == "synth"
    assert detect_kind(str(synth_folder / "train.txt")) == "list"
    assert detect_kind(str(small_rgbd)) == "rgbd"
    assert detect_kind("scenes:50") == "scenes"
    with pytest.raises(ValueError, match="neither a 'murk synth' folder"):
        detect_kind(str(tmp_path))
    with pytest.raises(ValueError, match="fewer than batch 64"):
        train(_config(tmp_path / "x", synth_folder, steps=1, batch=64))


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_ddp_two_gloo_processes_keep_replicas_identical(synth_folder: Path, tmp_path: Path) -> None:
    cfg = _config(tmp_path / "ddp", synth_folder, steps=3, batch=2)
    (tmp_path / "c.yaml").write_text(dump_yaml(cfg))
    cmd = [
        sys.executable,
        "-m",
        "torch.distributed.run",
        "--nproc_per_node",
        "2",
        "--master_port",
        str(_free_port()),
        "-m",
        "murk",
        "train",
        "--config",
        str(tmp_path / "c.yaml"),
        "-q",
    ]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads((tmp_path / "ddp" / "summary.json").read_text())
    sums = doc["replica_checksums"]
    assert len(sums) == 2 and sums[0] == sums[1]  # both ranks hold the same weights after 3 steps
    assert "world_size: 2" in (tmp_path / "ddp" / "config.yaml").read_text()
    assert doc["steps_done"] == 3


def test_unused_parameters_are_exactly_those_without_gradient() -> None:
    from murk.models.jointid import build_jointid, unused_parameter_names

    torch.manual_seed(0)
    model = build_jointid("tiny")
    out = model(torch.rand(1, 3, 32, 64))
    (out.depth_m.mean() + out.enhanced.mean()).backward()
    no_grad = {n for n, p in model.named_parameters() if p.grad is None}
    assert no_grad == set(unused_parameter_names(model)) and no_grad


def test_scenes_source_trains_and_matches_murk_scenes(tmp_path: Path) -> None:
    from murk.scenes import render_scene, sample_scene
    from murk.train.scenes_source import SceneDataset, render_size

    ds = SceneDataset(range(3, 6), (96, 128), seed=5)
    s = ds[1]
    assert s["clean"].shape == (3, 96, 128) and s["index"] == 4
    rgb, dist = render_scene(sample_scene(derive_seed(5, 4)), (128, 96))  # scene 4 of 'murk scenes --seed 5'
    np.testing.assert_array_equal(s["clean"].permute(1, 2, 0).numpy(), rgb)
    np.testing.assert_array_equal(s["depth"][0].numpy(), dist)
    assert render_size((288, 512)) == (512, 384) and render_size((96, 128)) == (128, 96)
    cfg = merge(
        merge(TrainConfig(), TINY),
        {
            "data": {"source": "scenes:6", "crop_hw": [64, 96], "val_fraction": 0.2},
            "out": str(tmp_path),
            "steps": 2,
            "eval": {"every": 2},
        },
    )
    summary = train(cfg)
    assert summary.steps_done == 2 and "val_psnr" in summary.last_eval


@pytest.mark.parametrize("head", ["depth", "enhance"])
def test_head_parameters_feed_only_their_own_output(head: str) -> None:
    from murk.models.jointid import VARIANTS, JointID, depth_head_parameter_names, enhance_head_parameter_names

    torch.manual_seed(0)
    model = JointID(replace(VARIANTS["tiny"], global_colour=True))
    names = (depth_head_parameter_names if head == "depth" else enhance_head_parameter_names)(model)
    own, other = ("depth_m", "enhanced") if head == "depth" else ("enhanced", "depth_m")
    getattr(model(torch.rand(1, 3, 32, 64)), other).mean().backward()
    assert names and all(model.get_parameter(n).grad is None for n in names)
    model.zero_grad(set_to_none=True)
    getattr(model(torch.rand(1, 3, 32, 64)), own).mean().backward()
    assert all(model.get_parameter(n).grad is not None for n in names)
    if head == "enhance":  # every other parameter reaches the depth map, so the set is as large as it can be
        rest = {n for n, p in model.named_parameters() if n not in names and ".norm_layer_2." not in n}
        model.zero_grad(set_to_none=True)
        model(torch.rand(1, 3, 32, 64)).depth_m.mean().backward()
        assert all(model.get_parameter(n).grad is not None for n in rest)


@pytest.mark.parametrize(
    ("head", "kept", "prefixes"),
    [
        ("depth_head", "enhanced", ("depth_structure.decoder.",)),
        (
            "enhance_head",
            "depth_m",
            (
                "enhanced_structure.decoder.up_skip_conv",
                "enhanced_structure.decoder.linear_pred1",
                "decoder_eh_joint_block_4.",
            ),
        ),
    ],
)
def test_a_trainable_head_changes_its_output_and_leaves_the_other_exact(
    synth_folder: Path, tmp_path: Path, head: str, kept: str, prefixes: tuple[str, ...]
) -> None:
    from murk.models.jointid import build_jointid, save_checkpoint

    torch.manual_seed(3)
    start = tmp_path / "start.pt"
    save_checkpoint(build_jointid("tiny"), start)
    cfg = _config(
        tmp_path / "run",
        synth_folder,
        steps=4,
        model={"variant": "tiny", "init_checkpoint": str(start), "trainable": head},
        optim={"lr": 1e-2, "min_lr": 1e-2},
    )
    train(cfg)
    before, after = load_checkpoint(start), load_checkpoint(tmp_path / "run" / "latest.pt")
    a, b = _params(start), _params(tmp_path / "run" / "latest.pt")
    changed = {k for k in a if not torch.equal(a[k], b[k])}
    assert changed and all(k.startswith(prefixes) for k in changed)
    x = torch.rand(2, 3, 32, 64)
    with torch.no_grad():
        ob, oa = before(x), after(x)
    moved = "depth_m" if kept == "enhanced" else "enhanced"
    assert torch.equal(getattr(ob, kept), getattr(oa, kept))
    assert not torch.equal(getattr(ob, moved), getattr(oa, moved))


@pytest.mark.parametrize("head", ["depth_head", "enhance_head"])
def test_trainable_heads_need_a_checkpoint_and_a_jointid(head: str) -> None:
    with pytest.raises(ValueError, match="init_checkpoint"):
        merge(TrainConfig(), {"model": {"trainable": head}})
    with pytest.raises(ValueError, match="jointid only"):
        merge(TrainConfig(), {"model": {"kind": "lite", "trainable": head, "init_checkpoint": "x.pt"}})


def test_colour_head_trains_alone_on_weights_saved_without_it(synth_folder: Path, tmp_path: Path) -> None:
    from murk.models.jointid import build_jointid, save_checkpoint

    torch.manual_seed(4)
    start = tmp_path / "start.pt"
    save_checkpoint(build_jointid("tiny"), start)  # no head in the file
    cfg = _config(
        tmp_path / "run",
        synth_folder,
        steps=4,
        model={"variant": "tiny", "init_checkpoint": str(start), "global_colour": True, "trainable": "colour_head"},
        optim={"lr": 1e-2, "min_lr": 1e-2},
    )
    train(cfg)
    a, b = _params(start), _params(tmp_path / "run" / "latest.pt")
    assert all(torch.equal(a[k], b[k]) for k in a)  # the network itself is untouched
    head = {k for k in b if k not in a}
    assert head and all(k.startswith("global_colour_head.") for k in head)
    assert b["global_colour_head.fc2.weight"].abs().sum() > 0  # it learned (it started at zero)
    after = load_checkpoint(tmp_path / "run" / "latest.pt")
    assert after.config.global_colour
    x = torch.rand(2, 3, 32, 64)
    with torch.no_grad():
        ob, oa = load_checkpoint(start)(x), after(x)
    assert torch.equal(ob.depth_m, oa.depth_m)
    assert not torch.equal(ob.enhanced, oa.enhanced)


def test_colour_head_options_are_checked(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="global_colour: true"):
        merge(TrainConfig(), {"model": {"trainable": "colour_head", "init_checkpoint": "x.pt"}})
    with pytest.raises(ValueError, match="init_checkpoint"):
        merge(TrainConfig(), {"model": {"trainable": "colour_head", "global_colour": True}})
    with pytest.raises(ValueError, match="jointid only"):
        merge(TrainConfig(), {"model": {"kind": "lite", "global_colour": True}})
    from murk.errors import InputFileError
    from murk.models.jointid import build_jointid, save_checkpoint
    from murk.train.config import ModelConfig
    from murk.train.networks import build_network

    other = tmp_path / "small.pt"
    save_checkpoint(build_jointid("small"), other)
    with pytest.raises(InputFileError, match=r"small\.pt"):
        build_network(ModelConfig(variant="tiny", init_checkpoint=str(other), global_colour=True))
