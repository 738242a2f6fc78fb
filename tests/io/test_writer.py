"""The background writer of ``murk synth`` (issue 29): groups keep their order, errors surface, memory is bounded."""

from __future__ import annotations

import threading
import time

import pytest

from murk.io.writer import BackgroundWriter


def test_groups_run_in_order_and_drain_waits_for_all() -> None:
    done: list[tuple[int, int]] = []
    lock = threading.Lock()

    def step(group: int, i: int) -> None:
        time.sleep(0.001 * (3 - i))  # later steps are quicker: only the group's order keeps them in sequence
        with lock:
            done.append((group, i))

    w = BackgroundWriter(threads=2, max_pending=3)
    for g in range(6):
        w.submit(*(lambda g=g, i=i: step(g, i) for i in range(3)))
    w.drain()
    assert sorted(done) == [(g, i) for g in range(6) for i in range(3)]
    for g in range(6):
        assert [i for gg, i in done if gg == g] == [0, 1, 2]
    w.close()


def test_at_most_max_pending_groups_are_queued() -> None:
    gate = threading.Event()
    w = BackgroundWriter(threads=1, max_pending=2)
    w.submit(gate.wait)
    w.submit(gate.wait)
    assert len(w._pending) == 2
    blocked = threading.Thread(target=lambda: w.submit(lambda: None))
    blocked.start()
    blocked.join(0.05)
    assert blocked.is_alive()  # the third group waits for the first (a busy machine can hide a fault, never fake one)
    gate.set()
    blocked.join(60)  # a guard against a fault only
    assert not blocked.is_alive()
    w.close()


def test_the_first_error_is_raised_after_the_other_groups_finished() -> None:
    done: list[str] = []

    def fail() -> None:
        raise OSError(28, "No space left on device")

    w = BackgroundWriter(threads=2)
    w.submit(fail)
    w.submit(lambda: done.append("b"))
    with pytest.raises(OSError, match="No space left"):
        w.drain()
    assert done == ["b"]
    w.close()


def test_zero_threads_writes_synchronously() -> None:
    done: list[int] = []
    w = BackgroundWriter(threads=0)
    w.submit(lambda: done.append(1), lambda: done.append(2))
    assert done == [1, 2]
    with pytest.raises(ValueError, match="threads >= 0"):
        BackgroundWriter(threads=-1)
