"""The frame pipeline of ``murk live``: capture thread -> restore thread -> the newest restored frame.

Capture: :class:`murk.io.readahead.ReadAhead` over a :class:`murk.live.source.PacedSource` in its live policy
(``drop_late``): only the newest captured frame waits; when restoration is slower than the source, the frame
that was waiting is replaced and counted as dropped. Nothing is ever queued without bound.

Restore: one thread restores each frame it takes with the current method (:func:`murk.enhance.job_common.
restore_batch`, as ``murk enhance`` does) and publishes a :class:`LiveView` (raw and restored uint8, depth,
stamps). Readers (the web server, one thread per page) wait for a view newer than the one they have
(:meth:`LivePipeline.wait_view`) and so also skip frames when they are slower: newest wins everywhere.

The method can be switched while running (:meth:`LivePipeline.set_method`): the new restorer is built in the
caller's thread (a bad method or option raises ``ValueError`` there and the running one stays) and swapped in
between two frames; methods with a ``temporal`` weight start their average afresh.

Threads: while the method is a light one (``lite``, ``post`` and chains of them:
:func:`murk.enhance.frame_overlap.one_thread_suits`), torch and OpenCV run each call on one thread: the restore thread
holds one core and the capture and publish threads the other. Split over two threads, every step of a 1920x1080
``lite`` frame waited for the core the decoder or the JPEG encoder held (issue 48: 22.7 frames/s to the page
against 30.0, and 19.9 against 29.9 with a Foxglove client subscribed; BENCHMARKS.md). Other methods keep the
process's threads; the previous settings come back when the method changes or the pipeline stops.

Publish: a third thread encodes the page's JPEG of each restored view (:meth:`LiveView.jpeg`), then hands the view
to the readers and to the hooks, while the restore thread restores the next frame (issue 48: at 1920x1080 the
page's JPEG costs about as much as restoring with ``lite``; in one thread the two costs added up). Newest wins here
too: a view still waiting when a newer one is restored is not shown (counted in :attr:`LivePipeline.unshown`).
The page gets the raw and the restored frame as two JPEGs (:meth:`LiveView.page_jpegs`), each encoded once per
view: at most :data:`PAGE_IMAGE_PX` wide (scaled down by OpenCV's area interpolation: what the page shows, a quarter
of the pixels to encode at 1920x1080), or at full resolution when a hook publishes that image at full resolution
anyway (:class:`SharesJpegs`: Foxglove, for the topics a client subscribes to); then the page shows the hook's own
JPEG, encoded once for both (issue 48, point 5). Snapshots, recordings and the ``raw``/``restored`` JPEGs of the MJPEG
stream and Foxglove keep the full resolution. Each JPEG is encoded at most once per view and shared by every reader.
"""

from __future__ import annotations

import collections
import contextlib
import statistics
import threading
import time
from collections.abc import Callable, Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np

from murk.enhance.frame_overlap import one_thread_per_call, one_thread_suits
from murk.enhance.frames_u8 import restore_frames
from murk.enhance.job_common import RESTORE_ERRORS
from murk.enhance.restorer import Restorer
from murk.io.images import swap_red_blue, to_float, to_uint
from murk.io.jsonl import json_safe
from murk.io.readahead import ReadAhead
from murk.live.outputs import Recorder, write_snapshot
from murk.live.source import LiveFrame, PacedSource

RATE_WINDOW_S = 2.0
"""Frames per second are counted over this last stretch of time."""
LATENCY_WINDOW = 60
"""The latency shown is the median over this many last frames."""

PAGE_WIDTH_PX = 1920
"""The widest the page's raw and restored images are side by side (and the MJPEG stream's ``pair``)."""
PAGE_IMAGE_PX = PAGE_WIDTH_PX // 2
"""The widest the page's raw and restored JPEGs are each encoded (unless shared at full resolution): a 640x480
frame as it is, a 1280x720 frame at 3/4 and a 1920x1080 frame at 1/2 of its size."""
JPEG_QUALITY = 85
"""The quality of the page's JPEGs (and the default of every other reader's, so that they can be shared)."""

