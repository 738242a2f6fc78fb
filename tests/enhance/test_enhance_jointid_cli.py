from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import torch
from typer.testing import CliRunner

from murk.cli.main import app
from murk.models.jointid import build_jointid, save_checkpoint

runner = CliRunner()


def test_enhance_with_a_jointid_checkpoint_writes_images_and_depth(tmp_path: Path) -> None:
    torch.manual_seed(0)
    ckpt = save_checkpoint(build_jointid("tiny"), tmp_path / "tiny.pt", step=0)
    src = tmp_path / "in"
    src.mkdir()
    for i, (h, w) in enumerate(((40, 70), (64, 64))):  # sizes that are not multiples of 32: padded, not resized
        cv2.imwrite(str(src / f"f{i}.png"), np.random.default_rng(i).integers(0, 255, (h, w, 3), dtype=np.uint8))
    out = tmp_path / "out"
    r = runner.invoke(
        app,
        [
            "enhance",
            str(src),
            "--out",
            str(out),
            "--method",
            "jointid+post",
            "--checkpoint",
            str(ckpt),
            "--precision",
            "fp32",
            "-q",
        ],
    )
    assert r.exit_code == 0, r.output
    assert cv2.imread(str(out / "f0.png")).shape == (40, 70, 3)
    d = cv2.imread(str(out / "depth" / "f0.png"), cv2.IMREAD_UNCHANGED)
    assert d.dtype == np.uint16 and d.shape == (40, 70) and 0 < d.max() <= 15000  # mm, Joint-ID's 15 m cap
    assert (out / "depth_preview" / "f1.jpg").exists()
    r = runner.invoke(app, ["enhance", str(src), "--out", str(tmp_path / "o2"), "--method", "jointid+post"])
    assert r.exit_code == 0, r.output  # no --checkpoint: the shipped weights, named in the output
    assert "jointid weights:" in r.output and "jointid-small.pt" in r.output and "shipped" in r.output
    assert cv2.imread(str(tmp_path / "o2" / "f0.png")).shape == (40, 70, 3)
    r = runner.invoke(
        app,
        [
            "enhance",
            str(src),
            "--out",
            str(tmp_path / "o3"),
            "--method",
            "jointid",
            "--checkpoint",
            str(tmp_path / "missing.pt"),
        ],
    )
    assert r.exit_code == 2 and "missing.pt" in r.output
