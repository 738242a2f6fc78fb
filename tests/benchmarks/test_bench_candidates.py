"""benchmarks/bench_candidates.py: the candidate table of the real-water work, run end to end on a tiny set."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from murk.data import sample_underwater_images, shipped_lite_weights

ROOT = Path(__file__).resolve().parents[2]


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), OMP_NUM_THREADS="1")
    cmd = [sys.executable, str(ROOT / "benchmarks" / "bench_candidates.py"), *args]
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False)


def test_identical_weights_score_identically_and_a_missing_file_is_named(tmp_path: Path) -> None:
    pairs = tmp_path / "pairs"
    for sub in ("input", "reference"):
        (pairs / sub).mkdir(parents=True)
    for i, path in enumerate(sample_underwater_images()[:3]):
        img = cv2.imread(str(path))
        small = cv2.resize(img, (96, 64), interpolation=cv2.INTER_AREA)
        cv2.imwrite(str(pairs / "input" / f"p{i}.png"), small)
        ref = np.clip(small.astype(np.float32) * 1.2 - 10, 0, 255).astype(np.uint8)  # any reference will do
        cv2.imwrite(str(pairs / "reference" / f"p{i}.png"), ref)
    copy = tmp_path / "same.pt"
    shutil.copy(shipped_lite_weights(), copy)
    proc = _run("--method", "lite", "--pairs", str(pairs), "--scenes", "2", "shipped", f"same={copy}")
    assert proc.returncode == 0, proc.stderr
    rows = [line for line in proc.stdout.splitlines() if line.startswith("| `")]
    assert [r.split("`")[1] for r in rows] == ["shipped", "same"]
    cells = [r.split(" | ") for r in rows]
    assert cells[0][1:3] == cells[1][1:3]  # real pairs: mean over sets and per set
    assert cells[0][4:] == cells[1][4:]  # held-out gain, (no snow pairs), periodic artefacts
    assert cells[1][3].startswith("+0.00 +- 0.00, higher on 0/3")  # the paired difference to the first
    missing = _run("--method", "lite", "--pairs", str(pairs), f"gone={tmp_path / 'gone.pt'}")
    assert missing.returncode != 0 and "candidate 'gone': no checkpoint file at" in missing.stderr
