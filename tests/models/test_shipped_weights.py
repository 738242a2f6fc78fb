"""The Joint-ID weights shipped in the package: loadable safely, small, and a real restorer (not a stub).

Figures of the full evaluation (64 held-out scenes, the real images, speed) are in docs/models.md and come from
benchmarks/bench_model.py; this test pins a cheap part of them so that a broken or replaced file is caught.
"""

from __future__ import annotations

import numpy as np
import torch

from murk.data import sample_underwater_images, shipped_jointid_weights
from murk.enhance.restorer import create, weights_used
from murk.io import read_rgb
from murk.metrics import restoration_measures


def test_shipped_file_is_small_safe_and_the_small_variant() -> None:
    path = shipped_jointid_weights()
    assert path.is_file() and path.stat().st_size <= 10 * 2**20
    obj = torch.load(path, weights_only=True)  # no pickled code: plain tensors and data
    assert obj["variant"] == "small+colour" and obj["config"]["residual_output"] is True
    assert obj["config"]["global_colour"] is True  # stage 6: the global colour head
    assert all(v.dtype == torch.float16 for v in obj["state_dict"].values() if v.is_floating_point())
    assert obj["meta"]["command"].startswith("murk train --config configs/train-small-cpu.yaml")
    assert "murk train --config configs/train-small-depth-cpu.yaml" in obj["meta"]["command"]  # stage 2
    assert "murk train --config configs/train-small-balance-cpu.yaml" in obj["meta"]["command"]  # stage 4
    assert "murk train --config configs/train-small-snow-cpu.yaml --stop-after 1000" in obj["meta"]["command"]
    assert obj["meta"]["stage6"]["soup_of_stage5"]["weights"] == [0.5, 0.5]  # stage 4 and its snow continuation
    assert "murk train --config configs/train-small-colour-cpu.yaml" in obj["meta"]["command"]  # stage 6: head
    assert "murk train --config configs/train-small-distill-cpu.yaml" in obj["meta"]["command"]  # stage 6: all
    assert "murk train --config configs/train-small-depthhead-cpu.yaml" in obj["meta"]["command"]  # stage 7: depth
    assert obj["meta"]["stage7"]["trainable"] == "depth_head"
    assert "murk train --config configs/train-small-water-head-cpu.yaml" in obj["meta"]["command"]  # stage 8: colour
    assert obj["meta"]["stage8"]["trainable"] == "colour_head" and obj["meta"]["stage8"]["teacher"] == "method:water"
    assert obj["meta"]["input_balance_pct"] == 1.0


def test_shipped_model_restores_heldout_scenes_and_keeps_real_images_sane() -> None:
    from murk._config import merge
    from murk.report.heldout import make_heldout, score_heldout
    from murk.synth.config import SnowConfig, SynthConfig

    torch.set_num_threads(2)
    restorer = create("jointid")
    assert weights_used(restorer).weights == str(shipped_jointid_weights())
    synthesis = merge(
        SynthConfig(medium=SynthConfig().medium, marine_snow=SnowConfig(reference_area_px=307200)),
        {"medium": {"vertical_depth_m": [2.0, 10.0]}},
    )
    # photographic targets (colour-balanced scenes, as in stage 4's training: docs/train.md)
    data = make_heldout(6, seed=4242, size_hw=(96, 128), synthesis=synthesis, balance_pct=0.5)
    scores = score_heldout(data, {"model": restorer})
    assert scores["model"]["psnr"] > scores["input"]["psnr"] + 1.0, scores
    # The 13 shipped real images, means (single images vary: the stage-4 weights darken funie_euvp/16.jpg to a
    # luminance ratio of 0.86 and paint its upper half blue, with periodic artefacts 1.66x; docs/models.md).
    rows = []
    for path in sample_underwater_images():
        img = read_rgb(path)
        rows.append(restoration_measures(img, np.clip(restorer.restore(img[None]).images[0], 0, 1)))
    m = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
    assert m["contrast_ratio"] > 0.5 and m["luminance_ratio"] > 0.9, m  # no grey collapse, not darkened
    assert m["artefact_periodic_ratio"] < 1.3 and m["artefact_isolated_ratio"] < 1.3, m


