"""What ``murk live`` writes, all inside its output folder: snapshots and recordings.

- :func:`write_snapshot`: the raw and the restored frame as full-resolution PNGs plus a JSON sidecar (time,
  source, frame number, method, options, capture and source times), and the depth map (uint16 millimetres PNG)
  when the method estimates one. Every file is written atomically.
- :class:`Recorder`: the restored stream as a video with :class:`murk.io.video.VideoSink`, the writer of
  ``murk enhance``, in its live mode (written straight to the file and flushed; with PyAV a fragmented MP4
  that stays playable up to its last second if the process is killed, else an MJPEG ``.avi``). Frames the
  restorer had to drop are filled with the previous restored frame, so the video keeps the source's timing.
"""

from __future__ import annotations

import datetime as dt
import json
import threading
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from murk.enhance.options import parse_spec
from murk.io.atomic import make_output_folder, write_text_atomic
from murk.io.depth import write_depth_png
from murk.io.images import write_uint
from murk.io.jsonl import json_safe
from murk.io.video import DEFAULT_FPS, VideoSink, av_available

if TYPE_CHECKING:  # the pipeline imports this module
    from murk.live.restore_loop import LiveView

MAX_FILL_S = 2.0
"""A gap between two restored frames longer than this is not filled (a paused or reconnected source)."""


def stamp(now: dt.datetime | None = None) -> str:
    """``YYYYmmdd-HHMMSS-mmm`` in UTC: the time part of output names (sorts in time order)."""
    now = now or dt.datetime.now(dt.timezone.utc)
    return now.strftime("%Y%m%d-%H%M%S-") + f"{now.microsecond // 1000:03d}"


def write_snapshot(out_dir: Path, view: LiveView, source: str) -> list[Path]:
    """Write ``snapshot_<time>_f<frame>_{raw,restored}.png`` (and ``_depth.png``) of a restored ``view`` and
    ``.json`` (its description, ``source`` the source's label, and what the method estimated on the frame under
    ``estimates`` when it reports anything: the ``water`` method's water); return the paths, the sidecar last.

    Raises:
        OutputError: the folder cannot be written or the disk is full (nothing half-written is left).
    """
    now = dt.datetime.now(dt.timezone.utc)
    make_output_folder(out_dir)
    base = out_dir / f"snapshot_{stamp(now)}_f{view.index:06d}"
    paths = [write_uint(f"{base}_raw.png", view.raw), write_uint(f"{base}_restored.png", view.restored)]
    if view.depth_m is not None:
        paths.append(write_depth_png(f"{base}_depth.png", view.depth_m))
    method, options = parse_spec(view.method)
    sidecar = {
        "time": now.isoformat(timespec="milliseconds"),
        "source": source,
        "frame": view.index,
        "method": method,
        "options": options,
        "capture_time_ns": view.capture_ns,
        "source_time_ns": view.source_ns,
        "size": [int(view.raw.shape[1]), int(view.raw.shape[0])],
        "files": {"raw": paths[0].name, "restored": paths[1].name}
        | ({"depth_mm_png": paths[2].name} if view.depth_m is not None else {}),
    } | ({"estimates": json_safe(view.facts)} if view.facts is not None else {})
    meta = Path(f"{base}.json")
    write_text_atomic(meta, json.dumps(sidecar, indent=2) + "\n")
    return [*paths, meta]


class Recorder:
    """The restored stream into ``out_dir/recording_<time>.<mp4|avi>`` (see the module docstring).

    Thread-safe: :meth:`write` (the restore thread) and :meth:`close` (a request or the shutdown) may race.
    """

    def __init__(self, out_dir: Path, fps: float | None) -> None:
        make_output_folder(out_dir)
        self.backend = "av" if av_available() else "opencv"
        self.path = out_dir / f"recording_{stamp()}{'.mp4' if self.backend == 'av' else '.avi'}"
        self.fps = fps or DEFAULT_FPS
        self.frames = 0
        self._sink: VideoSink | None = None
        self._last_index: int | None = None
        self._lock = threading.Lock()
        self._closed = False

    def write(self, index: int, image: np.ndarray) -> None:
        """Append the restored frame of source frame ``index``; skipped source frames are filled with the
        previous restored frame (up to :data:`MAX_FILL_S`)."""
        with self._lock:
            if self._closed:
                return
            if self._sink is None:
                h, w = image.shape[:2]
                self._sink = VideoSink(self.path, self.fps, (w, h), backend=self.backend, atomic=False)  # type: ignore[arg-type]
            w, h = self._sink.size
            if image.shape[:2] != (h, w):
                image = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)
            repeats = 1
            if self._last_index is not None and index > self._last_index:
                repeats = min(index - self._last_index, max(1, round(MAX_FILL_S * self.fps)))
            self._last_index = index
            for _ in range(repeats):
                self._sink.write(image)
                self.frames += 1

    def close(self) -> Path | None:
        """Finish the video (index written, file checked); None when no frame was written."""
        with self._lock:
            self._closed = True
            sink, self._sink = self._sink, None
        if sink is None:
            return None
        return sink.close()
