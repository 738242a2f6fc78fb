"""ReadAhead: decode in a background thread; finite sources lose nothing, live sources keep the newest frame."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from murk.io.readahead import ReadAhead
from murk.io.video import Frame, FrameSource


class _Counter(FrameSource):
    """Frames 0..n-1 (broken where listed); optionally raises after ``fail_after`` frames; records the reader
    thread and whether it was closed."""

    def __init__(self, n: int, *, live: bool = False, broken: tuple[int, ...] = (), fail_after: int | None = None):
        self.n, self.live, self.broken, self.fail_after = n, live, broken, fail_after
        self.name = "counter"
        self.i = 0
        self.closed = False
        self.threads: set[str] = set()
        self.gate = threading.Event()
        self.gate.set()

    def read(self) -> Frame | None:
        self.threads.add(threading.current_thread().name)
        self.gate.wait()
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
    ra = ReadAhead(src, depth=2)
    deadline = time.monotonic() + 5
    while src.i < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.1)
    assert src.i <= 3  # two frames buffered plus at most one decoded and waiting for room
    assert [ra.read().index for _ in range(5)] == [0, 1, 2, 3, 4]  # type: ignore[union-attr]
    ra.close()


def test_live_source_keeps_the_newest_frame_and_counts_the_rest() -> None:
    src = _Counter(200, live=True)
    src.gate.clear()
    ra = ReadAhead(src)
    assert ra.drop_late
    got = []
    src.gate.set()
    while (f := ra.read()) is not None:
        got.append(f.index)
        time.sleep(0.002)  # a consumer slower than the source
    ra.close()
    assert got == sorted(got) and len(set(got)) == len(got)
    assert got[-1] == 199  # the last frame is never dropped
    assert ra.dropped + len(got) == 200  # every decoded frame was either returned or counted as dropped
    assert ra.dropped > 0


def test_live_source_slower_than_the_consumer_loses_nothing() -> None:
    class Slow(_Counter):
        def read(self) -> Frame | None:
            time.sleep(0.003)
            return super().read()

    ra = ReadAhead(Slow(30, live=True))
    got = [f.index for f in ra]
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