def test_recorded_run_configs_equal_the_shipped_configs() -> None:
    """The model cards' recorded configs (written by the runs that made the shipped weights) are the shipped
    configs' recipes: only the output folder differs."""
    import dataclasses
    from pathlib import Path

    from murk._config import load_yaml
    from murk.train.config import TrainConfig

    root = Path(__file__).resolve().parents[2]
    pairs = {
        "configs/train-small-cpu.yaml": "docs/models/jointid-small-config.yaml",
        "configs/train-small-depth-cpu.yaml": "docs/models/jointid-small-depth-config.yaml",
        "configs/train-lite-cpu.yaml": "docs/models/lite-config.yaml",
        "configs/train-lite-balance-cpu.yaml": "docs/models/lite-balance-config.yaml",
        "configs/train-small-balance-cpu.yaml": "docs/models/jointid-small-balance-config.yaml",
        "configs/train-small-snow-cpu.yaml": "docs/models/jointid-small-snow-config.yaml",
        "configs/train-small-colour-cpu.yaml": "docs/models/jointid-small-colour-config.yaml",
        "configs/train-small-distill-cpu.yaml": "docs/models/jointid-small-distill-config.yaml",
        "configs/train-lite-mild-cpu.yaml": "docs/models/lite-mild-config.yaml",
        "configs/train-small-depthhead-cpu.yaml": "docs/models/jointid-small-depthhead-config.yaml",
        "configs/train-lite-water-cpu.yaml": "docs/models/lite-water-config.yaml",
        "configs/train-small-water-head-cpu.yaml": "docs/models/jointid-small-water-head-config.yaml",
        "configs/train-lite-water-halfdetail-cpu.yaml": "docs/models/lite-water-halfdetail-config.yaml",
        "configs/train-lite-long-s1-cpu.yaml": "docs/models/lite-long-s1-config.yaml",
        "configs/train-lite-long-halfdetail-cpu.yaml": "docs/models/lite-long-halfdetail-config.yaml",
        # the other stage 2 of 2026-12-07, measured and not shipped (docs/models.md)
        "configs/train-lite-long-waterdetail-cpu.yaml": "docs/models/lite-long-waterdetail-config.yaml",
        # the `wide` run of 2026-12-07, recorded with its card though not shipped (docs/models.md)
        "configs/train-lite-wide-long-cpu.yaml": "docs/models/lite-wide-long-config.yaml",
        "configs/train-lite-wide-long-halfdetail-cpu.yaml": "docs/models/lite-wide-long-halfdetail-config.yaml",
        # its control with `base`, measured and not shipped (docs/train.md, "Width or length: the control")
        "configs/train-lite-base-long-cpu.yaml": "docs/models/lite-base-long-config.yaml",
        "configs/train-lite-base-long-halfdetail-cpu.yaml": "docs/models/lite-base-long-halfdetail-config.yaml",
    }
    # Stage 6 ran from the files of that day (the head from the then-shipped stage-5 file, the distillation from the
    # head's first run); the shipped configs name where a reproduction finds them (docs/models.md, "Stage 6").
    moved = {
        "configs/train-small-colour-cpu.yaml": (
            "src/murk/data/models/jointid-small.pt",
            "runs/jointid-small-stage5.pt",
        ),
        "configs/train-small-distill-cpu.yaml": ("runs/small-gc-head-wb3/latest.pt", "runs/small-colour/latest.pt"),
        "configs/train-lite-mild-cpu.yaml": ("src/murk/data/models/lite.pt", "runs/lite-stage4.pt"),
        "configs/train-small-depthhead-cpu.yaml": (
            "src/murk/data/models/jointid-small.pt",
            "runs/jointid-small-stage6.pt",
        ),
        "configs/train-small-water-head-cpu.yaml": (
            "src/murk/data/models/jointid-small.pt",
            "runs/jointid-small-stage7.pt",
        ),
    }
    # Stage 6's teacher was the `lite` shipped that day (stage 4), which lite's stage 5 has since replaced.
    teachers = {"configs/train-small-distill-cpu.yaml": ("lite", "lite:runs/lite-stage4.pt")}
    for shipped, recorded in pairs.items():
        a, b = (load_yaml(TrainConfig, root / p) for p in (shipped, recorded))
        if shipped in moved:
            assert (b.model.init_checkpoint, a.model.init_checkpoint) == moved[shipped], shipped
            b = dataclasses.replace(b, model=dataclasses.replace(b.model, init_checkpoint=a.model.init_checkpoint))
        if shipped in teachers:
            assert (b.loss.teacher, a.loss.teacher) == teachers[shipped], shipped
            b = dataclasses.replace(b, loss=dataclasses.replace(b.loss, teacher=a.loss.teacher))
        snow = b.data.synthesis.marine_snow
        if snow.bank is None:  # recorded before 2026-12-03, when the default bank was today's builtin:snow-small
            synthesis = dataclasses.replace(
                b.data.synthesis, marine_snow=dataclasses.replace(snow, bank="builtin:snow-small")
            )
            b = dataclasses.replace(b, data=dataclasses.replace(b.data, synthesis=synthesis))
        assert dataclasses.replace(a, out="x") == dataclasses.replace(b, out="x"), shipped