RestorerFactory = Callable[[str], Restorer]
FrameHook = Callable[["LiveView"], None]


@runtime_checkable
class SharesJpegs(Protocol):
    """A hook that publishes some of a view's JPEGs at full resolution (:meth:`LiveView.jpeg` at
    :data:`JPEG_QUALITY`): ``full_views()`` names which of ``raw``/``restored`` it will take of the next view. The
    publish thread encodes those at full resolution before the page is served, and the page shows them too."""

    def full_views(self) -> Collection[str]: ...


@dataclass
class LiveView:
    """One restored frame as readers see it. ``raw``/``restored`` uint8 RGB (H, W, 3); ``depth_m`` (H, W) or
    None; times in nanoseconds since the epoch: ``capture_ns`` (left the source), ``source_ns`` (the frame's own
    time), ``done_ns`` (restored)."""

    index: int
    raw: np.ndarray
    restored: np.ndarray
    depth_m: np.ndarray | None
    capture_ns: int
    source_ns: int
    done_ns: int
    method: str
    frame_id: str = ""
    facts: dict[str, Any] | None = None
    """What the method estimated on this frame (``Restored.facts``: the ``water`` method's water), or None."""
    _jpeg: dict[str, bytes] = field(default_factory=dict, repr=False)
    _lock: threading.RLock = field(default_factory=threading.RLock, repr=False)

    def jpeg(self, view: str = "pair", quality: int = JPEG_QUALITY) -> bytes:
        """The frame encoded as JPEG, once per ``view``: ``pair`` (raw | restored side by side, the MJPEG stream's
        ``pair``; at most :data:`PAGE_WIDTH_PX` wide), ``raw`` or ``restored`` (full resolution)."""
        key = f"{view}:{quality}"
        with self._lock:
            if key not in self._jpeg:
                image = {"raw": self.raw, "restored": self.restored}.get(view)
                if image is None:
                    image = page_pair(self.raw, self.restored)
                self._jpeg[key] = encode_jpeg(image, quality)
            return self._jpeg[key]

    def page_jpegs(self, full: Collection[str] = ()) -> tuple[bytes, bytes]:
        """The raw and the restored JPEG the page shows, each encoded once per view: the full-resolution JPEG
        (:meth:`jpeg`, shared) when ``full`` names it, when it is encoded already or when the frame is at most
        :data:`PAGE_IMAGE_PX` wide; else one scaled down to that width. The first call decides for the view."""
        with self._lock:
            return self._page_jpeg("raw", full), self._page_jpeg("restored", full)

    def _page_jpeg(self, view: str, full: Collection[str]) -> bytes:
        key = f"{view}@page"
        if key not in self._jpeg:
            image = self.raw if view == "raw" else self.restored
            shared = f"{view}:{JPEG_QUALITY}" in self._jpeg or image.shape[1] <= PAGE_IMAGE_PX
            if view in full or shared:
                self._jpeg[key] = self.jpeg(view)
            else:
                self._jpeg[key] = encode_jpeg(page_image(image), JPEG_QUALITY)
        return self._jpeg[key]


