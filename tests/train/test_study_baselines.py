"""murk study evaluates the paper's comparison baselines beside the arms (``eval.baselines`` method specs)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from murk.report import compare as compare_module
from murk.report.compare import CompareResult, summarise
from murk.report.study import evaluate_study
from murk.train.study import arm_config, load_study


def test_study_eval_scores_the_baseline_specs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    train = {"model": {"variant": "tiny"}, "data": {"source": "scenes"}, "eval": {"real": None}, "steps": 1}
    (tmp_path / "train.yaml").write_text(yaml.safe_dump(train))
    real = tmp_path / "real"
    real.mkdir()
    cv2.imwrite(str(real / "a.png"), np.full((16, 16, 3), 90, np.uint8))
    study = {
        "train": "train.yaml",
        "arms": [{"name": "proposed", "stages": ["basic"]}],
        "eval": {
            "real": str(real),
            "synthetic_scenes": 0,
            "baselines": ["udaformer:w/UDA.pt", "ursct:w/URSCT.pth?policy=official"],
        },
    }
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study))
    cfg, base = load_study(tmp_path / "study.yaml")
    assert cfg.eval.baselines == ("udaformer:w/UDA.pt", "ursct:w/URSCT.pth?policy=official")
    out = tmp_path / "study"
    ckpt = Path(arm_config(base, cfg.arms[0], out).out) / "latest.pt"
    ckpt.parent.mkdir(parents=True)
    ckpt.write_bytes(b"")
    seen: list = []

    def fake_run_compare(images, methods, out_dir, **kwargs):
        seen.extend(methods)
        return CompareResult(out=Path(out_dir), summary=summarise([], [m.label for m in methods]))

    monkeypatch.setattr(compare_module, "run_compare", fake_run_compare)
    report = evaluate_study(cfg, base, out)
    specs = [(m.method, m.checkpoint, dict(m.options)) for m in seen]
    assert specs[-2:] == [("udaformer", "w/UDA.pt", {}), ("ursct", "w/URSCT.pth", {"policy": "official"})]
    assert report["real"]["methods"][-2:] == ["udaformer:w", "ursct:w"]
    assert "| udaformer:w |" in (out / "study.md").read_text()


def test_held_out_scenes_with_photographic_targets_score_the_balance_beside_the_arms(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from murk.models.jointid import build_jointid, save_checkpoint

    train = {"model": {"variant": "tiny"}, "data": {"source": "scenes"}, "eval": {"real": None}, "steps": 1}
    (tmp_path / "train.yaml").write_text(yaml.safe_dump(train))
    real = tmp_path / "real"
    real.mkdir()
    cv2.imwrite(str(real / "a.png"), np.full((16, 16, 3), 90, np.uint8))
    study = {
        "train": "train.yaml",
        "arms": [{"name": "proposed", "stages": ["basic"]}],
        "eval": {"real": str(real), "synthetic_scenes": 2, "synthetic_hw": [32, 48], "synthetic_balance_pct": 0.5},
    }
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study))
    cfg, base = load_study(tmp_path / "study.yaml")
    out = tmp_path / "study"
    save_checkpoint(build_jointid("tiny"), Path(arm_config(base, cfg.arms[0], out).out) / "latest.pt")
    monkeypatch.setattr(
        compare_module,
        "run_compare",
        lambda images, methods, out_dir, **kw: CompareResult(
            out=Path(out_dir), summary=summarise([], [m.label for m in methods])
        ),
    )
    held = evaluate_study(cfg, base, out)["heldout"]
    assert held["balance_pct"] == 0.5 and list(held["scores"]) == ["input", "colorbalance", "proposed"]
    assert all(np.isfinite(row["psnr"]) for row in held["scores"].values())
    assert "| colorbalance |" in (out / "study.md").read_text()
