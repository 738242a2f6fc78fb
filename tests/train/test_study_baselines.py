"""murk study evaluates baselines beside the arms: the paper's comparison baselines (``eval.baselines`` method
specs) and, on held-out scenes with photographic targets, the classical ``colorbalance``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from murk.report import compare as compare_module
from murk.report.compare import CompareResult, summarise
from murk.report.study import evaluate_study
from murk.train.study import arm_config
from tests.train._study import study_with_one_arm


def _no_real_images(monkeypatch: pytest.MonkeyPatch, seen: list) -> None:
    def fake_run_compare(images, methods, out_dir, **kwargs):
        seen.extend(methods)
        return CompareResult(out=Path(out_dir), summary=summarise([], [m.label for m in methods]))

    monkeypatch.setattr(compare_module, "run_compare", fake_run_compare)


def test_study_eval_scores_the_baseline_specs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    cfg, base, out = study_with_one_arm(tmp_path, baselines=["udaformer:w/UDA.pt", "ursct:w/URSCT.pth?policy=official"])
    assert cfg.eval.baselines == ("udaformer:w/UDA.pt", "ursct:w/URSCT.pth?policy=official")
    seen: list = []
    _no_real_images(monkeypatch, seen)
    report = evaluate_study(cfg, base, out)
    specs = [(m.method, m.checkpoint, dict(m.options)) for m in seen]
    assert specs[-2:] == [("udaformer", "w/UDA.pt", {}), ("ursct", "w/URSCT.pth", {"policy": "official"})]
    assert report["real"]["methods"][-2:] == ["udaformer:w", "ursct:w"]
    assert "| udaformer:w |" in (out / "study.md").read_text()


def test_held_out_scenes_with_photographic_targets_score_the_balance_beside_the_arms(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from murk.models.jointid import build_jointid, save_checkpoint

    cfg, base, out = study_with_one_arm(tmp_path, synthetic_scenes=2, synthetic_hw=[32, 48], synthetic_balance_pct=0.5)
    save_checkpoint(build_jointid("tiny"), Path(arm_config(base, cfg.arms[0], out).out) / "latest.pt")
    _no_real_images(monkeypatch, [])
    held = evaluate_study(cfg, base, out)["heldout"]
    assert held["balance_pct"] == 0.5 and list(held["scores"]) == ["input", "colorbalance", "proposed"]
    assert all(np.isfinite(row["psnr"]) for row in held["scores"].values())
    assert "| colorbalance |" in (out / "study.md").read_text()
