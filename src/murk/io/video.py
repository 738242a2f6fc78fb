"""Video at the I/O edge: frame sources (video files, cameras, network streams) and video sinks.

Sources yield :class:`Frame` objects holding uint8 RGB (H, W, 3) arrays; a frame that cannot be decoded is
yielded with ``image=None`` and an ``error`` so that a caller can record it and carry on. Reading uses OpenCV's
``VideoCapture`` (its FFmpeg backend reads files, ``rtsp://``/``http://`` streams and MJPEG over HTTP; V4L2
reads cameras by index).

Sinks take uint8 RGB frames. :class:`VideoSink` writes with OpenCV's ``VideoWriter`` (``mp4v`` for
``.mp4``/``.mov``/``.m4v``/``.mkv``, ``MJPG`` for ``.avi``) or with PyAV (the optional ``video`` extra:
H.264 in fragmented MP4, written and flushed packet by packet). Two write modes:

- ``atomic=True`` (finite inputs): frames go to a temporary file that is renamed onto the target by
  :meth:`VideoSink.close`; a killed run leaves no half-written output, only a ``.murk-tmp-`` file.
- ``atomic=False`` (live streams): frames go straight to the target. With the PyAV backend and MP4/MOV the
  file is fragmented (a fragment per keyframe, one keyframe per second) and flushed, so a killed recording
  stays playable up to its last second; MKV and AVI are readable without their index. OpenCV's writer
  buffers and writes the MP4 index only on close, so a killed OpenCV MP4 recording is not playable.

Codecs need even frame sizes: odd widths/heights are padded by one replicated pixel row/column.

Write errors: a full disk raises :class:`murk.errors.OutputError` ``"PATH: no space left on device"`` (the
mechanism of :mod:`murk.io.atomic`). PyAV reports it from ``write``/``close``; OpenCV's writer reports nothing
(its ``write`` returns nothing and ``release`` ignores the muxer's errors), so :meth:`VideoSink.close` counts
the frames of the finished file and refuses a file that does not hold every frame written. An atomic sink then
deletes its temporary file: no truncated video is ever left under the final name.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import re
import shutil
import uuid
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Literal, TypeVar
from urllib.parse import urlsplit, urlunsplit

import cv2
import numpy as np

from murk.errors import InputFileError, OutputError, ShapeError
from murk.io.atomic import TMP_PREFIX, make_output_folder, no_space_as_error, no_space_error
from murk.io.images import swap_red_blue

VIDEO_SUFFIXES = (".mp4", ".m4v", ".mov", ".mkv", ".avi", ".mpg", ".mpeg", ".wmv", ".webm", ".ts", ".mts", ".flv")
"""File suffixes read as video."""
WRITABLE_VIDEO_SUFFIXES = (".mp4", ".m4v", ".mov", ".mkv", ".avi")
"""File suffixes :class:`VideoSink` can write."""
STREAM_SCHEMES = ("rtsp", "rtsps", "rtmp", "http", "https", "udp", "tcp", "srt")
"""URL schemes read as live streams."""
DEFAULT_FPS = 25.0
"""Frame rate used when a source does not report a plausible one."""
LOW_SPACE_BYTES = 16 * 2**20
"""A finished video that lacks frames on a device with less free space than this failed for lack of space."""

VideoBackend = Literal["opencv", "av"]


@dataclass(frozen=True)
class Frame:
    """One frame of a source: ``image`` uint8 RGB (H, W, 3), or None with ``error`` when it could not be decoded."""

    index: int
    image: np.ndarray | None
    error: str | None = None


_Source = TypeVar("_Source", bound="FrameSource")


class FrameSource(ABC):
    """A sequence of frames with metadata. Iterate it (or call :meth:`read` until it returns None); close it,
    or use it as a context manager.

    Attributes:
        name: a file-name-safe label used to name per-frame outputs.
        live: True for cameras and network streams (no known length; an end is a disconnect).
        fps: reported frame rate, or None when unknown/implausible.
        frame_count: announced number of frames, or None when unknown (always None for live sources).
        end_reason: after the last frame: ``"end"``, ``"disconnected"``, or a description of an early end.
    """

    name: str = "frames"
    live: bool = False
    fps: float | None = None
    frame_count: int | None = None
    end_reason: str | None = None

    @abstractmethod
    def read(self) -> Frame | None:
        """The next frame, or None after the last one."""

    def close(self) -> None:  # noqa: B027 (optional hook: sources without resources need not override it)
        """Release the underlying device or file."""

    def __iter__(self) -> Iterator[Frame]:
        while (frame := self.read()) is not None:
            yield frame

    def __enter__(self: _Source) -> _Source:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


class CaptureSource(FrameSource):
    """Frames from OpenCV's ``VideoCapture``: a video file, a camera index, or a stream URL.

    A failed read is retried: if a later frame decodes, each failed one is yielded as a broken frame (the
    video continues); after ``max_failures`` consecutive failures the source ends. A file that ends before its
    announced frame count gets an ``end_reason`` saying so.

    Raises:
        InputFileError: the file, camera or URL cannot be opened (URL credentials are not repeated).
    """

    def __init__(
        self,
        target: str | int | Path,
        *,
        live: bool | None = None,
        name: str | None = None,
        max_failures: int | None = None,
        timeout_s: float = 10.0,
    ) -> None:
        if isinstance(target, Path):
            target = str(target)
        is_camera = isinstance(target, int)
        is_url = isinstance(target, str) and is_stream_url(target)
        self.live = bool(is_camera or is_url) if live is None else live
        self.label = f"camera {target}" if is_camera else redact_url(str(target)) if is_url else str(target)
        self.name = name or default_name(target)
        if isinstance(target, str) and not is_url and not Path(target).is_file():
            raise InputFileError(target, "video file not found")
        with _quiet_opencv():  # our error names the input; OpenCV's backend warnings add nothing
            if is_url:
                ms = int(timeout_s * 1000)
                params = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, ms, cv2.CAP_PROP_READ_TIMEOUT_MSEC, ms]
                cap = cv2.VideoCapture(target, cv2.CAP_FFMPEG, params)
            else:
                cap = cv2.VideoCapture(target)
        if not cap.isOpened():
            cap.release()
            what = "camera" if is_camera else "stream" if is_url else "video"
            todo = {
                "camera": "check the index (ls /dev/video*) and that no other program holds the camera",
                "stream": "check the URL and that the stream is up (e.g. with ffplay URL)",
                "video": "check that the file plays (e.g. with ffprobe); convert it to .mp4 (H.264) if not",
            }[what]
            raise InputFileError(self.label, f"cannot open {what} (not found, unsupported or not responding); {todo}")
        self._cap = cap
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        self.fps = fps if math.isfinite(fps) and 0.5 <= fps <= 1000 else None
        count = float(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self.frame_count = int(count) if not self.live and math.isfinite(count) and 0 < count < 1e9 else None
        self.max_failures = max_failures if max_failures is not None else (3 if self.live else 10)
        self._index = 0
        self._pending: deque[Frame] = deque()
        self._done = False

    def read(self) -> Frame | None:
        if self._pending:
            return self._pending.popleft()
        if self._done:
            return None
        failed: list[int] = []
        while len(failed) < self.max_failures:
            index = self._index + len(failed)
            ok, bgr = self._cap.read()
            if ok and bgr is not None and bgr.size:
                self._pending.extend(Frame(i, None, "frame could not be decoded") for i in failed)
                self._pending.append(Frame(index, _bgr_to_rgb(bgr)))
                self._index = index + 1
                return self._pending.popleft()
            if not failed and self.frame_count is not None and index >= self.frame_count:
                break  # the announced end
            failed.append(index)
        self._done = True
        if self.live:
            self.end_reason = "disconnected or ended"
        elif self.frame_count is not None and self._index < self.frame_count:
            self.end_reason = f"video ended after {self._index} of {self.frame_count} announced frames"
        else:
            self.end_reason = "end"
        return None

    def close(self) -> None:
        self._cap.release()


def is_stream_url(target: str) -> bool:
    """True for ``rtsp://``, ``http://`` and other stream URLs (see :data:`STREAM_SCHEMES`)."""
    return bool(re.match(rf"^({'|'.join(STREAM_SCHEMES)})://", target.strip(), flags=re.IGNORECASE))


