"""``loss.snow`` (issue 28): the restoration error on the training input's marine snow, weighted inside the
enhancement term, so that particles left in the output cost more than their share of the pixels."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import torch
import yaml
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_rgbd_dir
from murk.synth.config import SynthConfig
from murk.train.augment import AugmentParams, apply_augment, augment_map
from murk.train.config import AugmentConfig, DataConfig, LossWeights, TrainConfig
from murk.train.losses import jointid_loss, row_l2, snow_l2

runner = CliRunner()


def test_snow_l2_is_the_row_l2_scale_error_on_the_particles_only() -> None:
    g = torch.Generator().manual_seed(0)
    target = torch.rand(2, 3, 8, 10, generator=g)
    alpha = torch.zeros(2, 1, 8, 10)
    alpha[:, :, 2:4, 3:6] = 1.0
    pred = target + 0.1 * alpha  # an error of 0.1 on every particle pixel and channel, none elsewhere
    assert float(snow_l2(pred, target, alpha)) == pytest.approx(math.sqrt(10 * 0.01), rel=1e-5)
    # uniform error everywhere and alpha 1 everywhere: exactly row_l2's value
    ones = torch.ones(2, 1, 8, 10)
    assert float(snow_l2(target + 0.1, target, ones)) == pytest.approx(float(row_l2(target + 0.1, target)), rel=1e-4)
    # an error away from the particles does not count; half-transparent particles count half
    off = pred.clone()
    off[:, :, 6:, :] += 0.5
    assert float(snow_l2(off, target, alpha)) == pytest.approx(float(snow_l2(pred, target, alpha)), rel=1e-6)
    assert float(snow_l2(pred, target, 0.5 * alpha)) == pytest.approx(float(snow_l2(pred, target, alpha)), rel=1e-5)
    # no particle at all: (almost) zero, and finite gradients
    pred.requires_grad_(True)
    none = snow_l2(pred, target, torch.zeros_like(alpha))
    none.backward()
    assert float(none.detach()) < 1e-5 and torch.isfinite(pred.grad).all()  # type: ignore[arg-type]


def test_the_snow_term_is_added_inside_the_enhancement_term_only_when_asked() -> None:
    g = torch.Generator().manual_seed(1)
    clean = torch.rand(2, 3, 16, 16, generator=g)
    enhanced = (clean + 0.05 * torch.randn(2, 3, 16, 16, generator=g)).clamp(0, 1)
    depth = torch.rand(2, 1, 16, 16, generator=g) + 0.5
    gt = torch.rand(2, 1, 16, 16, generator=g) + 0.5
    alpha = (torch.rand(2, 1, 16, 16, generator=g) > 0.9).float()
    plain = jointid_loss(enhanced, clean, depth, gt, LossWeights())
    assert plain.snow is None
    assert float(jointid_loss(enhanced, clean, depth, gt, LossWeights(), alpha).total) == float(plain.total)
    w = LossWeights(snow=0.5)
    with_snow = jointid_loss(enhanced, clean, depth, gt, w, alpha)
    assert with_snow.snow is not None
    expected = float(plain.total) + w.enhance * 0.5 * float(snow_l2(enhanced, clean, alpha))
    assert float(with_snow.total) == pytest.approx(expected, rel=1e-6)
    assert float(jointid_loss(enhanced, clean, depth, gt, w).total) == float(plain.total)  # no alpha given: no term


def test_the_alpha_follows_the_inputs_through_the_augmentation() -> None:
    g = torch.Generator().manual_seed(2)
    alpha = (torch.rand(3, 1, 12, 20, generator=g) > 0.8).float()
    rgb = alpha.expand(3, 3, 12, 20).contiguous()
    cfg = AugmentConfig(color_p=0.0)
    params = AugmentParams(
        angle_deg=torch.zeros(3),
        flip=torch.tensor([True, False, True]),
        color=torch.zeros(3, dtype=torch.bool),
        brightness=torch.ones(3),
        gain=torch.ones(3, 3),
    )
    moved, _, _ = apply_augment(rgb, rgb, torch.ones(3, 1, 12, 20), params, cfg)
    torch.testing.assert_close(augment_map(alpha, params, cfg), moved[:, :1])
    # a rotation moves the map as it moves the images (bilinear against bicubic: equal where the map is flat)
    tilted = AugmentParams(torch.full((3,), 3.0), params.flip, params.color, params.brightness, params.gain)
    smooth = torch.ones(3, 1, 12, 20)
    smooth[:, :, :, :10] = 0.0
    moved, _, _ = apply_augment(smooth.expand(3, 3, 12, 20).contiguous(), rgb, torch.ones(3, 1, 12, 20), tilted, cfg)
    got = augment_map(smooth, tilted, cfg)
    inner = (slice(None), slice(None), slice(3, -3), slice(3, -3))
    assert (got[inner] - moved[:, :1][inner]).abs().max() < 0.35  # same edge position, different kernels
    assert (got[inner] - smooth[inner]).abs().max() > 0.35  # and it did move
    assert augment_map(alpha, params, AugmentConfig(enabled=False)) is alpha


def test_bad_snow_weights_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"loss\.snow"):
        TrainConfig(loss=LossWeights(snow=-1.0))
    no_snow = DataConfig(source="scenes", synthesis=SynthConfig(stages=("basic",)))
    with pytest.raises(ValueError, match=r"loss\.snow.*marine_snow"):
        TrainConfig(loss=LossWeights(snow=1.0), data=no_snow)


def _config(source: str, snow: float) -> dict:
    return {
        "model": {"kind": "lite", "variant": "tiny"},
        "data": {
            "source": source,
            "scenes_count": 6,
            "crop_hw": [32, 64],
            "workers": 0,
            "val_fraction": 0.34,
            "synthesis": {"stages": ["basic", "marine_snow"], "marine_snow": {"n_particles": [200, 300]}},
        },
        "loss": {"snow": snow},
        "eval": {"every": 4, "val_batches": 1, "real": None},
        "steps": 4,
        "batch": 2,
        "log_every": 2,
    }


def test_murk_train_with_a_snow_weight_logs_the_snow_term(tmp_path: Path) -> None:
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(_config("scenes", 1.0)))
    r = runner.invoke(app, ["train", "--config", str(tmp_path / "t.yaml"), "--out", str(tmp_path / "run"), "--quiet"])
    assert r.exit_code == 0, r.output
    train = [json.loads(line) for line in (tmp_path / "run" / "log.jsonl").read_text().splitlines()]
    snow = [rec["snow"] for rec in train if rec.get("kind") == "train"]
    assert len(snow) == 2 and all(math.isfinite(v) and v > 0 for v in snow)


def test_a_snow_weight_on_prerendered_data_is_refused(tmp_path: Path) -> None:
    synth = tmp_path / "synth"
    r = runner.invoke(app, ["synth", str(sample_rgbd_dir()), str(synth), "--variants", "1", "--stages", "basic", "-q"])
    assert r.exit_code == 0, r.output
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(_config(str(synth), 1.0)))
    r = runner.invoke(app, ["train", "--config", str(tmp_path / "t.yaml"), "--out", str(tmp_path / "run"), "--quiet"])
    assert r.exit_code != 0
    assert "loss.snow" in r.output
