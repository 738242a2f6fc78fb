"""ReadAhead: decode in a background thread; finite sources lose nothing, live sources keep the newest frame.

No test depends on the machine's speed: the order of reads and takes is set with events, and a wait on an event
that must come has a generous limit only so that a fault fails instead of hanging.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

from murk.io.readahead import ReadAhead
from murk.io.video import Frame, FrameSource

WAIT_S = 60.0
"""Limit of a wait for something that must happen (only a fault reaches it)."""
NOT_HAPPENING_S = 0.2
"""How long a test watches for something that must not happen (a busy machine can hide a fault, never fake one)."""


class _Counter(FrameSource):
    """Frames 0..n-1 (broken where listed); optionally raises after ``fail_after`` frames; records the reader
    thread and whether it was closed. ``asked[i]`` (when given) is set when the read of frame ``i`` starts
    (``i == n``: the read that finds the end); the read of frame ``i`` waits for ``hold[i]`` (when given)."""

    def __init__(self, n: int, *, live: bool = False, broken: tuple[int, ...] = (), fail_after: int | None = None):
        self.n, self.live, self.broken, self.fail_after = n, live, broken, fail_after
        self.name = "counter"
        self.i = 0
        self.closed = False
        self.threads: set[str] = set()
        self.asked: dict[int, threading.Event] = {}
        self.hold: dict[int, threading.Event] = {}

    def read(self) -> Frame | None:
        self.threads.add(threading.current_thread().name)
        if self.i in self.asked:
            self.asked[self.i].set()
        if self.i in self.hold:
            assert self.hold[self.i].wait(WAIT_S), f"frame {self.i} was never released"
        if self.fail_after is not None and self.i >= self.fail_after:
            raise OSError("camera unplugged")
        if self.i >= self.n:
            self.end_reason = "end"
            return None
        i = self.i
        self.i += 1
        if i in self.broken:
            return Frame(i, None, "frame could not be decoded")
        return Frame(i, np.full((2, 3, 3), i % 256, np.uint8))

    def close(self) -> None:
        self.closed = True


def test_finite_source_gives_every_frame_in_order_from_another_thread() -> None:
    src = _Counter(50, broken=(7,))
    with ReadAhead(src, depth=3) as ra:
        frames = list(ra)
        assert ra.dropped == 0 and ra.end_reason == "end"
    assert [f.index for f in frames] == list(range(50))
    assert frames[7].image is None and frames[7].error
    assert int(frames[49].image[0, 0, 0]) == 49
    assert src.closed and threading.current_thread().name not in src.threads


def test_finite_source_waits_when_the_queue_is_full() -> None:
    src = _Counter(100)
    src.asked = {1: threading.Event(), 2: threading.Event()}
    ra = ReadAhead(src, depth=2)
    assert src.asked[1].wait(WAIT_S)  # the queue fills with frames 0 and 1 ...
    assert not src.asked[2].wait(NOT_HAPPENING_S)  # ... and the reader waits instead of reading a third
    assert ra.read().index == 0  # type: ignore[union-attr]
    assert src.asked[2].wait(WAIT_S)  # room for one: the third is read
    assert [ra.read().index for _ in range(5)] == [1, 2, 3, 4, 5]  # type: ignore[union-attr]
    ra.close()


def test_live_source_keeps_the_newest_frame_and_counts_the_rest() -> None:
    src = _Counter(200, live=True)
    src.hold = {1: threading.Event()}  # frame 0 alone, until the consumer holds it
    src.asked = {200: threading.Event()}  # the read that finds the source's end
    ra = ReadAhead(src)
    assert ra.drop_late
    first = ra.read()
    assert first is not None and first.index == 0
    src.hold[1].set()
    assert src.asked[200].wait(WAIT_S)  # the source delivered frames 1..199 while the consumer was busy
    got = [first.index] + [f.index for f in ra]
    ra.close()
    assert got == [0, 199]  # only the newest frame waited; the last frame is never dropped
    assert ra.dropped == 198 and ra.dropped + len(got) == 200  # every frame was either returned or counted


def test_live_source_slower_than_the_consumer_loses_nothing() -> None:
    class Slow(_Counter):
        """Delivers frame i + 1 only once the consumer has taken frame i (slower than the consumer by
        construction, however busy the machine is)."""

        def __init__(self, n: int) -> None:
            super().__init__(n, live=True)
            self.taken = threading.Semaphore(1)

        def read(self) -> Frame | None:
            assert self.taken.acquire(timeout=WAIT_S), "the consumer never took the previous frame"
            return super().read()

    src = Slow(30)
    ra = ReadAhead(src)
    got = []
    for f in ra:
        got.append(f.index)
        src.taken.release()
    ra.close()
    assert got == list(range(30)) and ra.dropped == 0


def test_errors_in_the_reader_reach_the_caller_after_the_buffered_frames() -> None:
    ra = ReadAhead(_Counter(10, fail_after=4), depth=8)
    got = [ra.read().index for _ in range(4)]  # type: ignore[union-attr]
    assert got == [0, 1, 2, 3]
    with pytest.raises(OSError, match="unplugged"):
        ra.read()
    assert ra.read() is None
    ra.close()


def test_stop_leaves_the_source_open_and_depth_is_checked() -> None:
    src = _Counter(1000)
    ra = ReadAhead(src)
    ra.read()
    ra.stop()
    assert not src.closed
    with pytest.raises(ValueError, match="depth"):
        ReadAhead(_Counter(1), depth=0)
