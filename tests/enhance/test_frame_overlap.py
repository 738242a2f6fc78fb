"""Frames of one video restored two at a time (issue 48, point 3): results in frame order, none lost, broken frames
and failed restorations recorded as before, the bytes of one frame at a time, and only for methods that allow it."""

from __future__ import annotations

import threading
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.data import sample_underwater_images
from murk.enhance import frame_job
from murk.enhance.api import OutputOptions, enhance_frames
from murk.enhance.frame_overlap import InOrder, one_thread_per_call, reentrant, restore_threads
from murk.enhance.frames_u8 import restore_frames
from murk.enhance.job_common import restore_batch
from murk.enhance.post import PostRestorer
from murk.enhance.restorer import Chain, Restored, Restorer, create
from murk.io import read_jsonl
from murk.io.images import to_float, to_uint
from murk.io.video import CaptureSource

from ._enhance_helpers import FakeDepth, FakeSource, make_frames, read_video

WAIT_S = 60.0
"""A guard against a fault only: every wait below is released by the other restore thread."""


def _index(images: np.ndarray) -> int:
    """The frame index that ``make_frames`` encodes in the red level (20 + 8 i), from a float32 frame."""
    return round((float(images[0, 0, 0, 0]) * 255 - 20) / 8)


class _Swapping(Restorer):
    """Inverts the frames; each even frame waits until the next (odd) one is restored, so that, restored two at a
    time, every odd frame finishes first. Frame ``fail`` raises as a broken restoration does."""

    name = "swapping"
    reentrant = True

    def __init__(self, fail: int | None = None) -> None:
        self.fail = fail
        self.done: dict[int, threading.Event] = {}
        self.finished: list[int] = []
        self.threads: set[str] = set()
        self.lock = threading.Lock()

    def _event(self, i: int) -> threading.Event:
        with self.lock:
            return self.done.setdefault(i, threading.Event())

    def restore(self, images: np.ndarray) -> Restored:
        i = _index(images)
        self.threads.add(threading.current_thread().name)
        try:
            if i % 2 == 0 and i + 1 < 9:
                assert self._event(i + 1).wait(WAIT_S), f"frame {i + 1} was not restored beside frame {i}"
            if i == self.fail:
                raise RuntimeError(f"frame {i}: the method failed")
            return Restored(1.0 - images)
        finally:
            with self.lock:
                self.finished.append(i)
            self._event(i).set()