def page_pair(raw: np.ndarray, restored: np.ndarray, width_px: int = PAGE_WIDTH_PX) -> np.ndarray:
    """raw | restored side by side, scaled down (area interpolation, each half alike) to at most ``width_px``."""
    h, w = restored.shape[:2]
    if raw.shape[:2] != (h, w):
        raw = cv2.resize(raw, (w, h), interpolation=cv2.INTER_AREA)
    if 2 * w > width_px:
        size = (max(1, width_px // 2), max(1, round(h * width_px / (2 * w))))
        raw, restored = (cv2.resize(im, size, interpolation=cv2.INTER_AREA) for im in (raw, restored))
    return np.concatenate([raw, restored], axis=1)


def page_image(image: np.ndarray, width_px: int = PAGE_IMAGE_PX) -> np.ndarray:
    """``image`` scaled down (area interpolation) to at most ``width_px`` wide, as the page gets it."""
    h, w = image.shape[:2]
    if w <= width_px:
        return image
    return cv2.resize(image, (width_px, max(1, round(h * width_px / w))), interpolation=cv2.INTER_AREA)


def encode_jpeg(rgb: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    """uint8 RGB -> JPEG bytes."""
    ok, buf = cv2.imencode(".jpg", swap_red_blue(rgb), [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise ValueError(f"image: OpenCV could not encode a JPEG of shape {rgb.shape}")
    return buf.tobytes()


class LivePipeline:
    """Capture and restoration threads around ``source`` (see the module docstring).

    Args:
        source: the paced source (ownership passes).
        make_restorer: builds the restorer of a method spec (``"lite+post?temporal=0.8"``); raises ValueError.
        method: the first method spec.
        out_dir: where snapshots and recordings go (created on first use).
        hooks: called with every new view in the restore thread (the Foxglove publisher).
    """

    def __init__(
        self,
        source: PacedSource,
        make_restorer: RestorerFactory,
        method: str,
        out_dir: Path,
        *,
        hooks: list[FrameHook] | None = None,
    ) -> None:
        self.source = source
        self.label = source.label
        self.out_dir = Path(out_dir)
        self._make_restorer = make_restorer
        self._restorer = make_restorer(method)
        self.method = method
        self.hooks = list(hooks or [])
        self._cond = threading.Condition()
        self._view: LiveView | None = None
        self._restored_times: collections.deque[float] = collections.deque()
        self._latency_ms: collections.deque[float] = collections.deque(maxlen=LATENCY_WINDOW)
        self._stop = threading.Event()
        self._recorder: Recorder | None = None
        self._rec_lock = threading.Lock()
        self.restored = 0
        self.broken = 0
        self.failed = 0
        self.last_error: str | None = None
        self.ended: str | None = None
        """Why the source ended (``"end"``, ``"disconnected or ended"``, an error), None while it runs."""
        self.recordings: list[Path] = []
        self.recording_stopped: str | None = None
        """Why the last recording stopped by itself (a write failed: a full disk, ...); None when none did since
        a recording last started."""
        self.recording_stops = 0
        """Recordings that stopped by themselves (``murk live`` prints each one's ``recording_stopped``)."""
        self.unshown = 0
        """Restored views replaced by a newer one before the publish thread took them (newest wins); ``restored``
        counts the views shown (and handed to the hooks)."""
        self._reader = ReadAhead(source, drop_late=True)
        self._thread = threading.Thread(target=self._run, name="murk-live-restore", daemon=True)
        self._pending: LiveView | None = None
        self._pending_cond = threading.Condition()
        self._restore_done = False
        self._handed = 0  # views handed to the publish thread, and those it showed (or failed to)
        self._settled = 0
        self._publisher = threading.Thread(target=self._publish_loop, name="murk-live-publish", daemon=True)

    # -- running ---------------------------------------------------------------------------------------------

    def start(self) -> LivePipeline:
        self._publisher.start()
        self._thread.start()
        return self

    @property
    def dropped(self) -> int:
        """Captured frames replaced by a newer one before restoration took them."""
        return self._reader.dropped

    def _run(self) -> None:
        try:
            self._loop()
        except Exception as exc:  # a bug or an unexpected library error: shown as the end, never a silent freeze
            self._end(f"restoration failed ({type(exc).__name__}: {exc})")
        finally:
            with self._pending_cond:
                self._restore_done = True
                self._pending_cond.notify_all()

    def _loop(self) -> None:
        with contextlib.ExitStack() as sequence:
            active: Restorer | None = None
            while not self._stop.is_set():
                try:
                    frame = self._reader.read()
                except Exception as exc:  # the reader failed: the source is over
                    self._end(f"the source failed ({type(exc).__name__}: {exc})")
                    return
                if frame is None:
                    self._end(self.source.end_reason or "end")
                    return
                if frame.image is None:
                    self.broken += 1
                    self.last_error = f"frame {frame.index}: {frame.error or 'could not be decoded'}"
                    continue
                with self._cond:
                    restorer, method = self._restorer, self.method
                if restorer is not active:  # a new method: its average over time starts with this frame
                    sequence.close()
                    if one_thread_suits(restorer):  # lite, post: one thread per call beside capture and publish
                        sequence.enter_context(one_thread_per_call())
                    sequence.enter_context(restorer.sequence())
                    active = restorer
                self._restore(frame, restorer, method)  # type: ignore[arg-type]

    def _restore(self, frame: LiveFrame, restorer: Restorer, method: str) -> None:
        image = frame.image
        assert image is not None
        try:
            out = restore_frames(restorer, image[None])
        except RESTORE_ERRORS as exc:
            self.failed += 1
            self.last_error = f"frame {frame.index}: {method} failed ({type(exc).__name__}: {exc})"
            return
        raw = image if image.dtype == np.uint8 else to_uint(to_float(image), 8)
        view = LiveView(
            index=frame.index,
            raw=raw,
            restored=out.images[0],
            depth_m=None if out.depth_m is None else out.depth_m[0],
            capture_ns=frame.capture_ns,
            source_ns=frame.source_ns,
            done_ns=time.time_ns(),
            method=method,
            frame_id=frame.frame_id,
            facts=None if out.facts is None else out.facts[0],
        )
        with self._rec_lock:
            recorder = self._recorder
        if recorder is not None:  # every restored frame, in order (the publish thread may skip views)
            try:
                recorder.write(view.index, view.restored)
            except (OSError, ValueError) as exc:
                self.last_error = f"recording stopped: {exc}"
                self.recording_stopped = str(exc)
                self.recording_stops += 1
                self._finish_recording()
        with self._pending_cond:  # to the publish thread; newest wins
            if self._pending is not None:
                self.unshown += 1
            self._pending = view
            self._handed += 1
            self._pending_cond.notify_all()

    def _publish_loop(self) -> None:
        """The publish thread: encode the page's JPEGs of the newest restored view, show it, call the hooks."""
        while True:
            with self._pending_cond:
                while self._pending is None and not self._restore_done:
                    self._pending_cond.wait()
                view, self._pending = self._pending, None
            if view is None:
                return
            try:
                self._publish(view)
            except Exception as exc:  # an encoder failure: shown, the next view is tried
                self.last_error = f"frame {view.index}: could not be shown ({type(exc).__name__}: {exc})"
            with self._pending_cond:
                self._settled += 1
                self._pending_cond.notify_all()

    def _publish(self, view: LiveView) -> None:
        full: set[str] = set()
        for hook in self.hooks:  # the images a hook publishes at full resolution: the page shows the same JPEGs
            if isinstance(hook, SharesJpegs):
                with contextlib.suppress(Exception):
                    full.update(hook.full_views())
        view.page_jpegs(full)  # encoded before it is shown, so a waiting page gets them without delay
        now = time.perf_counter()
        with self._cond:
            self._view = view
            self.restored += 1
            self._restored_times.append(now)
            while self._restored_times and self._restored_times[0] < now - RATE_WINDOW_S:
                self._restored_times.popleft()
            self._latency_ms.append((view.done_ns - view.capture_ns) / 1e6)
            self._cond.notify_all()
        for hook in self.hooks:
            try:
                hook(view)
            except Exception as exc:  # a failing publisher never stops the live view
                self.last_error = f"{getattr(hook, '__qualname__', hook)}: {type(exc).__name__}: {exc}"

    def _end(self, reason: str) -> None:
        with self._pending_cond:  # the last restored view is shown first
            while self._handed > self._settled + self.unshown and self._publisher.is_alive():
                self._pending_cond.wait(1.0)
        with self._cond:
            self.ended = reason
            self._cond.notify_all()

    def stop(self, timeout_s: float = 20.0) -> list[Path]:
        """Stop capture and restoration, finish a running recording (a playable file); return the recordings."""
        self._stop.set()
        self.source.stop()
        self._reader.stop()
        if self._thread.is_alive():
            self._thread.join(timeout_s)
        if self._publisher.is_alive():
            self._publisher.join(timeout_s)
        self._finish_recording()
        if not self._thread.is_alive():
            with contextlib.suppress(Exception):
                self.source.close()
        with self._cond:
            if self.ended is None:
                self.ended = "stopped"
            self._cond.notify_all()
        return list(self.recordings)

    # -- readers ---------------------------------------------------------------------------------------------

    def latest(self) -> LiveView | None:
        with self._cond:
            return self._view

    def wait_view(self, after: int, timeout_s: float) -> LiveView | None:
        """The newest view with ``index > after``, waiting at most ``timeout_s``; None if none came (or the
        source ended)."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while True:
                view = self._view
                if view is not None and view.index > after:
                    return view
                left = deadline - time.monotonic()
                if left <= 0 or self.ended is not None:
                    return None
                self._cond.wait(left)

    def status(self) -> dict[str, Any]:
        """What the page shows: method, rates, latency, drops, errors, recording, the source's end, and what the method
        estimated on the latest frame (``estimates``: the ``water`` method's water; None for other methods)."""
        now = time.perf_counter()
        with self._cond:
            times = [t for t in self._restored_times if t >= now - RATE_WINDOW_S]
            span = (times[-1] - times[0]) if len(times) > 1 else 0.0
            fps = (len(times) - 1) / span if span > 0 else 0.0
            latency = statistics.median(self._latency_ms) if self._latency_ms else None
            view = self._view
        with self._rec_lock:
            recording = None if self._recorder is None else str(self._recorder.path.name)
        return {
            "source": self.label,
            "method": self.method,
            "frame": None if view is None else view.index,
            "size": None if view is None else [int(view.raw.shape[1]), int(view.raw.shape[0])],
            "restored": self.restored,
            "fps": round(fps, 2),
            "latency_ms": None if latency is None else round(latency, 1),
            "dropped": self.dropped,
            "unshown": self.unshown,
            "broken": self.broken,
            "failed": self.failed,
            "last_error": self.last_error,
            "ended": self.ended,
            "recording": recording,
            "recording_stopped": self.recording_stopped,
            "has_depth": bool(view is not None and view.depth_m is not None),
            "estimates": None if view is None or view.facts is None else json_safe(view.facts),
            "out_dir": str(self.out_dir),
        }

    # -- controls --------------------------------------------------------------------------------------------

    def set_method(self, spec: str) -> str:
        """Switch to the method ``spec`` from the next frame on; returns it.

        Raises:
            ValueError: an unknown method or option (the running method stays).
        """
        restorer = self._make_restorer(spec)
        with self._cond:
            self._restorer, self.method = restorer, spec
        return spec

    def snapshot(self) -> list[Path]:
        """Save the newest raw and restored frame (full resolution) with a JSON sidecar; returns the paths.

        Raises:
            ValueError: no frame has been restored yet.
        """
        view = self.latest()
        if view is None:
            raise ValueError("snapshot: no frame has been restored yet")
        return write_snapshot(self.out_dir, view, self.label)

    def set_recording(self, on: bool) -> Path | None:
        """Start (``on``) or stop recording the restored stream; returns the recording's path."""
        with self._rec_lock:
            if on and self._recorder is None:
                self._recorder = Recorder(self.out_dir, self.source.fps)
                self.recording_stopped = None
                return self._recorder.path
            if on:
                return self._recorder.path if self._recorder else None
        return self._finish_recording()

    def _finish_recording(self) -> Path | None:
        with self._rec_lock:
            recorder, self._recorder = self._recorder, None
        if recorder is None:
            return None
        path = recorder.close()
        if path is not None:
            self.recordings.append(path)
        return path
