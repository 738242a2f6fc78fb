"""benchmarks/bench_arms.py ``--probe``: a file's own methods become arms; the probes of benchmarks/probes/ load,
declare their options, are listed in their README, and reduce to the method they change at their neutral setting."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import cv2
import numpy as np
import pytest

from murk.data import sample_underwater_images
from murk.enhance.restorer import options_of, unregister

ROOT = Path(__file__).resolve().parents[2]
PROBES = ROOT / "benchmarks" / "probes"
REGISTERED = {
    "detail_area.py": ("detail_area", {"area", "threshold"}),
    "desnow_input.py": ("desnow_input", {"base", "source", "threshold", "crowd", "size"}),
    "cast_gate.py": ("cast_gate", {"cast", "below"}),
    "tta.py": ("tta", {"target", "steps", "lr", "mix"}),
}


def _bench_arms() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_arms_under_test", ROOT / "benchmarks" / "bench_arms.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), OMP_NUM_THREADS="1")
    cmd = [sys.executable, str(ROOT / "benchmarks" / "bench_arms.py"), *args]
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False)


@pytest.mark.parametrize("file", sorted(REGISTERED))
def test_each_probe_registers_its_method_with_its_options(file: str) -> None:
    name, options = REGISTERED[file]
    try:
        _bench_arms().load_probe(PROBES / file)
        assert set(options_of(name)) == options
    finally:
        unregister(name)


def test_every_probe_is_in_the_readme_and_every_named_file_exists() -> None:
    readme = (PROBES / "README.md").read_text()
    files = sorted(p.name for p in PROBES.glob("*.py"))
    assert set(REGISTERED) <= set(files)
    missing = [f for f in files if f"`{f}`" not in readme]
    assert not missing, f"benchmarks/probes/README.md does not list {missing}"
    named = {line.split("`")[1] for line in readme.splitlines() if line.startswith("| `") and ".py`" in line}
    assert named == set(files)


def test_a_probe_at_its_neutral_setting_scores_as_the_method_it_changes(tmp_path: Path) -> None:
    pairs = tmp_path / "snow"
    (pairs / "clean").mkdir(parents=True)
    (pairs / "snowy").mkdir()
    rng = np.random.default_rng(3)
    for i, path in enumerate(sample_underwater_images()[:2]):
        clean = cv2.resize(cv2.imread(str(path)), (96, 72), interpolation=cv2.INTER_AREA)
        snowy = clean.copy()
        for y, x in rng.integers(4, 68, size=(12, 2)):
            cv2.circle(snowy, (int(x), int(y)), 2, (235, 240, 240), -1)
        cv2.imwrite(str(pairs / "clean" / f"{i}.png"), clean)
        cv2.imwrite(str(pairs / "snowy" / f"{i}.png"), snowy)
    proc = _run(
        "--probe", str(PROBES / "detail_area.py"), "--probe", str(PROBES / "cast_gate.py"),
        "d=detail", "a0=detail_area?area=0", "a9=detail_area?area=9", "l=lite", "g1=cast_gate?below=1",
        "--ref", "d,l", "--snow-pairs", str(pairs), "--heldout-scenes", "0", "--threads", "1",
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    line = next(s for s in proc.stdout.splitlines() if s.startswith("snow residue, mean:"))
    residue = {k: float(v) for k, v in (part.split() for part in line.split(":", 1)[1].split(";"))}
    assert residue["a0"] == residue["d"] and residue["g1"] == residue["l"]
    assert residue["a9"] != residue["d"]  # the filter does act


def test_a_missing_probe_file_is_named() -> None:
    proc = _run("--probe", "benchmarks/probes/nothing_here.py", "l=lite", "--ref", "l", "--heldout-scenes", "0")
    assert proc.returncode == 2
    assert "--probe benchmarks/probes/nothing_here.py: no such file" in proc.stderr
