"""Training the lite network with ``murk train`` (model.kind: lite): no depth term, checkpoints that the
``lite`` restorer and ``murk export`` take, exact resume, and the study evaluation with lite arms."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import yaml
from typer.testing import CliRunner

from murk._config import merge
from murk.cli.main import app
from murk.enhance.restorer import create
from murk.io import read_jsonl
from murk.models.lite.checkpoint import read_lite_checkpoint
from murk.train.config import ModelConfig, TrainConfig
from murk.train.loop import train
from murk.train.losses import LossWeights, jointid_loss

LITE = {
    "model": {"kind": "lite", "variant": "tiny"},
    "data": {"source": "scenes", "scenes_count": 8, "crop_hw": [32, 64], "workers": 0, "val_fraction": 0.25},
    "optim": {"lr": 0.002},
    "eval": {"every": 10, "val_batches": 1, "real": None},
    "steps": 20,
    "batch": 2,
    "log_every": 5,
}

runner = CliRunner()


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 20-step ``murk train`` run of the tiny lite network on procedural scenes (through the CLI)."""
    root = tmp_path_factory.mktemp("lite-train")
    (root / "train.yaml").write_text(yaml.safe_dump(LITE))
    r = runner.invoke(app, ["train", "--config", str(root / "train.yaml"), "--out", str(root / "run"), "--quiet"])
    assert r.exit_code == 0, r.output
    return root / "run"


def test_murk_train_writes_a_lite_checkpoint_the_restorer_loads(trained: Path) -> None:
    obj = torch.load(trained / "latest.pt", weights_only=True)
    assert obj["format"] == "murk.lite" and obj["variant"] == "tiny" and obj["meta"]["step"] == 20
    assert "optimizer" in obj["meta"]
    records = read_jsonl(trained / "log.jsonl")
    steps = [r for r in records if r["kind"] == "train"]
    evals = [r for r in records if r["kind"] == "eval"]
    assert [r["step"] for r in steps] == [5, 10, 15, 20] and all(np.isfinite(r["loss"]) for r in steps)
    assert all("silog" not in r for r in steps)  # no depth head: no depth term
    assert [r["step"] for r in evals] == [10, 20]
    assert {"val_psnr", "val_ssim", "val_input_psnr", "val_loss", "val_affine_psnr", "val_input_affine_psnr"} <= set(
        evals[-1]
    )
    # forgiving a global colour map can only raise the input's score (the fit includes gain 1, offset 0)
    assert evals[-1]["val_input_affine_psnr"] >= evals[-1]["val_input_psnr"] - 1e-6
    assert not any(k.startswith(("val_silog", "val_abs_rel", "val_rmse", "val_d1")) for k in evals[-1])
    assert (trained / "best.pt").is_file()
    restorer = create("lite", checkpoint=str(trained / "latest.pt"))
    img = np.random.default_rng(0).random((1, 50, 70, 3), dtype=np.float32)
    out = restorer.restore(img)
    assert out.images.shape == img.shape and np.isfinite(out.images).all() and out.depth_m is None
    assert create("lite+post", checkpoint=str(trained / "best.pt")).restore(img).images.shape == img.shape


def test_lite_training_learns_and_resumes_exactly(tmp_path: Path) -> None:
    base = merge(TrainConfig(), {**LITE, "steps": 6, "eval": {"every": 100, "val_batches": 1, "real": None}})
    full = merge(base, {"out": str(tmp_path / "full")})
    part = merge(base, {"out": str(tmp_path / "part")})
    train(full)
    train(part, stop_after=3)
    assert read_lite_checkpoint(tmp_path / "part" / "latest.pt")[1].meta["step"] == 3
    train(part, resume=True)
    a, _ = read_lite_checkpoint(tmp_path / "full" / "latest.pt")
    b, _ = read_lite_checkpoint(tmp_path / "part" / "latest.pt")
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    fresh = merge(base, {"out": str(tmp_path / "fresh"), "steps": 1})
    train(fresh)
    c, _ = read_lite_checkpoint(tmp_path / "fresh" / "latest.pt")
    assert not torch.equal(a["head.weight"], c["head.weight"])  # the weights moved


