"""Distillation (``loss.distill`` with ``loss.teacher``): the term, its checks, and a run that uses it."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import torch

from murk.train.config import LossWeights
from murk.train.losses import jointid_loss, row_l2
from murk.train.networks import load_teacher, run_network
from tests.train._cli import train_cli


def test_the_distill_term_is_the_row_l2_to_the_teacher_inside_the_enhancement_term() -> None:
    g = torch.Generator().manual_seed(2)
    out, clean, teacher = (torch.rand(2, 3, 16, 24, generator=g) for _ in range(3))
    depth = torch.ones(2, 1, 16, 24)
    plain = jointid_loss(out, clean, None, depth, LossWeights())
    taught = jointid_loss(out, clean, None, depth, LossWeights(distill=0.5, teacher="lite"), teacher=teacher)
    assert plain.distill is None and taught.distill is not None
    assert torch.allclose(taught.distill, row_l2(out, teacher))
    expect = plain.total + LossWeights().enhance * 0.5 * row_l2(out, teacher)
    assert torch.allclose(taught.total, expect)
    # no teacher output given: the original loss, whatever the weight
    assert torch.equal(
        jointid_loss(out, clean, None, depth, LossWeights(distill=0.5, teacher="lite")).total, plain.total
    )


def test_a_distill_weight_needs_a_known_teacher() -> None:
    with pytest.raises(ValueError, match="teacher"):
        LossWeights(distill=1.0)
    with pytest.raises(ValueError, match="teacher"):
        LossWeights(distill=1.0, teacher="udaformer")
    with pytest.raises(ValueError, match="distill"):
        LossWeights(distill=-1.0, teacher="lite")
    LossWeights(distill=1.0, teacher="jointid:runs/x.pt")  # the file is read when training starts


def test_the_shipped_lite_teacher_restores_like_its_restorer() -> None:
    from murk.enhance.restorer import create

    kind, net = load_teacher("lite")
    assert kind == "lite" and not any(p.requires_grad for p in net.parameters())
    x = torch.rand(1, 3, 64, 96, generator=torch.Generator().manual_seed(3))
    with torch.no_grad():
        got = run_network(kind, net, x, net.input_balance_pct)[0].clamp(0, 1)
    # The network teacher is the network's own output: the method without its exposure step (docs/train.md)
    ref = create("lite", exposure="network").restore(x.permute(0, 2, 3, 1).numpy()).images[0]
    assert float((got[0].permute(1, 2, 0) - torch.from_numpy(ref).clamp(0, 1)).abs().max()) < 2e-3


@pytest.mark.parametrize(
    ("model", "teacher"),
    [({"variant": "tiny"}, "lite"), ({"kind": "lite", "variant": "base"}, "method:colorbalance")],
    ids=["network-teacher", "method-teacher"],
)
def test_murk_train_with_a_teacher_logs_the_distill_term(tmp_path: Path, model: dict, teacher: str) -> None:
    cfg = {
        "model": model,
        "data": {"source": "scenes", "scenes_count": 4, "crop_hw": [32, 64], "workers": 0, "val_fraction": 0.25},
        "loss": {"distill": 1.0, "teacher": teacher},
        "eval": {"every": 4, "val_batches": 1, "real": None},
        "steps": 4,
        "batch": 2,
        "log_every": 2,
    }
    run = train_cli(tmp_path, cfg)
    recs = [json.loads(line) for line in (run / "log.jsonl").read_text().splitlines()]
    distill = [rec["distill"] for rec in recs if rec.get("kind") == "train"]
    assert len(distill) == 2 and all(math.isfinite(v) and v > 0 for v in distill)


def test_a_method_teacher_is_named_by_its_spec() -> None:
    LossWeights(distill=1.0, teacher="method:water?strength=0.5")  # the method is built when training starts
    for bad in ("method:", "method: ", "method: water", "methods:water"):
        with pytest.raises(ValueError, match="method:SPEC"):
            LossWeights(distill=1.0, teacher=bad)


def test_the_method_teacher_restores_as_the_method_does_on_the_device_it_is_given() -> None:
    from murk.enhance.restorer import create
    from murk.train.config import TrainConfig
    from murk.workflows.distill import MethodTeacher, method_teacher

    x = torch.rand(2, 3, 40, 56, generator=torch.Generator().manual_seed(5)).requires_grad_(True)
    build = method_teacher(TrainConfig(loss=LossWeights(distill=1.0, teacher="method:colorbalance?low=2")))
    assert build is not None
    teacher = build(torch.device("cpu"))
    assert isinstance(teacher, MethodTeacher) and teacher.restorer.device == torch.device("cpu")
    ref = create("colorbalance?low=2").restore(x.detach().permute(0, 2, 3, 1).numpy()).images
    got = teacher(x)
    assert got.shape == x.shape and not got.requires_grad  # no gradient flows into the teacher
    assert torch.allclose(got.permute(0, 2, 3, 1), torch.from_numpy(ref), atol=1e-6)
    assert not torch.allclose(got, x, atol=1e-2)  # the balance changed the input
    # a network method is built on the device given (under torchrun: each rank's own), not the config's
    assert build_device_of("method:lite", "cpu:0") == torch.device("cpu:0") != torch.device("cpu")
    # a network teacher, or no distillation: training loads its own teacher (or none)
    assert method_teacher(TrainConfig(loss=LossWeights(distill=1.0, teacher="lite"))) is None
    assert method_teacher(TrainConfig(loss=LossWeights(teacher="method:water"))) is None


def build_device_of(spec: str, device: str) -> torch.device:
    from murk.train.config import TrainConfig
    from murk.workflows.distill import method_teacher

    build = method_teacher(TrainConfig(loss=LossWeights(distill=1.0, teacher=spec)))
    assert build is not None
    return torch.device(build(torch.device(device)).restorer.device)


def test_an_unknown_method_teacher_is_named_as_loss_teacher_before_anything_is_built() -> None:
    from murk.train.config import TrainConfig
    from murk.workflows.distill import method_teacher

    with pytest.raises(ValueError, match=r"loss\.teacher: method:nosuch: .*unknown 'nosuch'"):
        method_teacher(TrainConfig(loss=LossWeights(distill=1.0, teacher="method:nosuch")))
    with pytest.raises(ValueError, match=r"loss\.teacher: method:water\?strenght=1: .*strength"):
        method_teacher(TrainConfig(loss=LossWeights(distill=1.0, teacher="method:water?strenght=1")))


def test_the_training_loop_alone_refuses_a_method_teacher_before_writing_anything(tmp_path: Path) -> None:
    from murk.train.config import TrainConfig
    from murk.train.loop import train

    config = TrainConfig(loss=LossWeights(distill=1.0, teacher="method:water"), out=str(tmp_path / "run"))
    with pytest.raises(ValueError, match=r"method:water is a restoration method.*murk\.workflows\.distill"):
        train(config)
    assert not (tmp_path / "run").exists()
