"""Writing files in the background while the next image renders: a small pool of writer threads.

PNG encoding costs as much as rendering a 640x480 variant, and OpenCV's encoder and Python's file writes release
the GIL, so a writer thread runs beside the renderer on another core. :class:`BackgroundWriter` takes *groups* of
writes: the writes of one group run in order on one thread (``murk synth`` writes a variant's ``degraded`` image
last because its presence marks the variant done), different groups run in parallel. At most ``max_pending``
groups are queued (bounded memory: :meth:`submit` waits for the oldest); :meth:`drain` waits for all of them and
raises the first error (a full disk: :class:`murk.errors.OutputError`), so a caller returns only when its files
are complete. Files are written atomically by the functions given, so the bytes and the outputs are those of the
serial path.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

Write = Callable[[], Any]


class BackgroundWriter:
    """Runs groups of writes on ``threads`` threads, at most ``max_pending`` groups queued.

    ``threads=0`` writes synchronously in :meth:`submit` (the serial path, e.g. for debugging).
    """

    def __init__(self, threads: int = 2, max_pending: int = 4) -> None:
        if threads < 0 or max_pending < 1:
            raise ValueError(f"threads >= 0 and max_pending >= 1 expected, got {threads} and {max_pending}")
        self.threads = threads
        self.max_pending = max_pending
        self._pool = ThreadPoolExecutor(threads, thread_name_prefix="murk-writer") if threads else None
        self._pending: deque[Future[None]] = deque()

    def submit(self, *writes: Write) -> None:
        """Queue one group of writes (run in the order given); waits while ``max_pending`` groups are queued."""
        if self._pool is None:
            _run(writes)
            return
        while len(self._pending) >= self.max_pending:
            self._pending.popleft().result()
        self._pending.append(self._pool.submit(_run, writes))

    def drain(self) -> None:
        """Wait for every queued group; raise the first error (the remaining groups still finish first)."""
        first: BaseException | None = None
        while self._pending:
            try:
                self._pending.popleft().result()
            except BaseException as exc:  # re-raised below, after the others finished
                first = first or exc
        if first is not None:
            raise first

    def close(self) -> None:
        """Drain, then stop the threads."""
        try:
            self.drain()
        finally:
            if self._pool is not None:
                self._pool.shutdown(wait=True)


def _run(writes: tuple[Write, ...]) -> None:
    for write in writes:
        write()
