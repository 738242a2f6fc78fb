"""benchmarks/bench_jointid_cost.py: the four arms of jointid's cost table, run end to end on a small frame."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_every_arm_is_timed_against_the_first() -> None:
    from murk.data import shipped_jointid_weights

    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), OMP_NUM_THREADS="1")
    script = ROOT / "benchmarks" / "bench_jointid_cost.py"
    # any Joint-ID weights stand in for the previous ones: the arms differ in the steps they run
    cmd = [sys.executable, str(script), "--previous-jointid", str(shipped_jointid_weights()), "--rounds", "2"]
    proc = subprocess.run(
        [*cmd, "--size", "96x64", "--threads", "1"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300
    )
    assert proc.returncode == 0, proc.stderr
    rows = [line for line in proc.stdout.splitlines() if line.startswith("| ") and not line.startswith("| arm")]
    assert len(rows) == 4 and rows[0].endswith("| 1.000x |")
    assert rows[-1].startswith("| `jointid` now")
    assert all(float(r.split(" | ")[-2]) > 0 and float(r.split(" | ")[-1].rstrip(" x|")) > 0 for r in rows)
