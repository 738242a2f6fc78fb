"""Decode the next frames in a background thread while the caller restores the current one.

A :class:`ReadAhead` wraps any :class:`~murk.io.video.FrameSource`. Decoding (OpenCV and PyAV release the GIL)
then overlaps with restoration and encoding, so on 2 cores the frame rate is set by the slowest stage rather
than by the sum of the stages.

Two policies:

- finite sources (files, bags): a bounded queue (``depth`` frames); the reader waits when it is full, so no
  frame is ever lost;
- live sources (cameras, streams; ``drop_late``): only the NEWEST decoded frame waits. When the source delivers
  faster than murk restores, the frame that was waiting is replaced and counted in :attr:`ReadAhead.dropped`,
  so the output stays current instead of falling further and further behind the camera. A live source that is
  slower than restoration loses nothing.
"""

from __future__ import annotations

import threading
from collections import deque

from murk.io.video import Frame, FrameSource

JOIN_TIMEOUT_S = 15.0
"""How long :meth:`ReadAhead.close` waits for a read in progress (a stream read times out after 10 s)."""


class ReadAhead(FrameSource):
    """``source`` read ahead in a daemon thread; see the module docstring.

    Args:
        source: the frames (ownership passes: closing this closes ``source``).
        depth: frames decoded ahead for finite sources (>= 1).
        drop_late: replace a waiting frame by a newer one (default: ``source.live``).

    Exceptions raised by ``source.read`` in the thread are raised again by :meth:`read`.
    """

    def __init__(self, source: FrameSource, *, depth: int = 2, drop_late: bool | None = None) -> None:
        if depth < 1:
            raise ValueError(f"depth: expected >= 1, got {depth}")
        self.source = source
        self.name = source.name
        self.live = source.live
        self.fps = source.fps
        self.frame_count = source.frame_count
        self.label = getattr(source, "label", source.name)
        self.drop_late = source.live if drop_late is None else drop_late
        self.depth = 1 if self.drop_late else depth
        self.dropped = 0
        """Frames decoded but replaced by a newer one before they were read (``drop_late`` only)."""
        self._buffer: deque[Frame] = deque()
        self._cond = threading.Condition()
        self._finished = False
        self._stop = False
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name=f"murk-read-{source.name}", daemon=True)
        self._thread.start()

    @property
    def end_reason(self) -> str | None:  # type: ignore[override]
        return self.source.end_reason if self._finished else None

    def _run(self) -> None:
        try:
            while True:
                with self._cond:
                    while not self.drop_late and len(self._buffer) >= self.depth and not self._stop:
                        self._cond.wait()
                    if self._stop:
                        return
                frame = self.source.read()  # outside the lock: the caller keeps reading what is buffered
                with self._cond:
                    if frame is None:
                        return
                    if self.drop_late and self._buffer:
                        self._buffer.popleft()
                        self.dropped += 1
                    self._buffer.append(frame)
                    self._cond.notify_all()
        except BaseException as exc:  # re-raised in the caller's thread by read()
            with self._cond:
                self._error = exc
        finally:
            with self._cond:
                self._finished = True
                self._cond.notify_all()

    def read(self) -> Frame | None:
        with self._cond:
            while not self._buffer and not self._finished:
                self._cond.wait()
            if self._buffer:
                frame = self._buffer.popleft()
                self._cond.notify_all()
                return frame
            if self._error is not None:
                error, self._error = self._error, None
                raise error
            return None

    def stop(self) -> None:
        """Stop reading ahead; waits for a read in progress (at most :data:`JOIN_TIMEOUT_S`). The source stays
        open (its owner closes it)."""
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        self._thread.join(JOIN_TIMEOUT_S)

    def close(self) -> None:
        """:meth:`stop`, then close the source (left to the process's exit if a read never returned)."""
        self.stop()
        if not self._thread.is_alive():
            self.source.close()
