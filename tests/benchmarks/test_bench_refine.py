"""benchmarks/bench_refine.py: the refine step's cost table, run end to end on a small frame."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_every_pair_and_step_is_timed() -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), OMP_NUM_THREADS="1")
    cmd = [sys.executable, str(ROOT / "benchmarks" / "bench_refine.py"), "--rounds", "2", "--threads", "1"]
    proc = subprocess.run([*cmd, "--size", "96x64"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    rows = [line for line in proc.stdout.splitlines() if line.startswith("| `")]
    assert [r.split("`")[1] for r in rows] == ["jointid?lite_blend=0", "lite?refine=0.125"]
    assert all(float(r.split(" | ")[-1].rstrip(" x|")) > 0 for r in rows)
    for name in ("transfer, fast guided filter (step 1)", "transfer, exact guided filter", "particle guard"):
        assert f"{name}: " in proc.stdout
