"""What the image job and the frame job of ``murk enhance`` share: the output options, the report (a
:class:`murk.io.jobs.JobSummary` with stage timings), one restore call for a numpy batch, and the depth outputs.

Timing: :class:`EnhanceReport` accumulates read (decode + conversion), restore and write (encode + files)
seconds, reported as milliseconds per frame, and frames per second over the wall time.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol, TypeVar

import numpy as np

from murk.enhance.choices import ImageFormat, VideoBackendChoice
from murk.enhance.preview import DEPTH_PREVIEW_RANGE_M, colorize_depth
from murk.enhance.restorer import Restored, Restorer, device_type
from murk.errors import InputFileError, ShapeError
from murk.io.depth import write_depth_png
from murk.io.images import write_rgb
from murk.io.jobs import JobSummary

SIXTEEN_BIT_SUFFIXES = (".png", ".tif", ".tiff")

ESTIMATES_NAME = "estimates.jsonl"
"""The file of an output folder that receives what a method estimated per image or frame (``Restored.facts``)."""

ProgressFn = Callable[["EnhanceReport"], None]
StopFn = Callable[[], bool]
_F_co = TypeVar("_F_co", covariant=True)


@dataclass(frozen=True)
class OutputOptions:
    """How outputs are written.

    Attributes:
        format: image format of outputs (``png``/``jpg``); None keeps each input's format (images) or writes
            ``jpg`` (frames of videos/streams).
        side_by_side: write input|output panels instead of the output alone.
        overwrite: redo outputs that exist (default: skip them, so a rerun resumes).
        depth: write depth maps and previews when the method returns depth.
        depth_video: also write a coloured depth video beside a video output (``<stem>_depth.<ext>``).
        jpeg_quality: JPEG quality of image outputs.
        video_backend: ``opencv``, ``av`` (PyAV) or ``auto`` (PyAV for live recordings when installed, so a
            killed recording stays playable; OpenCV otherwise).
        fps: frame rate of video outputs; None uses the source's (25 when it reports none).
        depth_range_m: fixed (near, far) range of the depth colour previews.
    """

    format: ImageFormat | None = None
    side_by_side: bool = False
    overwrite: bool = False
    depth: bool = True
    depth_video: bool = False
    jpeg_quality: int = 95
    video_backend: VideoBackendChoice = "auto"
    fps: float | None = None
    depth_range_m: tuple[float, float] = DEPTH_PREVIEW_RANGE_M

    def __post_init__(self) -> None:
        if self.format not in (None, "png", "jpg"):
            raise ValueError(f"format: expected 'png' or 'jpg', got {self.format!r}")
        if self.video_backend not in ("auto", "opencv", "av"):
            raise ValueError(f"video_backend: expected 'auto', 'opencv' or 'av', got {self.video_backend!r}")
        if not 1 <= int(self.jpeg_quality) <= 100:
            raise ValueError(f"jpeg_quality: expected 1..100, got {self.jpeg_quality}")
        if self.fps is not None and not (np.isfinite(self.fps) and self.fps > 0):
            raise ValueError(f"fps: expected a finite number > 0, got {self.fps}")


@dataclass
class EnhanceReport(JobSummary):
    """The job summary of an enhance run (:class:`murk.io.jobs.JobSummary`) with its timings: ``failed``
    counts records written to ``errors.jsonl``."""

    command: str = "enhance"
    total: int | None = None
    read_s: float = 0.0
    restore_s: float = 0.0
    write_s: float = 0.0
    stopped: bool = False
    dropped: int = 0
    """Live sources: frames replaced by a newer one while restoration was busy (see murk.io.readahead)."""
    outputs: list[Path] = field(default_factory=list)

    @property
    def fps(self) -> float:
        """Processed frames per second of wall time."""
        return self.processed / self.wall_s if self.wall_s > 0 else 0.0

    def stage_ms(self) -> dict[str, float]:
        """Milliseconds per processed frame spent reading, restoring and writing."""
        n = max(self.processed, 1)
        return {"read": 1e3 * self.read_s / n, "restore": 1e3 * self.restore_s / n, "write": 1e3 * self.write_s / n}

    def tick(self) -> None:
        """Stamp the wall time so far (:meth:`JobSummary.finish`)."""
        self.finish()


INPUT_ERRORS = (InputFileError, ValueError, OSError)
RESTORE_ERRORS = (ValueError, RuntimeError, MemoryError)


class Reads(Protocol[_F_co]):
    """A source of frames read one at a time (a video, stream or bag source): None after the last one."""

    def read(self) -> _F_co | None: ...


def read_frames(
    source: Reads[_F_co], report: EnhanceReport, should_stop: StopFn | None, max_frames: int | None
) -> Iterator[_F_co]:
    """The frames of ``source`` until it ends, a stop request (``report.stopped`` is set) or ``max_frames``
    read; the time spent reading goes to ``report.read_s``. The reading loop of every frame job."""
    n_read = 0
    while True:
        if should_stop and should_stop():
            report.stopped = True
            return
        if max_frames is not None and n_read >= max_frames:
            return
        t0 = time.perf_counter()
        frame = source.read()
        report.read_s += time.perf_counter() - t0
        if frame is None:
            return
        n_read += 1
        yield frame


def restore_batch(restorer: Restorer, images: np.ndarray) -> Restored:
    """Run the restorer on a numpy batch; on CUDA through the tensor path (pinned upload, one download). A method
    on the CPU runs its numpy path without torch being imported here (the classical methods never load it)."""
    if device_type(restorer) == "cuda":
        import torch

        device = restorer.device
        x = torch.from_numpy(np.ascontiguousarray(images)).pin_memory().to(device, non_blocking=True)
        out = restorer.restore_tensor(x.permute(0, 3, 1, 2))
        imgs = out.images.detach().float().clamp(0, 1).permute(0, 2, 3, 1).cpu().numpy()
        depth = None if out.depth_m is None else out.depth_m.detach().float()[:, 0].cpu().numpy()
        result = Restored(imgs, depth)
    else:
        result = restorer.restore(images)
    b = images.shape[0]
    if result.images.ndim != 4 or result.images.shape[0] != b or result.images.shape[3] != 3:
        raise ShapeError(f"restorer {restorer.name}: returned images of shape {result.images.shape} for {images.shape}")
    if result.depth_m is not None and result.depth_m.shape != result.images.shape[:3]:
        raise ShapeError(f"restorer {restorer.name}: depth shape {result.depth_m.shape} != {result.images.shape[:3]}")
    return result


def write_depth_outputs(out_dir: Path, stem: str, depth_m: np.ndarray, options: OutputOptions) -> None:
    """``depth/<stem>.png`` (uint16 millimetres) and ``depth_preview/<stem>.jpg`` (fixed colour range)."""
    write_depth_png(out_dir / "depth" / f"{stem}.png", depth_m)
    preview = colorize_depth(depth_m, options.depth_range_m)
    write_rgb(out_dir / "depth_preview" / f"{stem}.jpg", preview, jpeg_quality=options.jpeg_quality)


def without_path(exc: BaseException, path: Path) -> str:
    """The message of ``exc`` without a leading ``"<path>: "`` (the error record holds the path)."""
    text = str(exc)
    prefix = f"{path}: "
    return text[len(prefix) :] if text.startswith(prefix) else text