def redact_url(url: str) -> str:
    """The URL without its ``user:password@`` part (safe to print and log)."""
    parts = urlsplit(url)
    if parts.username is None and parts.password is None:
        return url
    host = parts.hostname or ""
    netloc = f"{host}:{parts.port}" if parts.port else host
    return urlunsplit((parts.scheme, netloc, parts.path, parts.query, parts.fragment))


def default_name(target: str | int | Path) -> str:
    """A file-name-safe label: the file stem, ``camera0``, or host and path of a URL. Letters and digits of any
    script are kept (``tauchgang ü`` -> ``tauchgang_ü``), so that two videos whose names differ only there get
    distinct frame names; white space and punctuation other than ``.``, ``_`` and ``-`` become ``_``."""
    if isinstance(target, int):
        return f"camera{target}"
    target = str(target)
    if is_stream_url(target):
        parts = urlsplit(target)
        raw = f"{parts.hostname or 'stream'}{parts.path}"
    else:
        raw = Path(target).stem
    name = re.sub(r"[^\w.-]+", "_", raw).strip("._")
    return name[:80] or "stream"


def open_source(target: str | int | Path) -> CaptureSource:
    """Open a video file, a camera (an int, or a string of digits that is not an existing file) or a URL."""
    if isinstance(target, str) and target.strip().isdigit() and not Path(target).exists():
        return CaptureSource(int(target.strip()))
    return CaptureSource(target)


