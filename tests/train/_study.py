"""A study of one trained arm, for the tests of the study's evaluation."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml

from murk.train.study import arm_config, load_study


def study_with_one_arm(tmp_path: Path, **eval_extra: Any) -> tuple:
    """A study of one (fake, empty) trained arm ``proposed`` whose eval has ``eval_extra`` and one real image:
    (config, base, out). The arm's ``latest.pt`` is an empty file: write a checkpoint over it to score it."""
    train = {"model": {"variant": "tiny"}, "data": {"source": "scenes"}, "eval": {"real": None}, "steps": 1}
    (tmp_path / "train.yaml").write_text(yaml.safe_dump(train))
    real = tmp_path / "real"
    real.mkdir()
    cv2.imwrite(str(real / "a.png"), np.full((16, 16, 3), 90, np.uint8))
    study = {
        "train": "train.yaml",
        "arms": [{"name": "proposed", "stages": ["basic"]}],
        "eval": {"real": str(real), "synthetic_scenes": 0, **eval_extra},
    }
    (tmp_path / "study.yaml").write_text(yaml.safe_dump(study))
    cfg, base = load_study(tmp_path / "study.yaml")
    out = tmp_path / "study"
    ckpt = Path(arm_config(base, cfg.arms[0], out).out) / "latest.pt"
    ckpt.parent.mkdir(parents=True)
    ckpt.write_bytes(b"")
    return cfg, base, out
