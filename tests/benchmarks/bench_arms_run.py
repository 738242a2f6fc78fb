"""What the tests of benchmarks/bench_arms.py share: loading a benchmark or probe file as a module, and running
bench_arms.py in a subprocess (one thread, ``src`` on the path)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[2]
BENCH_ARMS = ROOT / "benchmarks" / "bench_arms.py"


def load_file(path: Path) -> ModuleType:
    """``path`` (a benchmark or a probe) imported as a module of its own."""
    spec = importlib.util.spec_from_file_location(f"under_test_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # a dataclass of the file looks its module up there
    spec.loader.exec_module(module)
    return module


def run_bench_arms(*args: str) -> subprocess.CompletedProcess[str]:
    """``bench_arms.py ARGS`` in a subprocess from the repository root; its exit status is not checked."""
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), OMP_NUM_THREADS="1")
    cmd = [sys.executable, str(BENCH_ARMS), *args]
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False)