def _two_threads(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two restore threads whatever the machine's core count (a 1-core runner would take one)."""
    monkeypatch.setattr(frame_job, "restore_threads", lambda restorer: 2)


@pytest.mark.parametrize("out_name", ["v.avi", "frames"])
def test_frames_restored_two_at_a_time_are_written_in_order_and_none_lost(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, out_name: str
) -> None:
    _two_threads(monkeypatch)
    method = _Swapping()
    out = tmp_path / out_name
    report = enhance_frames(FakeSource(make_frames(9), live=False), method, out, OutputOptions("png"))
    assert (report.processed, report.failed) == (9, 0)
    assert method.finished[:2] == [1, 0]  # restored two at a time: frame 1 finished before frame 0
    assert method.threads and all(t.startswith("murk-restore") for t in method.threads)
    pngs = sorted(out.glob("*.png"))
    written = read_video(out) if out.suffix else [cv2.imread(str(p))[:, :, ::-1] for p in pngs]  # type: ignore[index]
    red = [float(255 - f[:, :, 0].mean()) for f in written]  # inverted: the red level is 255 - (20 + 8 i)
    assert len(written) == 9
    assert [round((r - 20) / 8) for r in red] == list(range(9))


def test_two_at_a_time_records_broken_and_failed_frames_as_one_at_a_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A frame that cannot be decoded (2) and one whose restoration fails (5, finished after 6 was restored) are
    recorded in errors.jsonl in frame order and replaced by the previous frame, as with one restore thread."""
    runs = {}
    for threads in (1, 2):
        monkeypatch.setattr(frame_job, "restore_threads", lambda restorer, n=threads: n)
        out = tmp_path / str(threads) / "v.avi"
        source = FakeSource(make_frames(9), live=False, broken=(2,))
        report = enhance_frames(source, _Swapping(fail=5) if threads == 2 else _Inverting(fail=5), out)
        assert (report.processed, report.failed) == (7, 2)
        records = read_jsonl(out.parent / "errors.jsonl")
        assert [(r["frame"], r["stage"]) for r in records] == [(2, "read"), (5, "restore")]
        assert "the method failed" in records[1]["error"]
        runs[threads] = out.read_bytes()
    assert runs[1] == runs[2]


class _Inverting(Restorer):
    """What :class:`_Swapping` computes, one frame at a time, without waiting."""

    name = "inverting"

    def __init__(self, fail: int | None = None) -> None:
        self.fail = fail

    def restore(self, images: np.ndarray) -> Restored:
        if _index(images) == self.fail:
            raise RuntimeError(f"frame {self.fail}: the method failed")
        return Restored(1.0 - images)


def _clip(path: Path, n: int = 8, w: int = 640, h: int = 480) -> Path:
    """An MJPEG clip panning over a real underwater photograph."""
    photo = cv2.imread(str(sample_underwater_images()[0]))
    base = cv2.resize(photo, (w + 8 * n, h), interpolation=cv2.INTER_AREA)  # type: ignore[arg-type]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (w, h))  # type: ignore[attr-defined]
    for i in range(n):
        writer.write(np.ascontiguousarray(base[:, 8 * i : 8 * i + w]))
    writer.release()
    return path


@pytest.mark.parametrize("method", ["lite", "lite+post"])
def test_lite_two_at_a_time_writes_the_frames_of_one_at_a_time(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, method: str
) -> None:
    """Real frames through ``lite`` (and ``lite+post``): the frames written two at a time (one torch and OpenCV
    thread per call) are each the 8-bit path's restoration of their own input, and within one grey level of the
    float32 path's (``to_uint(restore(to_float(frame)))``, what ``murk enhance`` wrote before issue 48)."""
    clip = _clip(tmp_path / "clip.avi")
    restorer = create(method)
    _two_threads(monkeypatch)
    with CaptureSource(clip) as source:
        report = enhance_frames(source, restorer, tmp_path / "out", OutputOptions(format="png"))
    assert (report.processed, report.failed) == (8, 0)
    with CaptureSource(clip) as source:
        inputs = [f.image for f in source]
    for i, frame in enumerate(inputs):
        written = cv2.imread(str(tmp_path / "out" / f"clip_{i:06d}.png"))[:, :, ::-1]  # type: ignore[index]
        with one_thread_per_call():
            expected = restore_frames(restorer, frame[None]).images[0]  # type: ignore[index]
        assert np.array_equal(written, expected), f"frame {i}"
        before = to_uint(restore_batch(restorer, to_float(frame[None])).images[0], 8)  # type: ignore[index]
        assert np.abs(written.astype(np.int16) - before).max() <= 1, f"frame {i}"


def test_only_reentrant_cpu_methods_without_state_over_time_restore_two_at_a_time(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    assert restore_threads(create("lite")) == 2
    assert restore_threads(create("lite+post")) == 2
    assert restore_threads(PostRestorer()) == 2
    assert restore_threads(create("lite?temporal=0.5")) == 1  # a frame's output depends on the frames before
    assert restore_threads(create("post?temporal=0.5")) == 1
    assert restore_threads(FakeDepth()) == 1  # not declared reentrant
    assert not reentrant(Chain([create("lite"), FakeDepth()])) and reentrant(Chain([create("lite"), PostRestorer()]))
    monkeypatch.setattr("os.cpu_count", lambda: 1)
    assert restore_threads(create("lite")) == 1


def test_a_live_source_restores_one_frame_at_a_time(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A live recording keeps "newest frame wins" with one restore thread: nothing runs on the restore threads."""
    _two_threads(monkeypatch)
    method = _Inverting()
    seen: set[str] = set()
    original = method.restore

    def restore(images: np.ndarray) -> Restored:
        seen.add(threading.current_thread().name)
        return original(images)

    method.restore = restore  # type: ignore[method-assign]
    report = enhance_frames(FakeSource(make_frames(4), live=True), method, tmp_path / "rec.avi")
    assert report.processed >= 1
    assert seen == {threading.current_thread().name}


def test_in_order_returns_results_in_submission_order_and_bounds_the_pending_calls() -> None:
    gates = [threading.Event() for _ in range(3)]
    pool: InOrder[int] = InOrder(2)
    assert pool.submit(lambda: gates[0].wait(WAIT_S) and 0) == []
    assert pool.submit(lambda: 1) == []  # the first is not finished: nothing is due
    assert pool._pending[1].result(WAIT_S) == 1  # the second finished first
    gates[0].set()
    # two were pending: the oldest waited for, then the finished second handed on; the third stays pending
    assert pool.submit(lambda: gates[2].wait(WAIT_S) and 2) == [0, 1]
    assert len(pool._pending) == 1
    gates[2].set()
    assert pool.drain() == [2]
    pool.close()


def test_in_order_raises_a_call_error_when_its_result_is_due() -> None:
    def fail() -> int:
        raise RuntimeError("boom")

    pool: InOrder[int] = InOrder(2)
    with pytest.raises(RuntimeError, match="boom"):
        pool.submit(fail)
        pool.submit(lambda: 1)
        pool.drain()
    pool.close()
    inline: InOrder[int] = InOrder(1)
    assert inline.submit(lambda: 7) == [7] and inline.drain() == []
    with pytest.raises(ValueError, match="threads"):
        InOrder(-1)


def test_one_thread_per_call_restores_the_settings() -> None:
    import torch

    cv_before, torch_before = cv2.getNumThreads(), torch.get_num_threads()
    with one_thread_per_call():
        assert (cv2.getNumThreads(), torch.get_num_threads()) == (1, 1)
    assert (cv2.getNumThreads(), torch.get_num_threads()) == (cv_before, torch_before)
