"""Process-level performance settings (murk/_perf.py): the passive OpenMP wait policy of the ``murk`` command."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

SRC = str(Path(__file__).resolve().parents[1] / "src")
PROBE = (
    "import os; {pre}from murk._perf import prefer_passive_openmp as p; print(p(), os.environ.get('OMP_WAIT_POLICY'))"
)


def _probe(extra_env: dict[str, str], pre: str = "") -> str:
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "KMP_BLOCKTIME")}
    env.update(extra_env, PYTHONPATH=SRC)
    code = PROBE.format(pre=pre)
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip()


@pytest.mark.parametrize(
    ("env", "pre", "expected"),
    [
        ({}, "", "True PASSIVE"),  # nothing chosen: idle OpenMP threads sleep
        ({"OMP_WAIT_POLICY": "ACTIVE"}, "", "False ACTIVE"),  # the user's choice stays
        ({"GOMP_SPINCOUNT": "300000"}, "", "False None"),
        ({"KMP_BLOCKTIME": "0"}, "", "False None"),
        ({}, "import torch; ", "False None"),  # too late for this process: its children are left alone too
    ],
)
def test_prefer_passive_openmp_only_when_nothing_was_chosen(env: dict[str, str], pre: str, expected: str) -> None:
    assert _probe(env, pre) == expected


def test_the_murk_command_applies_it_before_torch_loads() -> None:
    code = (
        "import os, sys; sys.argv = ['murk', '--version']; from murk.cli.main import main\n"
        "try:\n    main()\nexcept SystemExit:\n    pass\n"
        "print(os.environ.get('OMP_WAIT_POLICY'), 'torch' in sys.modules)"
    )
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "KMP_BLOCKTIME")}
    proc = subprocess.run(
        [sys.executable, "-c", code], env={**env, "PYTHONPATH": SRC}, capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split()[-2:] == ["PASSIVE", "False"], proc.stdout


@pytest.mark.skipif(platform.libc_ver()[0] != "glibc", reason="glibc's mallopt")
def test_tune_allocator_applies_every_setting_on_glibc() -> None:
    """Each of the three mallopt settings (mmap threshold, trim threshold, top pad) is accepted: a value glibc
    refuses (mallopt returns 0) makes it False."""
    code = "from murk._perf import tune_allocator; print(tune_allocator())"
    env = {**os.environ, "PYTHONPATH": SRC}
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "True"
