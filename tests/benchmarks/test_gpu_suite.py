"""benchmarks/gpu_suite.py must not rot between GPU windows: its CPU dry run runs every part here, in CI.

No timing is asserted (timings belong to benchmarks/); these tests check that every part runs through the same
code as on the GPU, records figures with their same-run baselines, imports nothing the GPU machine lacks, and
that the watchdog and the merge into BENCHMARKS.md work.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]
SUITE = ROOT / "benchmarks" / "gpu_suite.py"
MERGE = ROOT / "benchmarks" / "merge_gpu_suite.py"
STATUSES = {"ok", "partial", "failed", "timeout", "skipped"}


def _suite() -> ModuleType:
    """benchmarks/gpu_suite.py as a module (its sys.path additions undone)."""
    name = "gpu_suite_under_test"
    if name in sys.modules:
        return sys.modules[name]
    saved = list(sys.path)
    try:
        spec = importlib.util.spec_from_file_location(name, SUITE)
        assert spec is not None and spec.loader is not None
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module  # dataclasses look their module up there
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path[:] = saved


def _run(*args: str, timeout: float) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")])))
    return subprocess.run(
        [sys.executable, *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=timeout, check=False
    )


def _importable(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except ImportError:
        return False


def test_cpu_dry_run_runs_every_part(tmp_path: Path) -> None:
    out = tmp_path / "dry"
    proc = _run(str(SUITE), "--cpu-dry-run", "--out", str(out), timeout=1300)  # the suite stops itself at 1200 s
    details = f"exit {proc.returncode}\n{proc.stdout[-4000:]}\n{proc.stderr[-4000:]}"
    compiler = shutil.which(os.environ.get("CXX", "g++")) is not None  # what torch.compile's inductor calls
    assert proc.returncode == 0 if compiler else proc.returncode in (0, 1), details

    suite = _suite()
    files = sorted(p for p in out.rglob("*") if p.is_file())
    assert [p.name for p in files] == sorted(suite.OUTPUT_FILES), details
    assert len(files) <= 8 and all(p.stat().st_size < 16 * 2**20 for p in files)

    report = json.loads((out / "gpu_suite.json").read_text())
    assert report["mode"] == "cpu-dry-run"
    assert report["machine"]["torch"] and report["date"]
    parts = {p["name"]: p for p in report["parts"]}
    assert list(parts) == [p.name for p in suite.PARTS]  # every part, in order

    expected = dict.fromkeys(parts, "ok")
    expected["jointid_lite"] = "ok" if _importable("murk.models.lite") else "skipped"
    expected["pytest_gpu"] = "ok" if _importable("pytest") else "skipped"
    for name, part in parts.items():
        assert part["status"] in STATUSES, name
        if part["status"] != "skipped":  # a skipped part may not have run at all
            assert part["foreign_imports"] == [], (name, part["foreign_imports"])
        if name == "jointid_base_compile" and not compiler:
            assert part["status"] in ("partial", "failed"), name  # recorded, not raised
            continue
        assert part["status"] == expected[name], (name, part)
        if part["status"] != "ok" or name == "pytest_gpu":
            continue
        assert part["figures"], name
        for f in part["figures"]:
            assert math.isfinite(f["value"]) and f["value"] > 0, (name, f)
            if f["baseline_value"] is not None:
                assert math.isfinite(f["baseline_value"]) and f["baseline_value"] > 0, (name, f)
                assert f["ratio"] is None or (math.isfinite(f["ratio"]) and f["ratio"] > 0), (name, f)
        assert any(f["baseline_value"] for f in part["figures"]), f"{name}: no figure has a same-run baseline"

    # Every part is recorded, and everything skipped says why: a part skipped whole, a GPU-only measurement (CUDA
    # graphs, NCCL), a GPU test that skips on the CPU.
    for name, part in parts.items():
        if part["status"] == "skipped":
            assert part["skipped"].strip(), name
        for q in part.get("problems", []):
            if q["kind"] == "skipped":
                assert q["why"].strip() and q["why"] != suite.NO_REASON, (name, q)
    skipped = {(name, q["label"]): q["why"] for name, p in parts.items() for q in p.get("problems", [])
               if q["kind"] == "skipped"}  # fmt: skip
    for name in ("jointid_base", "jointid_small"):
        assert skipped[(name, "bf16 + channels-last + CUDA graph, 64x96 batch 1")].startswith("CUDA graphs need")
        assert skipped[(name, "bf16 + channels-last + CUDA graph, 96x160 batch 1")].startswith("CUDA graphs need")
    assert "CUDA graphs need" in skipped[("jointid_base_compile", "bf16 + channels-last + compile + CUDA graph")]
    assert "NCCL needs CUDA" in skipped[("ddp", "DDP nccl step")] and parts["ddp"]["figures"]  # gloo measured
    if expected["pytest_gpu"] == "ok":  # on the CPU the GPU tests are collected and skip, each with its reason
        d = parts["pytest_gpu"]["details"]
        assert d["failed"] == 0 and d["passed"] + d["skipped"] >= 1, d
        tests = {label for name, label in skipped if name == "pytest_gpu"}
        assert len(tests) == d["skipped"] and all("::test_" in t for t in tests), tests
    if compiler:
        labels = [f["label"] for f in parts["jointid_base_compile"]["figures"]]
        assert any("compile" in label for label in labels), labels  # torch.compile ran and was timed

    md = (out / "gpu_suite.md").read_text()
    assert "CPU DRY RUN" in md and all(f"| {name} |" in md for name in parts)
    assert all(f"- {name}: {label}: {why}" in md for (name, label), why in skipped.items())


def test_watchdog_kills_a_hung_part_and_the_suite_goes_on(tmp_path: Path) -> None:
    out = tmp_path / "selftest"
    # the hanging part sleeps an hour: within the 300 s of this run only the watchdog can have ended it
    proc = _run(str(SUITE), "--cpu-dry-run", "--out", str(out), "--parts", "_selftest_hang,_selftest_fail,_selftest_ok",
                timeout=300)  # fmt: skip
    assert proc.returncode == 1, proc.stdout + proc.stderr
    parts = {p["name"]: p for p in json.loads((out / "gpu_suite.json").read_text())["parts"]}
    hang, fail, ok = parts["_selftest_hang"], parts["_selftest_fail"], parts["_selftest_ok"]
    assert hang["status"] == "timeout" and hang["error"] == f"killed at its budget ({hang['timeout_s']:.0f} s)"
    suite = _suite()
    budget = suite.PARTS_BY_NAME["_selftest_hang"].budget_s * suite.DRY_BUDGET_FACTOR
    assert hang["exit_code"] is None and hang["timeout_s"] == budget  # its own budget ended it, not the suite's end
    assert [f["key"] for f in hang["figures"]] == ["before_hang"]  # what it measured before hanging is kept
    assert fail["status"] == "failed" and "self-test failure" in fail["error"]
    assert ok["status"] == "ok" and ok["figures"][0]["value"] == 1.0
    # the part's whole process group was killed, its own child process too
    pid = int(re.search(r"grandchild pid (\d+)", " ".join(hang["notes"]))[1])
    assert _wait_gone(pid), f"grandchild {pid} of the killed part is still running"


def _wait_gone(pid: int) -> bool:
    for _ in range(600):  # a guard against a fault only: SIGKILL of the group ends it at once
        state = Path(f"/proc/{pid}/stat")
        if not state.exists() or state.read_text().split(") ")[-1].startswith("Z"):
            return True
        time.sleep(0.1)
    return False


def test_the_gpu_runs_launcher_runs_each_part_in_a_fresh_process_and_kills_its_group(tmp_path: Path) -> None:
    # The dry run forks its parts from a server that imported torch once; the GPU run starts a fresh interpreter
    # per part (_spawn). The dry run above no longer goes through that launcher, so it is checked here.
    suite = _suite()
    env = suite._child_env()
    ok = tmp_path / "ok.json"
    args = ["--part", "_selftest_ok", "--result", str(ok), "--budget", "60", "--cpu-dry-run"]
    rc, wall, cpu = suite._spawn(args, tmp_path / "ok.log", 120.0, env)
    result = json.loads(ok.read_text())
    assert rc == 0 and result["finished"] and result["figures"][0]["value"] == 1.0
    assert wall > 0 and cpu > 0  # its own interpreter: it costs CPU to start
    hang = tmp_path / "hang.json"
    args = ["--part", "_selftest_hang", "--result", str(hang), "--budget", "60", "--cpu-dry-run"]
    rc, wall, _ = suite._spawn(args, tmp_path / "hang.log", 8.0, env)
    assert rc is None and wall >= 8.0  # killed at its budget (the part sleeps an hour)
    result = json.loads(hang.read_text())
    assert [f["key"] for f in result["figures"]] == ["before_hang"]
    pid = int(re.search(r"grandchild pid (\d+)", " ".join(result["notes"]))[1])
    assert _wait_gone(pid), f"grandchild {pid} of the killed part is still running"


def test_a_skip_carries_its_reason_and_leaves_the_part_complete() -> None:
    suite = _suite()
    with pytest.raises(ValueError, match="expected the reason of the skip"):
        suite.Recorder().skip("DDP nccl step", " ")
    nccl = {"label": "DDP nccl step", "kind": "skipped", "why": "NCCL needs CUDA"}
    entry = {"finished": True, "figures": [{"key": "ddp_img_s"}], "problems": [nccl]}
    assert suite._status(entry) == "ok"  # what cannot run here is not missing
    assert suite._status({**entry, "problems": [nccl, {"label": "x", "kind": "failed", "why": "boom"}]}) == "partial"
    report = _report("cpu-dry-run")
    report["parts"][2] |= {"status": "skipped", "skipped": "not installed: pytest"}
    report["parts"][0]["problems"] = [nccl]
    assert suite.skipped_items(report) == [
        ("synth", "DDP nccl step", "NCCL needs CUDA"),
        ("pytest_gpu", "the whole part", "not installed: pytest"),
    ]
    md = suite.render_markdown(report)
    assert "- synth: DDP nccl step: NCCL needs CUDA\n" in md
    assert "- pytest_gpu: the whole part: not installed: pytest\n" in md
    assert "| synth | ok | 7 / 15 s | 1 | 1 skipped (listed below) |" in md


def test_import_check_flags_a_package_the_gpu_machine_lacks() -> None:
    if not _importable("h5py"):
        pytest.skip("needs h5py installed (a murk dependency the GPU machine does not have)")
    code = (
        f"import sys, json; sys.path.insert(0, {str(ROOT / 'benchmarks')!r}); import gpu_suite; "
        "before = set(sys.modules); import h5py, numpy; print(json.dumps(gpu_suite.foreign_imports(before)))"
    )
    proc = _run("-c", code, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == ["h5py"]


def _report(mode: str) -> dict:
    figure = {
        "key": "torch_b64_variants_s",
        "label": "render_batch_torch cuda, 640x480, batch 64",
        "value": 12345.6,
        "unit": "variants/s",
        "baseline": "murk numpy render, 1 core, 640x480",
        "baseline_value": 120.5,
        "target": ">= 5,000 variants/s (640x480)",
        "ratio": 102.45,
    }
    return {
        "mode": mode,
        "date": "2026-12-02T10:00:00Z",
        "limit_s": 480,
        "wall_s": 300.0,
        "machine": {"gpu": {"name": "NVIDIA H200", "memory_gib": 139.8, "capability": "9.0"}, "torch": "2.13.0"},
        "parts": [
            {"name": "synth", "section": "synth", "status": "ok", "budget_s": 15, "wall_s": 7.0, "figures": [figure]},
            {"name": "snow", "section": "snow", "status": "timeout", "budget_s": 20, "wall_s": 20.0, "figures": [],
             "error": "killed at its budget (20 s)"},
            {"name": "pytest_gpu", "section": "gpu-suite", "status": "ok", "budget_s": 40, "wall_s": 20.0,
             "figures": [], "notes": ["pytest -m gpu: 3 passed, 0 failed, 0 skipped"]},
        ],
    }  # fmt: skip


def test_merge_fills_only_the_gpu_blocks(tmp_path: Path) -> None:
    bench = tmp_path / "BENCHMARKS.md"
    text = (
        "# Benchmarks\n\nCPU table | stays\n\n<!-- gpu: synth -->\nGPU: **not measured**.\n<!-- /gpu: synth -->\n"
        "between\n<!-- gpu: snow -->\nold snow\n<!-- /gpu: snow -->\n<!-- gpu: metrics -->\nuntouched\n"
        "<!-- /gpu: metrics -->\n<!-- gpu: gpu-suite -->\nnot run\n<!-- /gpu: gpu-suite -->\nend\n"
    )
    bench.write_text(text)
    report = tmp_path / "gpu_suite.json"
    report.write_text(json.dumps(_report("gpu")))
    proc = _run(str(MERGE), str(report), "--benchmarks", str(bench), timeout=120)
    assert proc.returncode == 0, proc.stderr
    merged = bench.read_text()
    synth = merged.split("<!-- gpu: synth -->")[1].split("<!-- /gpu: synth -->")[0]
    assert "**12,346 variants/s**" in synth and "murk numpy render, 1 core, 640x480: 120.5 variants/s" in synth
    assert "x102.45" in synth and "NVIDIA H200" in synth and "not measured" not in synth
    assert "timeout" in merged.split("<!-- gpu: snow -->")[1] and "old snow" not in merged
    assert "| synth | ok | 7 / 15 s | 1 |" in merged and "3 passed" in merged
    outside = re.sub(r"<!-- gpu: ([\w-]+) -->.*?<!-- /gpu: \1 -->", "", merged, flags=re.DOTALL)
    assert outside == re.sub(r"<!-- gpu: ([\w-]+) -->.*?<!-- /gpu: \1 -->", "", text, flags=re.DOTALL)
    assert "untouched" in merged  # a block with no part in the report is left as it was
    assert _run(str(MERGE), str(report), "--benchmarks", str(bench), timeout=120).returncode == 0
    assert bench.read_text() == merged  # merging twice changes nothing

    dry = tmp_path / "dry.json"
    dry.write_text(json.dumps(_report("cpu-dry-run")))
    refused = _run(str(MERGE), str(dry), "--benchmarks", str(bench), timeout=120)
    assert refused.returncode == 2 and "cpu-dry-run" in refused.stderr
    assert bench.read_text() == merged


def test_benchmarks_md_has_a_gpu_block_for_every_part() -> None:
    text = (ROOT / "BENCHMARKS.md").read_text()
    blocks = set(re.findall(r"<!-- gpu: ([\w-]+) -->", text))
    assert blocks == set(re.findall(r"<!-- /gpu: ([\w-]+) -->", text))
    assert {p.section for p in _suite().PARTS} <= blocks
