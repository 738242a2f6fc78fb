"""The sources of ``murk live``: a camera, a video file played at its own rate, a stream URL, or a ROS bag topic
replayed at its recorded speed, each frame stamped with its capture time and its source time.

The readers are murk's own (:class:`murk.io.video.CaptureSource`, :class:`murk.io.rosbag.BagSource`);
:class:`PacedSource` wraps one and adds what a live view needs:

- pacing: a file is delivered at its frame rate (frame ``i`` at ``start + i / fps``), a bag at the spacing of
  its record times; cameras and streams are delivered as they arrive (they pace themselves);
- stamps: ``capture_ns`` (wall clock, nanoseconds since the epoch, when the frame left the source: the start of
  the glass-to-page latency) and ``source_ns`` (the frame's own time: a bag message's header stamp, a file's
  playback start plus its position, a camera's capture time), what Foxglove receives;
- ``loop``: a file or bag starts again at its end (demos, benchmarks);
- a prompt stop: :meth:`PacedSource.stop` interrupts the wait for the next frame.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from murk.io.video import DEFAULT_FPS, Frame, FrameSource


@dataclass(frozen=True)
class LiveFrame(Frame):
    """A :class:`murk.io.video.Frame` with its capture time and its source time (nanoseconds since the epoch)."""

    capture_ns: int = 0
    source_ns: int = 0
    frame_id: str = ""


def open_live_source(spec: str, *, topic: str | None = None) -> FrameSource:
    """The reader for ``spec``: a camera index (``0``), a video file, a stream URL, or a ROS bag with ``topic``.

    Raises:
        InputFileError: nothing usable at ``spec`` (named); a bag without ``topic`` lists its image topics.
        ValueError: ``topic`` given for a source that is not a bag.
    """
    from murk.io.rosbag import BagSource, is_bag
    from murk.io.video import open_source

    if is_bag(spec):
        return BagSource(spec, topic)
    if topic is not None:
        raise ValueError(f"--topic {topic}: {spec} is not a ROS bag (--topic selects the image topic of a bag)")
    return open_source(spec)


class PacedSource(FrameSource):
    """``source`` delivered in real time with stamped :class:`LiveFrame` objects (see the module docstring).

    Args:
        source: the reader (ownership passes: closing this closes it).
        reopen: builds a fresh reader for ``loop`` (files and bags).
        loop: start again at the end of a file or bag.
    """

    def __init__(
        self, source: FrameSource, *, reopen: Callable[[], FrameSource] | None = None, loop: bool = False
    ) -> None:
        self.source = source
        self.name = source.name
        self.label = str(getattr(source, "label", source.name))
        self.live = source.live
        self.fps = source.fps
        self.frame_count = None if loop else source.frame_count
        self.loop = loop and not source.live and callable(reopen)
        self._reopen = reopen
        self._stop = threading.Event()
        self._start_wall_ns: int | None = None
        self._start_mono = 0.0
        self._first_log_ns: int | None = None
        self._index = 0
        self._base_s = 0.0  # playback time at which the current pass over a looped file or bag started
        self._last_pos_s = 0.0

    @property
    def end_reason(self) -> str | None:  # type: ignore[override]
        return self.source.end_reason

    def stop(self) -> None:
        """Interrupt a wait for the next frame; :meth:`read` then returns None."""
        self._stop.set()

    def read(self) -> LiveFrame | None:
        while True:
            if self._stop.is_set():
                return None
            frame = self.source.read()
            if frame is not None:
                break
            if not (self.loop and self.source.end_reason == "end"):
                return None
            self.source.close()
            self.source = self._reopen()  # type: ignore[misc]
            self._base_s = self._last_pos_s + 1.0 / (self.fps or DEFAULT_FPS)
            self._first_log_ns = None
        pos_s = self._position_s(frame)
        self._last_pos_s = pos_s
        if self._start_wall_ns is None:
            self._start_wall_ns, self._start_mono = time.time_ns(), time.perf_counter()
        if not self.live:
            wait = self._start_mono + pos_s - time.perf_counter()
            if wait > 0 and self._stop.wait(wait):
                return None
        capture_ns = time.time_ns()
        stamp = int(getattr(frame, "stamp_ns", 0) or 0)
        if stamp:
            source_ns = stamp
        elif self.live:
            source_ns = capture_ns
        else:
            source_ns = self._start_wall_ns + round(pos_s * 1e9)
        index = self._index
        self._index += 1
        return LiveFrame(
            index, frame.image, frame.error, capture_ns, source_ns, str(getattr(frame, "frame_id", "") or "")
        )

    def _position_s(self, frame: Frame) -> float:
        """Playback position of ``frame`` in seconds: a bag's record time since its first message, else the
        frame's index over the frame rate."""
        log_ns = int(getattr(frame, "log_time_ns", 0) or 0)
        if log_ns:
            if self._first_log_ns is None:
                self._first_log_ns = log_ns
            return self._base_s + (log_ns - self._first_log_ns) / 1e9
        return self._base_s + frame.index / (self.fps or DEFAULT_FPS)

    def close(self) -> None:
        self._stop.set()
        self.source.close()


def reopener(spec: str, topic: str | None) -> Callable[[], FrameSource]:
    """A function opening ``spec`` again (for ``loop``)."""
    return lambda: open_live_source(spec, topic=topic)


def describe(spec: str, source: FrameSource) -> str:
    """One line for the terminal and the page: what the source is and its rate."""
    kind = "camera" if spec.strip().isdigit() and not Path(spec).exists() else "stream" if source.live else "file"
    if hasattr(source, "topic"):
        kind = "ROS bag"
    rate = f"{source.fps:.3g} frames/s" if source.fps else "frame rate unknown"
    return f"{kind} {getattr(source, 'label', source.name)} ({rate})"