@contextlib.contextmanager
def _quiet_opencv() -> Iterator[None]:
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    try:
        yield
    finally:
        cv2.utils.logging.setLogLevel(level)


def _bgr_to_rgb(bgr: np.ndarray) -> np.ndarray:
    if bgr.ndim == 2:
        return np.ascontiguousarray(np.repeat(bgr[:, :, None], 3, axis=2))
    if bgr.shape[2] == 3:  # the same bytes as numpy's copy of the reversed view, 40x faster (swap_red_blue)
        return swap_red_blue(bgr)
    return np.ascontiguousarray(bgr[:, :, 2::-1])


# ----------------------------------------------------------------------------------------------------------
# Sinks
# ----------------------------------------------------------------------------------------------------------


class VideoSink:
    """Write uint8 RGB frames of one size to a video file (see the module docstring for modes and backends).

    Args:
        path: target file; the suffix picks the container (``.mp4``, ``.m4v``, ``.mov``, ``.mkv``, ``.avi``).
        fps: frame rate written in the container.
        size: (width, height) of the frames; odd values are padded to even.
        backend: ``"opencv"`` or ``"av"`` (PyAV, optional dependency).
        atomic: write to a temporary file renamed on :meth:`close` (True), or straight to ``path`` (False).

    Raises:
        ValueError: unsupported suffix, bad fps/size, PyAV missing, or the writer cannot be opened.
    """

    def __init__(
        self,
        path: str | Path,
        fps: float,
        size: tuple[int, int],
        *,
        backend: VideoBackend = "opencv",
        atomic: bool = True,
    ) -> None:
        self.path = Path(path)
        suffix = self.path.suffix.lower()
        if suffix not in WRITABLE_VIDEO_SUFFIXES:
            raise ValueError(f"{self.path}: expected a video suffix {', '.join(WRITABLE_VIDEO_SUFFIXES)}")
        if not (math.isfinite(fps) and fps > 0):
            raise ValueError(f"fps: expected a finite number > 0, got {fps}")
        w, h = (int(v) for v in size)
        if w < 1 or h < 1:
            raise ValueError(f"size: expected (width, height) >= 1, got {size}")
        if backend not in ("opencv", "av"):
            raise ValueError(f"backend: expected 'opencv' or 'av', got {backend!r}")
        self.fps = float(fps)
        self.size = (w, h)
        self.backend = backend
        self.atomic = atomic
        self.frames_written = 0
        self._even = (w + w % 2, h + h % 2)
        make_output_folder(self.path.parent)
        self._target = (
            self.path.with_name(f"{TMP_PREFIX}{uuid.uuid4().hex[:12]}-{self.path.name}") if atomic else self.path
        )
        self._closed = False
        if backend == "opencv":
            self._open_opencv(suffix)
        else:
            self._open_av(suffix)

    def _open_opencv(self, suffix: str) -> None:
        fourcc = cv2.VideoWriter_fourcc(*("MJPG" if suffix == ".avi" else "mp4v"))  # type: ignore[attr-defined]
        self._writer = cv2.VideoWriter(str(self._target), fourcc, self.fps, self._even)
        if not self._writer.isOpened():
            self._writer.release()
            with contextlib.suppress(FileNotFoundError):
                self._target.unlink()
            raise ValueError(
                f"{self.path}: OpenCV cannot open a video writer for this file; try .mp4 or .avi, or --video-backend av"
            )

    def _open_av(self, suffix: str) -> None:
        try:
            import av
        except ImportError:
            raise ValueError("backend 'av' needs PyAV: pip install 'murk[video]'") from None
        options = {"flush_packets": "1"}
        if suffix in (".mp4", ".m4v", ".mov"):
            options["movflags"] = "frag_keyframe+empty_moov+default_base_moof"
        self._container = av.open(str(self._target), "w", options=options)
        rate = _rate(self.fps)
        gop = max(1, round(self.fps))
        if suffix == ".avi":
            stream = self._container.add_stream("mjpeg", rate=rate)
            stream.pix_fmt = "yuvj420p"
            stream.options = {"q:v": "3"}
        elif "libx264" in av.codecs_available:
            stream = self._container.add_stream("libx264", rate=rate)
            stream.pix_fmt = "yuv420p"
            stream.options = {"crf": "18", "preset": "veryfast", "tune": "zerolatency", "g": str(gop)}
        else:
            stream = self._container.add_stream("mpeg4", rate=rate)
            stream.pix_fmt = "yuv420p"
            stream.gop_size = gop
            stream.bit_rate = int(max(2e6, 0.2 * self._even[0] * self._even[1] * self.fps))
        stream.width, stream.height = self._even
        self._stream = stream

    def write(self, image: np.ndarray) -> None:
        """Append one uint8 RGB frame of the sink's size."""
        if self._closed:
            raise ValueError(f"{self.path}: write after close")
        if not isinstance(image, np.ndarray) or image.dtype != np.uint8:
            raise TypeError(f"image: expected a uint8 numpy array, got {getattr(image, 'dtype', type(image))}")
        w, h = self.size
        if image.shape != (h, w, 3):
            raise ShapeError(f"image: expected shape {(h, w, 3)} (the sink's size), got {image.shape}")
        if self._even != self.size:
            image = np.pad(image, ((0, self._even[1] - h), (0, self._even[0] - w), (0, 0)), mode="edge")
        with no_space_as_error(self.path):
            if self.backend == "opencv":
                self._writer.write(swap_red_blue(image))
            else:
                import av

                frame = av.VideoFrame.from_ndarray(np.ascontiguousarray(image), format="rgb24")
                for packet in self._stream.encode(frame):
                    self._container.mux(packet)
        self.frames_written += 1

    def close(self) -> Path:
        """Finish the file (flush the encoder, write the index), check that it holds every frame written and,
        when atomic, rename it onto ``path``.

        Raises:
            OutputError: no space left on the device, or the finished file lacks frames. An atomic sink then
                deletes its temporary file (nothing under ``path``); a direct one keeps what it wrote.
        """
        if self._closed:
            return self.path
        try:
            with no_space_as_error(self.path):
                self._release()
                self._check_finished()
                if self.atomic:
                    _fsync(self._target)  # deferred write errors (network file systems) surface here
                    os.replace(self._target, self.path)
        except BaseException:
            if self.atomic:
                with contextlib.suppress(FileNotFoundError):
                    self._target.unlink()
            raise
        return self.path

    def _check_finished(self) -> None:
        """Refuse a finished file that does not hold the frames written (OpenCV's writer fails silently).

        The count comes from the container's index (no decoding). Measured exact for every suffix and backend
        of this module at 7.5, 23.976 and 29.97 fps; one frame of slack covers containers whose count is
        estimated from the duration. A full disk leaves a file without an index, which does not open at all.
        """
        if self.frames_written == 0:
            return
        with _quiet_opencv():
            cap = cv2.VideoCapture(str(self._target))
        try:
            found = int(cap.get(cv2.CAP_PROP_FRAME_COUNT)) if cap.isOpened() else -1
        finally:
            cap.release()
        if abs(found - self.frames_written) <= 1:
            return
        try:
            free = shutil.disk_usage(self._target.parent).free
        except OSError:
            free = None
        if free is not None and free < LOW_SPACE_BYTES:
            raise no_space_error(self.path)
        what = "cannot be read back" if found < 0 else f"holds {found}"
        raise OutputError(
            errno.EIO,
            f"the video writer failed: {self.frames_written} frames were written, the finished file {what}",
            str(self.path),
        )

    def abort(self) -> None:
        """Stop writing; an atomic sink deletes its temporary file (a direct one keeps what was written)."""
        if self._closed:
            return
        with contextlib.suppress(Exception):
            self._release()
        if self.atomic:
            with contextlib.suppress(FileNotFoundError):
                self._target.unlink()

    def _release(self) -> None:
        self._closed = True
        if self.backend == "opencv":
            self._writer.release()
        else:
            try:
                for packet in self._stream.encode(None):
                    self._container.mux(packet)
            finally:
                self._container.close()

    def __enter__(self) -> VideoSink:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        if exc_type is None:
            self.close()
        else:
            self.abort()


def av_available() -> bool:
    """True when PyAV (the optional ``video`` extra) can be imported."""
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDWR)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _rate(fps: float):
    from fractions import Fraction

    return Fraction(fps).limit_denominator(1001)
