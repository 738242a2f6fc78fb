"""``murk synth`` under faults (issue 13): an output folder overlapping the inputs, a full disk, stale error
records, and a killed parent whose workers must stop."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.io import read_jsonl

from .._faults import assert_nothing_partial, fill_disk, one_line_error

runner = CliRunner()


def _synth(*args: str):
    return runner.invoke(app, ["synth", *args, "--variants", "2", "-q"])


def test_output_folder_equal_to_the_input_folder_is_refused(small_rgbd: Path) -> None:
    before = sorted(p.relative_to(small_rgbd) for p in small_rgbd.rglob("*"))
    line = one_line_error(_synth(str(small_rgbd), str(small_rgbd), "--size", "32x24"))
    assert f"OUT_DIR {small_rgbd}: the input folder {small_rgbd / 'depth'} lies in its output folder" in line
    assert "the outputs would overwrite or mix with the input files" in line
    assert sorted(p.relative_to(small_rgbd) for p in small_rgbd.rglob("*")) == before  # nothing written


def test_output_inside_an_input_folder_or_holding_inputs_in_its_subfolders_is_refused(
    small_rgbd: Path, tmp_path: Path
) -> None:
    line = one_line_error(_synth(str(small_rgbd), str(small_rgbd / "rgb" / "out")))
    assert f"inside the input folder {small_rgbd / 'rgb'}" in line
    assert not (small_rgbd / "rgb" / "out").exists()
    r = _synth(str(small_rgbd), str(small_rgbd / "synth"))  # beside rgb/ and depth/: nothing overlaps
    assert r.exit_code == 0, r.output
    assert len(list((small_rgbd / "synth" / "degraded").iterdir())) == 4
    r = _synth(str(small_rgbd), str(tmp_path))  # above the input folder: fine too
    assert r.exit_code == 0, r.output
    lst = tmp_path / "pairs.txt"  # a list naming the clean image of an earlier run: its folder is an output
    lst.write_text(f"{tmp_path}/clean/a.png {small_rgbd}/depth/a.png\n")
    line = one_line_error(runner.invoke(app, ["synth", "--list", str(lst), str(tmp_path)]))
    assert f"the input folder {tmp_path / 'clean'} lies in its output folder {tmp_path / 'clean'}" in line
    r = runner.invoke(app, ["synth", "--list", str(lst), str(tmp_path / "o2"), "--variants", "1", "-q"])
    assert r.exit_code == 0, r.output


def test_full_disk_stops_with_one_line_and_a_rerun_completes(
    small_rgbd: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "out"
    # three PNG files fit, then the disk is full; the writer threads write a.png's clean image, its depth map and
    # its variants in parallel, so which files fail depends on their timing, not on the serial order
    failed = fill_disk(monkeypatch, after=3, only=".png")
    line = one_line_error(_synth(str(small_rgbd), str(out)))
    assert failed
    named = [out / sub / name for sub in ("clean", "depth", "degraded") for name in failed]
    assert any(line == f"error: {p}: no space left on device" for p in named), (line, failed)
    assert_nothing_partial(out)
    assert not (out / "degraded" / "b_v0.png").exists()  # the run stopped with a.png's variants
    monkeypatch.undo()  # space freed
    r = _synth(str(small_rgbd), str(out))
    assert r.exit_code == 0, r.output
    assert [(x["stem"], x["variant"]) for x in read_jsonl(out / "manifest.jsonl")] == [
        (s, k) for s in "ab" for k in range(2)
    ]


def test_errors_jsonl_lists_the_latest_run_only(small_rgbd: Path, tmp_path: Path) -> None:
    (small_rgbd / "rgb" / "broken.png").write_bytes(b"nope")
    cv2.imwrite(str(small_rgbd / "depth" / "broken.png"), np.ones((4, 4), np.uint16))
    out = tmp_path / "out"
    assert _synth(str(small_rgbd), str(out)).exit_code == 1
    assert [Path(e["input"]).name for e in read_jsonl(out / "errors.jsonl")] == ["broken.png"]
    for sub in ("rgb", "depth"):
        (small_rgbd / sub / "broken.png").unlink()
    r = _synth(str(small_rgbd), str(out))
    assert r.exit_code == 0, r.output
    assert not (out / "errors.jsonl").exists()


# ------------------------------------------------------------------------------------- a killed parent


def _stat(pid: int) -> tuple[str, int, str] | None:
    """(state, ppid, start time) of a process from /proc, or None when it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (FileNotFoundError, ProcessLookupError):
        return None
    return fields[0], int(fields[1]), fields[19]


def _workers_of(parent: int) -> dict[int, str]:
    """Pool workers (spawned ``multiprocessing`` children) of ``parent``: pid -> start time."""
    found = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        st = _stat(int(entry.name))
        try:
            cmd = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        if st is not None and st[1] == parent and b"spawn_main" in cmd:
            found[int(entry.name)] = st[2]
    return found


def _alive(pid: int, start: str) -> bool:
    st = _stat(pid)
    return st is not None and st[2] == start and st[0] not in ("Z", "X")  # a zombie has stopped


def _files(folder: Path) -> dict[str, int]:
    return {str(p.relative_to(folder)): p.stat().st_size for p in folder.rglob("*") if p.is_file()}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_killing_the_parent_stops_its_workers(tmp_path: Path) -> None:
    """Each image holds far more work (400 variants) than the 10 s bound: workers that outlived their parent
    would still be writing when it expires."""
    rgbd = tmp_path / "rgbd"
    for sub in ("rgb", "depth"):
        (rgbd / sub).mkdir(parents=True)
    g = np.random.default_rng(0)
    yy, xx = np.mgrid[0:360, 0:480]
    for stem in ("a", "b"):
        cv2.imwrite(str(rgbd / "rgb" / f"{stem}.png"), (g.random((360, 480, 3)) * 255).astype(np.uint8))
        cv2.imwrite(str(rgbd / "depth" / f"{stem}.png"), (800 + 10 * xx + 5 * yy).astype(np.uint16))
    out = tmp_path / "out"
    cmd = [sys.executable, "-m", "murk", "synth", str(rgbd), str(out), "--workers", "2", "--variants", "400", "-q"]
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src")}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    workers: dict[int, str] = {}
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and proc.poll() is None:
            workers = _workers_of(proc.pid)
            if len(workers) == 2 and len(list(out.glob("degraded/*.png"))) >= 2:
                break
            time.sleep(0.05)
        assert proc.poll() is None and len(workers) == 2, "the workers never started writing"
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and any(_alive(p, s) for p, s in workers.items()):
            time.sleep(0.05)
        assert not [p for p, s in workers.items() if _alive(p, s)], "workers outlived their parent"
        before = _files(out)
        time.sleep(1.0)
        assert _files(out) == before  # nothing is written any more
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for pid, start in workers.items():  # only our own workers, identified by pid and start time
            if _alive(pid, start):
                os.kill(pid, signal.SIGKILL)
