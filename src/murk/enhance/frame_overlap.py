"""Restore several frames of one video at the same time, and take the results in frame order (issue 48, point 3).

``murk enhance CLIP --out OUT.avi`` decodes frames on a read-ahead thread (:class:`murk.io.readahead.ReadAhead`)
and encodes them on a write-behind thread (:class:`murk.io.writer.BackgroundWriter`). Restoring on one thread
between them leaves the second core idle for most of a frame at HD: restoration is the slowest stage (``lite`` at
1920x1080: about 22 ms of CPU against 4 to decode and 9 to encode). :class:`InOrder` runs the restoration of
consecutive batches on :func:`restore_threads` threads; the caller takes the results in submission order, so the
writer sees the frames in their order whatever thread finished first, and at most ``max_pending`` batches are in
flight (bounded memory; the caller waits beyond).

Only a method whose output for a frame does not depend on the frames before it (no ``temporal`` weight), that runs
on the CPU, and whose every stage is known to be safe to call from two threads at once (:data:`REENTRANT`, or a
``reentrant = True`` attribute) restores frames at the same time; any other keeps one frame at a time, in order,
on the caller's thread (the ``--resume`` replay of a method with state over time relies on that order).

While frames restore at the same time, torch and OpenCV run each call on one thread (:func:`one_thread_per_call`):
the frames are the parallelism. Two frames each split over both cores would make every parallel step wait for a
core that the other frame, the decoder or the encoder holds; measured at 1920x1080 (``lite``), the whole run then
costs about 55 ms of CPU per frame against 38 with one thread per call (BENCHMARKS.md).
"""

from __future__ import annotations

import contextlib
import os
import sys
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any, Generic, TypeVar

from murk.enhance.restorer import Restorer, device_type

T = TypeVar("T")

REENTRANT = frozenset({"lite", "post"})
"""Methods whose ``restore`` may run for different frames on two threads at once: they keep no state between calls
outside a ``temporal`` average (torch's inference, OpenCV and numpy calls on the call's own arrays). A method
declares it with a ``reentrant`` attribute; these names are the built-in ones checked."""

MAX_RESTORE_THREADS = 2
"""Frames restored at the same time. Two keep both cores of the target machine busy with the decoder and the
encoder beside them (BENCHMARKS.md, "HD in real time"); more would only queue frames in memory on such a machine."""


def _parts(restorer: Restorer) -> list[Any]:
    """The restorers a composite is made of (a chain's stages, a blend's members), or the restorer itself."""
    parts = getattr(restorer, "parts", None)
    if parts is None:
        parts = getattr(restorer, "stages", None)
    return [restorer] if parts is None else list(parts)


def reentrant(restorer: Restorer) -> bool:
    """Whether ``restorer`` (every part of a chain or a blend) may restore different frames on two threads at once."""
    parts = _parts(restorer)
    if parts != [restorer]:
        return all(reentrant(p) for p in parts)
    return bool(getattr(restorer, "reentrant", getattr(restorer, "name", None) in REENTRANT))


def restore_threads(restorer: Restorer) -> int:
    """How many frames of one video ``restorer`` may restore at the same time: up to :data:`MAX_RESTORE_THREADS`
    (no more than the machine's cores) for a reentrant CPU method without state over time, else 1."""
    if restorer.carries_state or not reentrant(restorer) or not _on_cpu(restorer):
        return 1
    return max(1, min(MAX_RESTORE_THREADS, os.cpu_count() or 1))


def one_thread_suits(restorer: Restorer) -> bool:
    """Whether ``restorer`` should run each call on one torch and OpenCV thread while other threads decode and encode
    beside it (``murk live``: the capture and publish threads): a reentrant CPU method (:data:`REENTRANT`: ``lite``,
    ``post`` and chains of them, with or without a ``temporal`` weight), whose steps are too short to gain from a
    second thread that the decoder or the encoder holds. Heavier networks keep torch's threads."""
    return reentrant(restorer) and _on_cpu(restorer)


@contextlib.contextmanager
def one_thread_per_call() -> Iterator[None]:
    """Inside: torch (when it is loaded) and OpenCV use one thread per call; their previous settings after."""
    import cv2

    torch = sys.modules.get("torch")
    cv_threads = cv2.getNumThreads()
    torch_threads = torch.get_num_threads() if torch is not None else None
    cv2.setNumThreads(1)
    if torch is not None:
        torch.set_num_threads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(cv_threads)
        if torch is not None and torch_threads is not None:
            torch.set_num_threads(torch_threads)


def _on_cpu(restorer: Restorer) -> bool:
    parts = _parts(restorer)
    return device_type(restorer) == "cpu" and (parts == [restorer] or all(_on_cpu(p) for p in parts))


class InOrder(Generic[T]):
    """Calls run on ``threads`` threads; their results are returned in the order the calls were submitted.

    ``threads`` <= 1 runs each call at once on the caller's thread (:meth:`submit` returns its result). Otherwise
    at most ``max_pending`` calls (default: ``threads``) are queued or running; :meth:`submit` returns the results
    now due, oldest first: those already finished, and the oldest ones waited for while more are queued. An
    exception raised by a call is raised again when its result is due (the calls after it still run; :meth:`close`
    waits for them).
    """

    def __init__(self, threads: int, max_pending: int | None = None) -> None:
        if threads < 0:
            raise ValueError(f"threads: expected >= 0, got {threads}")
        self.threads = threads
        self.max_pending = max(1, threads if max_pending is None else max_pending)
        self._pool = ThreadPoolExecutor(threads, thread_name_prefix="murk-restore") if threads > 1 else None
        self._pending: deque[Future[T]] = deque()

    def submit(self, call: Callable[[], T]) -> list[T]:
        """Queue ``call``; return the results that are due (see the class docstring)."""
        if self._pool is None:
            return [call()]
        due = []
        while len(self._pending) >= self.max_pending:
            due.append(self._pending.popleft().result())
        self._pending.append(self._pool.submit(call))
        while self._pending and self._pending[0].done():  # finished early: hand it on now
            due.append(self._pending.popleft().result())
        return due

    def drain(self) -> list[T]:
        """Wait for every queued call; their results in order."""
        due = []
        while self._pending:
            due.append(self._pending.popleft().result())
        return due

    def close(self) -> None:
        """Drop the calls not started, wait for those running (their results and errors are discarded)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
        self._pending.clear()