def test_model_config_checks_the_lite_options() -> None:
    assert ModelConfig(kind="lite").variant == "base"
    assert ModelConfig(kind="lite", variant="wide").variant == "wide"
    with pytest.raises(ValueError, match=r"variant: expected base, wide or tiny for model\.kind lite"):
        ModelConfig(kind="lite", variant="small")
    with pytest.raises(ValueError, match=r"variant: wide applies to model\.kind lite only"):
        ModelConfig(kind="jointid", variant="wide")
    with pytest.raises(ValueError, match=r"init: 'icnr' applies to model\.kind jointid only"):
        ModelConfig(kind="lite", init="icnr")


def test_loss_without_depth_has_no_depth_term() -> None:
    g = torch.Generator().manual_seed(0)
    pred, clean = torch.rand(2, 3, 16, 16, generator=g), torch.rand(2, 3, 16, 16, generator=g)
    gt = torch.rand(2, 1, 16, 16, generator=g) + 1.0
    w = LossWeights()
    no_depth = jointid_loss(pred, clean, None, gt, w)
    with_depth = jointid_loss(pred, clean, gt * 2.0, gt, w)  # constant scale: SILog > 0 only via lam < 1
    assert float(no_depth.silog) == 0.0
    assert torch.allclose(no_depth.total, w.enhance * (no_depth.l2 + w.laplacian * no_depth.lap))
    assert float(with_depth.total) > float(no_depth.total)


def test_murk_export_folds_a_lite_checkpoint(trained: Path, tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime")
    out = tmp_path / "lite.onnx"
    r = runner.invoke(app, ["export", "--checkpoint", str(trained / "latest.pt"), "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert out.is_file() and "folded" in r.output and "verified 97x131" in r.output
    img = np.random.default_rng(1).random((1, 48, 64, 3), dtype=np.float32)
    ref = create("lite", checkpoint=str(trained / "latest.pt")).restore(img).images
    np.testing.assert_allclose(create("lite", checkpoint=str(out)).restore(img).images, ref, atol=1e-4)


def test_murk_enhance_with_method_lite(trained: Path, tmp_path: Path) -> None:
    src = tmp_path / "in"
    src.mkdir()
    cv2.imwrite(str(src / "a.png"), np.random.default_rng(2).integers(0, 255, (40, 70, 3), dtype=np.uint8))
    args = ["enhance", str(src), "--out", str(tmp_path / "out"), "--method", "lite+post"]
    r = runner.invoke(app, [*args, "--checkpoint", str(trained / "latest.pt")])
    assert r.exit_code == 0, r.output
    assert "lite weights:" in r.output and "shipped" not in r.output
    assert cv2.imread(str(tmp_path / "out" / "a.png")).shape == (40, 70, 3)
    assert not (tmp_path / "out" / "depth").exists()


def test_study_evaluates_lite_arms(trained: Path, tmp_path: Path) -> None:
    """The study's evaluation builds the arms' restorers from model.kind (lite, lite+post), not Joint-ID."""
    from murk.report.study import evaluate_study
    from murk.train.study import StudyConfig, arm_config, load_study

    (tmp_path / "train.yaml").write_text(yaml.safe_dump(LITE))
    real = tmp_path / "real"
    real.mkdir()
    for i in range(2):
        cv2.imwrite(str(real / f"r{i}.png"), np.random.default_rng(i).integers(0, 255, (48, 64, 3), dtype=np.uint8))
    study_yaml = {
        "train": "train.yaml",
        "arms": [{"name": "basic", "stages": ["basic"]}, {"name": "proposed", "stages": ["basic", "marine_snow"]}],
        "eval": {"real": str(real), "synthetic_scenes": 2, "synthetic_hw": [32, 48]},
    }
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study_yaml))
    study, base = load_study(tmp_path / "study.yaml")
    assert isinstance(study, StudyConfig) and base.model.kind == "lite"
    out = tmp_path / "study"
    for arm in study.arms:  # stand-in for training: the trained run's checkpoint in every arm's folder
        d = Path(arm_config(base, arm, out).out)
        d.mkdir(parents=True)
        (d / "latest.pt").write_bytes((trained / "latest.pt").read_bytes())
    report = evaluate_study(study, base, out)
    assert report["real"]["methods"] == ["raw", "post", "basic", "proposed", "proposed+post"]
    assert not report["real"]["errors"]
    scores = json.loads((out / "heldout.json").read_text())["scores"]
    assert {"input", "basic", "proposed"} <= set(scores)
    assert "psnr" in scores["basic"] and "abs_rel" not in scores["basic"]
