"""``murk._workers.worker_pool``: the process pool of ``synth``, ``scenes`` and shard writing leaves Ctrl+C to the
parent, waits for its work on a normal exit and stops its workers at once on an error (no hang on a second
Ctrl+C: the shutdown cannot be interrupted half-way)."""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from murk._workers import die_with_parent, sigint_ignored, worker_pool


def _sigint_disposition() -> str:
    handler = signal.getsignal(signal.SIGINT)
    return "ignored" if handler == signal.SIG_IGN else "handled"


def _sleep_then(value: int, seconds: float) -> int:
    time.sleep(seconds)
    return value


def _mark_then_sleep(value: int, seconds: float, marks: str) -> int:
    """Leave a file in ``marks`` (the item has started), then sleep."""
    Path(marks, f"started-{value}-{os.getpid()}").touch()
    return _sleep_then(value, seconds)


def _own_handler(signum: int, frame: object) -> None:
    """A SIGINT handler only this test installs: what the pool must give back."""


@pytest.fixture
def known_sigint_handler() -> Iterator[Callable[[int, object], None]]:
    """Installs :func:`_own_handler` for SIGINT and restores the previous disposition after the test: the test
    then asserts on a state it set, not on the one it inherited (a shell running the suite in the background
    starts it with SIGINT ignored)."""
    previous = signal.signal(signal.SIGINT, _own_handler)
    try:
        yield _own_handler
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize("method", ["spawn", "fork"])
def test_workers_ignore_ctrl_c_and_a_normal_exit_waits_for_the_work(
    method: str, known_sigint_handler: Callable[[int, object], None]
) -> None:
    ctx = mp.get_context(method)
    with worker_pool(2, mp_context=ctx, initializer=die_with_parent) as pool:
        processes = list(pool._processes.values())  # type: ignore[attr-defined]
        futures = [pool.submit(_sleep_then, i, 0.2) for i in range(4)]
        assert {pool.submit(_sigint_disposition).result() for _ in range(4)} == {"ignored"}
    assert [f.result() for f in futures] == [0, 1, 2, 3]
    assert len(processes) == 2 and not any(p.is_alive() for p in processes)
    assert signal.getsignal(signal.SIGINT) is known_sigint_handler  # the parent's own handler is back


_INTERRUPTED_SCRIPT = """
import multiprocessing as mp, sys, time
from pathlib import Path
from murk._workers import die_with_parent, worker_pool
from tests.test_workers import _mark_then_sleep
if __name__ == "__main__":
    marks = sys.argv[1]
    try:
        with worker_pool(2, mp_context=mp.get_context("spawn"), initializer=die_with_parent) as pool:
            procs = list(pool._processes.values())
            for i in range(6):
                pool.submit(_mark_then_sleep, i, 600.0, marks)  # ten minutes each, were they waited for
            while len(list(Path(marks).iterdir())) < 2:  # both workers are busy (however long they take to start)
                time.sleep(0.05)
            raise KeyboardInterrupt
    except KeyboardInterrupt:
        print("stopped", len(procs), "workers", flush=True)
        sys.exit(130)
"""


def test_an_error_in_the_block_stops_busy_workers_and_the_process_exits(tmp_path: Path) -> None:
    script = tmp_path / "interrupted.py"
    script.write_text(_INTERRUPTED_SCRIPT)
    root = Path(__file__).resolve().parent.parent
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root / "src"), str(root)])}
    # Were the shutdown to wait for the workers' items, or to leave them waiting for work, this would hang
    # (the interpreter joins the pool's threads at exit): the timeout turns that into a failure.
    marks = tmp_path / "marks"
    marks.mkdir()
    r = subprocess.run([sys.executable, str(script), str(marks)], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 130, r.stderr[-2000:]
    assert "stopped 2 workers" in r.stdout  # both were started up front and busy when the error came
    assert len(list(marks.iterdir())) == 2  # one item each, and no other item started after the error


def test_sigint_ignored_restores_the_previous_handler(known_sigint_handler: Callable[[int, object], None]) -> None:
    with sigint_ignored():
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
    assert signal.getsignal(signal.SIGINT) is known_sigint_handler
