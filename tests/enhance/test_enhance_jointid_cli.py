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
    r = runner.invoke(
        app,
        ["enhance", str(src), "--out", str(tmp_path / "o0"), "-m", "jointid", "--checkpoint", str(ckpt), "--tile", "0"],
    )
    assert r.exit_code == 0, r.output  # --tile 0: whole frames, as jointid?tile=0 (the flag refused 0 until 2026-12-08)
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


def test_the_murk_command_restores_mixed_odd_sizes_as_the_restorer_does(tmp_path: Path) -> None:
    # The console command as users run it (a fresh process: murk's passive OpenMP wait policy, murk/_perf.py) on
    # a folder of mixed odd sizes (issue 29): each output equals the in-process restorer's within 1/255.
    import os
    import subprocess
    import sys

    from murk.enhance.restorer import create
    from murk.io.images import read_image, to_float

    src = tmp_path / "in"
    src.mkdir()
    rng = np.random.default_rng(7)
    sizes = ((45, 70), (97, 129), (31, 200), (45, 70))
    for i, (h, w) in enumerate(sizes):
        cv2.imwrite(str(src / f"f{i}.png"), rng.integers(0, 255, (h, w, 3), dtype=np.uint8))
    out = tmp_path / "out"
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "KMP_BLOCKTIME")}
    env["PYTHONPATH"] = os.pathsep.join(
        filter(None, [str(Path(__file__).resolve().parents[2] / "src"), env.get("PYTHONPATH")])
    )
    cmd = [sys.executable, "-m", "murk", "enhance", str(src), "--out", str(out), "--method", "jointid", "-q"]
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    restorer = create("jointid")
    for i, (h, w) in enumerate(sizes):
        ref = restorer.restore(to_float(read_image(src / f"f{i}.png")[0])[None]).images[0]
        got = cv2.imread(str(out / f"f{i}.png"))[:, :, ::-1].astype(np.float64) / 255
        assert got.shape == (h, w, 3)
        assert np.abs(got - ref).max() <= 1 / 255 + 1e-6, (i, np.abs(got - ref).max())
