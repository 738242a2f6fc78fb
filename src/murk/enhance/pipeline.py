"""Running a restorer over images, video files and live streams (what ``murk enhance`` delegates to).

Inputs: an image, a folder of images (optionally recursive), a glob, a video file, a camera index or a stream
URL (:func:`resolve_input`). Images are restored in batches of equal size and written with their size, format
and bit depth (16-bit PNG/TIFF stays 16-bit unless another format is asked for); frames of videos and streams
are written as a video (source frame rate) or as numbered images. When a method returns depth, every output
also gets ``depth/<stem>.png`` (uint16 millimetres) and ``depth_preview/<stem>.jpg`` (fixed 0-15 m colour
range), and videos optionally a coloured depth video.

Reliability: unreadable or undecodable inputs are recorded in ``errors.jsonl`` in the output folder and
skipped (the run continues; callers exit non-zero); ``errors.jsonl`` is rewritten by every run (it lists the
failures of the latest run only); a broken video frame is recorded and replaced by the previous output frame
so the video keeps its length and timing; outputs inside the input folder are never read back as inputs, and
the input folder itself is refused as output (:func:`murk.io.paths.check_output_location`); inputs whose
outputs would share a name get distinct names (:func:`murk.io.paths.output_names`); rerunning skips images
whose output exists (``overwrite=True`` redoes them); video files are written atomically (complete or absent),
live recordings directly and flushed (see :mod:`murk.io.video`). A full disk stops the run with
:class:`murk.errors.OutputError` (``PATH: no space left on device``), never a truncated file under a final name.

Timing: :class:`EnhanceReport` accumulates read (decode + conversion), restore and write (encode + files)
seconds, reported as milliseconds per frame, and frames per second over the wall time.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np
import torch

from murk.enhance.choices import ImageFormat, VideoBackendChoice
from murk.enhance.preview import DEPTH_PREVIEW_RANGE_M, colorize_depth, side_by_side
from murk.enhance.restorer import Restored, Restorer
from murk.errors import InputFileError, OutputError, ShapeError
from murk.io.atomic import TMP_PREFIX, remove_stale_temporaries
from murk.io.depth import write_depth_png
from murk.io.images import IMAGE_SUFFIXES, list_images, read_image, to_float, to_uint, write_rgb, write_uint
from murk.io.jsonl import append_jsonl
from murk.io.listing import glob_files
from murk.io.paths import check_output_location, output_names
from murk.io.video import (
    DEFAULT_FPS,
    VIDEO_SUFFIXES,
    WRITABLE_VIDEO_SUFFIXES,
    FrameSource,
    VideoSink,
    av_available,
    is_stream_url,
    redact_url,
)

InputKind = Literal["images", "video", "stream"]
ERRORS_FILE = "errors.jsonl"
SIXTEEN_BIT_SUFFIXES = (".png", ".tif", ".tiff")
_GLOB_CHARS = set("*?[")

ProgressFn = Callable[["EnhanceReport"], None]
StopFn = Callable[[], bool]


# ----------------------------------------------------------------------------------------------------------
# Inputs and options
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class EnhanceInput:
    """What the INPUT argument designates. ``images`` and ``root`` (for relative output paths) are set for
    ``kind="images"``; ``target`` (a path, a camera index or a URL) for ``"video"`` and ``"stream"``."""

    kind: InputKind
    label: str
    images: tuple[Path, ...] = ()
    root: Path | None = None
    target: str | int | None = None


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


def resolve_input(spec: str, *, recursive: bool = False, exclude: Path | None = None) -> EnhanceInput:
    """Classify INPUT: an existing folder or image file, a video file (by suffix), a camera index (digits),
    a stream URL, or a glob of images. Images under ``exclude`` (the output folder) are left out.

    Raises:
        InputFileError: nothing exists at ``spec``, a glob or folder matches no image.
    """
    path = Path(spec)
    if path.is_dir():
        images = _exclude(list_images(path, recursive=recursive), exclude, path)
        if not images:
            raise InputFileError(path, f"no images found{'' if recursive else ' (use --recursive for subfolders)'}")
        return EnhanceInput("images", str(path), tuple(images), root=path)
    if path.is_file():
        if path.suffix.lower() in VIDEO_SUFFIXES:
            return EnhanceInput("video", str(path), target=str(path))
        return EnhanceInput("images", str(path), (path,), root=path.parent)
    if spec.strip().isdigit():
        return EnhanceInput("stream", f"camera {int(spec)}", target=int(spec))
    if is_stream_url(spec):
        return EnhanceInput("stream", redact_url(spec), target=spec.strip())
    if _GLOB_CHARS & set(spec):
        images = [p for p in glob_files(spec) if p.suffix.lower() in IMAGE_SUFFIXES]  # survives symlink loops
        root = _glob_root(spec)
        images = _exclude([p for p in images if not p.name.startswith(".")], exclude, root)
        if not images:
            raise InputFileError(spec, "the pattern matches no image file")
        return EnhanceInput("images", spec, tuple(images), root=root)
    raise InputFileError(
        spec,
        "not found (expected an image, a folder, a glob, a video file, a camera index or an rtsp:// / http:// URL)",
    )


def _exclude(images: list[Path], folder: Path | None, root: Path) -> list[Path]:
    """Drop images below ``folder`` (the output) when it lies inside the input ``root``; an output folder
    equal to the input, or above it with outputs landing inside it, is refused by :func:`plan_images`."""
    if folder is None:
        return images
    out = folder.resolve()
    if root.resolve().is_relative_to(out):
        return images
    return [p for p in images if not p.resolve().is_relative_to(out)]


def _glob_root(spec: str) -> Path:
    parts = Path(spec).parts
    root: list[str] = []
    for part in parts:
        if _GLOB_CHARS & set(part):
            break
        root.append(part)
    return Path(*root) if root else Path(".")


@dataclass(frozen=True)
class ImageJob:
    """One image to restore: ``src`` -> ``dst``; ``stem`` names its depth outputs (relative, no suffix)."""

    src: Path
    dst: Path
    stem: str


def plan_images(inp: EnhanceInput, out: Path, fmt: ImageFormat | None = None) -> tuple[list[ImageJob], Path]:
    """Output paths for the images of ``inp``; returns (jobs, output folder).

    ``out`` is a folder (outputs mirror the inputs' paths relative to the input folder or glob root), or, for
    a single image, a file path with an image suffix.

    Two inputs whose outputs would share a name (``x.jpg`` and ``x.png`` with ``fmt="png"``, or their depth
    maps ``depth/x.png``) get distinct names (``x_jpg``, ``x_png``; see :func:`murk.io.paths.output_names`).

    Raises:
        ValueError: the output folder is the input folder, an output would overwrite its input, or ``fmt``
            contradicts an output file's suffix.
    """
    if inp.kind != "images" or inp.root is None:
        raise ValueError(f"inp: expected an images input, got {inp.kind}")
    if out.suffix.lower() in VIDEO_SUFFIXES:
        raise ValueError(f"--out {out}: images are written to a folder or an image file, not a video")
    if len(inp.images) == 1 and out.suffix.lower() in IMAGE_SUFFIXES and not out.is_dir():
        if fmt is not None and out.suffix.lower() not in _suffixes(fmt):
            raise ValueError(f"--format {fmt} contradicts the output file name {out.name}")
        jobs = [ImageJob(inp.images[0], out, out.stem)]
        out_dir = out.parent
    else:
        # an --out inside the input folder is fine: resolve_input leaves it out of the inputs
        check_output_location(out, [inp.root], inside="allow")
        names = output_names(list(inp.images), root=inp.root)
        jobs = []
        for src in inp.images:
            rel = src.relative_to(inp.root) if src.is_relative_to(inp.root) else Path(src.name)
            dst = out / (f"{names[src]}.{fmt}" if fmt else rel)  # without fmt the suffix keeps rel distinct
            jobs.append(ImageJob(src, dst, names[src]))
        out_dir = out
        root, out_real = inp.root.resolve(), out.resolve()
        if not out_real.is_relative_to(root):  # (an --out inside the input folder is left out of the listing)
            for job in jobs:  # an --out above the input folder: outputs must not land inside the input folder
                if job.dst.resolve().is_relative_to(root):
                    raise ValueError(
                        f"--out {out}: the output {job.dst} would land inside the input folder {inp.root} (and be "
                        "read back as an input on a rerun); choose another folder"
                    )
    sources = {job.src.resolve(): job.src for job in jobs}
    for job in jobs:
        hit = sources.get(job.dst.resolve())
        if hit is not None:
            what = "its input" if hit == job.src else f"the input {hit}"
            raise ValueError(f"--out {out}: the output {job.dst} would overwrite {what}")
    return jobs, out_dir


def _suffixes(fmt: str) -> tuple[str, ...]:
    return (".jpg", ".jpeg") if fmt == "jpg" else (f".{fmt}",)


# ----------------------------------------------------------------------------------------------------------
# Report
# ----------------------------------------------------------------------------------------------------------


@dataclass
class EnhanceReport:
    """Counts and timings of a run. ``failed`` counts records written to ``errors.jsonl``."""

    processed: int = 0
    skipped: int = 0
    failed: int = 0
    total: int | None = None
    read_s: float = 0.0
    restore_s: float = 0.0
    write_s: float = 0.0
    wall_s: float = 0.0
    stopped: bool = False
    errors_path: Path | None = None
    outputs: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    started: float = field(default_factory=time.perf_counter, repr=False)

    @property
    def fps(self) -> float:
        """Processed frames per second of wall time."""
        return self.processed / self.wall_s if self.wall_s > 0 else 0.0

    def stage_ms(self) -> dict[str, float]:
        """Milliseconds per processed frame spent reading, restoring and writing."""
        n = max(self.processed, 1)
        return {"read": 1e3 * self.read_s / n, "restore": 1e3 * self.restore_s / n, "write": 1e3 * self.write_s / n}

    def tick(self) -> None:
        self.wall_s = time.perf_counter() - self.started

    def note(self, text: str) -> None:
        if text not in self.notes:
            self.notes.append(text)


class _ErrorLog:
    """Appends one ``errors.jsonl`` record per failure (created only when something fails); :meth:`start`
    removes the records of an earlier run, so the file lists the failures of the latest run only."""

    def __init__(self, folder: Path, report: EnhanceReport) -> None:
        self.path = folder / ERRORS_FILE
        self.report = report

    def start(self) -> None:
        self.path.unlink(missing_ok=True)

    def add(self, source: str, stage: str, error: str, frame: int | None = None) -> None:
        record: dict[str, object] = {"input": source, "stage": stage, "error": error}
        if frame is not None:
            record["frame"] = frame
        append_jsonl(self.path, [record])
        self.report.failed += 1
        self.report.errors_path = self.path


_INPUT_ERRORS = (InputFileError, ValueError, OSError)
_RESTORE_ERRORS = (ValueError, RuntimeError, MemoryError)


def _restore(restorer: Restorer, images: np.ndarray) -> Restored:
    """Run the restorer on a numpy batch; on CUDA through the tensor path (pinned upload, one download)."""
    device = getattr(restorer, "device", torch.device("cpu"))
    if torch.device(device).type == "cuda":
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


def _write_depth(out_dir: Path, stem: str, depth_m: np.ndarray, options: OutputOptions) -> None:
    write_depth_png(out_dir / "depth" / f"{stem}.png", depth_m)
    preview = colorize_depth(depth_m, options.depth_range_m)
    write_rgb(out_dir / "depth_preview" / f"{stem}.jpg", preview, jpeg_quality=options.jpeg_quality)


# ----------------------------------------------------------------------------------------------------------
# Images
# ----------------------------------------------------------------------------------------------------------


@dataclass
class _Loaded:
    job: ImageJob
    image: np.ndarray
    bits: int


def enhance_images(
    jobs: Sequence[ImageJob],
    restorer: Restorer,
    out_dir: Path,
    options: OutputOptions | None = None,
    *,
    batch: int = 1,
    on_progress: ProgressFn | None = None,
    should_stop: StopFn | None = None,
) -> EnhanceReport:
    """Restore image files (see :func:`plan_images`) in batches of equal-size images.

    Existing outputs are skipped unless ``options.overwrite``; failures are recorded in
    ``out_dir/errors.jsonl`` (rewritten by each run) and the run continues. ``should_stop`` is polled between
    images.

    Raises:
        OutputError: no space left on the device; the run stops (finished outputs are kept, none is partial).
    """
    options = options or OutputOptions()
    if batch < 1:
        raise ValueError(f"batch: expected >= 1, got {batch}")
    report = EnhanceReport(total=len(jobs))
    errors = _ErrorLog(out_dir, report)
    out_dir.mkdir(parents=True, exist_ok=True)
    remove_stale_temporaries(out_dir)
    errors.start()
    pending: list[_Loaded] = []
    claimed: dict[Path, Path] = {}

    def flush() -> None:
        if pending:
            _restore_and_write_images(pending, restorer, out_dir, options, report, errors)
            pending.clear()
        report.tick()
        if on_progress:
            on_progress(report)

    for job in jobs:
        if should_stop and should_stop():
            report.stopped = True
            break
        key = job.dst.resolve()
        if key in claimed:
            errors.add(str(job.src), "plan", f"output {job.dst} is already written from {claimed[key]}")
            continue
        claimed[key] = job.src
        if job.dst.exists() and not options.overwrite:
            report.skipped += 1
            continue
        t0 = time.perf_counter()
        try:
            raw, info = read_image(job.src)
            image = to_float(raw)
        except _INPUT_ERRORS as exc:
            errors.add(str(job.src), "read", _message(exc, job.src))
            continue
        finally:
            report.read_s += time.perf_counter() - t0
        bits = 16 if info.bit_depth == 16 and job.dst.suffix.lower() in SIXTEEN_BIT_SUFFIXES else 8
        if pending and pending[0].image.shape != image.shape:
            flush()
        pending.append(_Loaded(job, image, bits))
        if len(pending) >= batch:
            flush()
    flush()
    return report


def _restore_and_write_images(
    items: list[_Loaded],
    restorer: Restorer,
    out_dir: Path,
    options: OutputOptions,
    report: EnhanceReport,
    errors: _ErrorLog,
) -> None:
    t0 = time.perf_counter()
    try:
        result = _restore(restorer, np.stack([it.image for it in items]))
    except _RESTORE_ERRORS as exc:
        for it in items:
            errors.add(str(it.job.src), "restore", f"{type(exc).__name__}: {exc}")
        return
    finally:
        report.restore_s += time.perf_counter() - t0
    t0 = time.perf_counter()
    for i, it in enumerate(items):
        try:
            if result.depth_m is not None and options.depth:
                _write_depth(out_dir, it.job.stem, result.depth_m[i], options)
            image = result.images[i]
            if options.side_by_side:
                image = side_by_side(it.image, image)
            write_uint(it.job.dst, to_uint(image, it.bits), jpeg_quality=options.jpeg_quality)  # last: marks done
            report.processed += 1
        except OutputError:  # a full disk ends the run (every later write would fail too)
            raise
        except _INPUT_ERRORS as exc:
            errors.add(str(it.job.src), "write", _message(exc, it.job.dst))
    report.write_s += time.perf_counter() - t0


def _message(exc: BaseException, path: Path) -> str:
    text = str(exc)
    prefix = f"{path}: "
    return text[len(prefix) :] if text.startswith(prefix) else text


# ----------------------------------------------------------------------------------------------------------
# Frames (video files, cameras, streams)
# ----------------------------------------------------------------------------------------------------------


@dataclass
class _FrameItem:
    index: int
    image: np.ndarray | None  # float32 RGB
    error: str | None = None
    dst: Path | None = None


class _FrameWriter:
    """Writes processed frames in order to a video (with repeats for broken frames) or to numbered images."""

    def __init__(self, source: FrameSource, out: Path, options: OutputOptions, report: EnhanceReport) -> None:
        self.source, self.out, self.options, self.report = source, out, options, report
        self.as_video = out.suffix.lower() in VIDEO_SUFFIXES
        self.out_dir = out.parent if self.as_video else out
        self.stem = out.stem if self.as_video else source.name
        self.ext = f".{options.format or 'jpg'}"
        self.sink: VideoSink | None = None
        self.depth_sink: VideoSink | None = None
        self.last: np.ndarray | None = None
        self.last_depth: np.ndarray | None = None
        self.backend = options.video_backend
        if self.backend == "auto":
            self.backend = "av" if source.live and av_available() else "opencv"

    def frame_path(self, index: int) -> Path:
        return self.out_dir / f"{self.stem}_{index:06d}{self.ext}"

    def _open(self, path: Path, size: tuple[int, int]) -> VideoSink:
        fps = self.options.fps or self.source.fps
        if fps is None:
            fps = DEFAULT_FPS
            self.report.note(f"the source reports no frame rate; videos are written at {DEFAULT_FPS:g} fps")
        sink = VideoSink(path, fps, size, backend=self.backend, atomic=not self.source.live)  # type: ignore[arg-type]
        self.report.outputs.append(path)
        return sink

    def write(self, index: int, frame_u8: np.ndarray, depth_m: np.ndarray | None) -> None:
        if depth_m is not None and self.options.depth:
            _write_depth(self.out_dir, f"{self.stem}_{index:06d}", depth_m, self.options)
            if self.options.depth_video and self.as_video:
                preview = to_uint(colorize_depth(depth_m, self.options.depth_range_m), 8)
                if self.depth_sink is None:
                    path = self.out.with_name(f"{self.out.stem}_depth{self.out.suffix}")
                    self.depth_sink = self._open(path, (preview.shape[1], preview.shape[0]))
                self.last_depth = self._fit(preview, self.depth_sink)
                self.depth_sink.write(self.last_depth)
        if not self.as_video:
            write_uint(self.frame_path(index), frame_u8, jpeg_quality=self.options.jpeg_quality)
            return
        if self.sink is None:
            self.sink = self._open(self.out, (frame_u8.shape[1], frame_u8.shape[0]))
        frame_u8 = self._fit(frame_u8, self.sink)
        self.sink.write(frame_u8)
        self.last = frame_u8

    def repeat_last(self) -> bool:
        """Write the previous frame again (keeps a video's length and timing); False when there is none."""
        if self.sink is None or self.last is None:
            return False
        self.sink.write(self.last)
        if self.depth_sink is not None and self.last_depth is not None:
            self.depth_sink.write(self.last_depth)
        return True

    def _fit(self, frame: np.ndarray, sink: VideoSink) -> np.ndarray:
        w, h = sink.size
        if frame.shape[:2] == (h, w):
            return frame
        import cv2

        self.report.note(f"the frame size changed during the stream; frames are resized to {w}x{h}")
        return cv2.resize(frame, (w, h), interpolation=cv2.INTER_AREA)

    def finish(self, complete: bool) -> None:
        """Close the videos; an incomplete atomic video (interrupted file input) is discarded. When closing one
        fails (a full disk), the others are discarded too and the error is raised."""
        sinks = [s for s in (self.sink, self.depth_sink) if s is not None]
        try:
            for sink in sinks:
                if complete or not sink.atomic:
                    sink.close()
                else:
                    self._discard(sink)
        except BaseException:
            for sink in sinks:
                self._discard(sink)
            raise

    def _discard(self, sink: VideoSink) -> None:
        sink.abort()
        if sink.atomic and sink.path in self.report.outputs:
            self.report.outputs.remove(sink.path)


def enhance_frames(
    source: FrameSource,
    restorer: Restorer,
    out: Path,
    options: OutputOptions | None = None,
    *,
    batch: int = 1,
    max_frames: int | None = None,
    on_progress: ProgressFn | None = None,
    should_stop: StopFn | None = None,
) -> EnhanceReport:
    """Restore the frames of ``source`` into a video (``out`` with a video suffix) or numbered images (``out``
    a folder: ``<name>_<index:06d>.<format>``).

    A video from a finite source is written atomically: when ``should_stop`` interrupts it, the partial video
    is discarded. A live source is recorded directly and closed cleanly on disconnect, on ``max_frames`` and
    on ``should_stop``. Broken frames are recorded in ``errors.jsonl`` and, in a video, replaced by the
    previous output frame.

    Raises:
        ValueError: a live recording would replace an existing output without ``options.overwrite``.
        OutputError: no space left on the device, or a finished video lacks frames; an atomic video is
            discarded (nothing under ``out``).
    """
    options = options or OutputOptions()
    if batch < 1:
        raise ValueError(f"batch: expected >= 1, got {batch}")
    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames: expected >= 1, got {max_frames}")
    report = EnhanceReport()
    if source.frame_count is not None:
        report.total = min(source.frame_count, max_frames) if max_frames else source.frame_count
    elif max_frames is not None:
        report.total = max_frames
    if out.suffix.lower() in IMAGE_SUFFIXES:
        raise ValueError(f"--out {out}: frames are written to a video file or a folder, not an image file")
    writer = _FrameWriter(source, out, options, report)
    if writer.as_video and out.suffix.lower() not in WRITABLE_VIDEO_SUFFIXES:
        raise ValueError(
            f"--out {out}: cannot write {out.suffix} videos; use one of {', '.join(WRITABLE_VIDEO_SUFFIXES)}"
        )
    if writer.backend == "av" and not av_available():
        raise ValueError("--video-backend av needs PyAV: pip install 'murk[video]'")
    errors = _ErrorLog(writer.out_dir, report)
    label = getattr(source, "label", source.name)
    if writer.as_video and out.exists() and not options.overwrite:
        if source.live:
            raise ValueError(f"{out}: exists; pass --overwrite to replace it")
        report.skipped = 1
        report.note(f"{out} exists; skipped (use --overwrite to redo it)")
        return report
    if not writer.as_video and source.live and writer.frame_path(0).exists() and not options.overwrite:
        raise ValueError(f"{writer.frame_path(0)}: exists (an earlier recording); pass --overwrite or another --out")
    if options.depth_video and not writer.as_video:
        report.note("--depth-video applies to video outputs; depth previews are in depth_preview/")
    writer.out_dir.mkdir(parents=True, exist_ok=True)
    for stale in writer.out_dir.glob(f"{TMP_PREFIX}*-{out.name}"):
        stale.unlink(missing_ok=True)
    errors.start()

    items: list[_FrameItem] = []
    saw_depth = False

    def flush() -> None:
        nonlocal saw_depth
        good = [it for it in items if it.image is not None]
        outputs: dict[int, tuple[np.ndarray, np.ndarray | None]] = {}
        t0 = time.perf_counter()
        for group in _same_shape_runs(good):
            try:
                result = _restore(restorer, np.stack([it.image for it in group]))  # type: ignore[misc]
            except _RESTORE_ERRORS as exc:
                for it in group:
                    it.error = f"restore failed: {type(exc).__name__}: {exc}"
                continue
            for j, it in enumerate(group):
                outputs[it.index] = (result.images[j], None if result.depth_m is None else result.depth_m[j])
        report.restore_s += time.perf_counter() - t0
        t0 = time.perf_counter()
        for it in items:
            if it.index not in outputs:
                repeated = writer.repeat_last()
                errors.add(label, "read" if it.image is None else "restore", _frame_error(it, repeated), it.index)
                continue
            image, depth = outputs[it.index]
            saw_depth |= depth is not None
            panel = side_by_side(it.image, image) if options.side_by_side else image  # type: ignore[arg-type]
            try:
                writer.write(it.index, to_uint(panel, 8), depth)
                report.processed += 1
            except OutputError:  # a full disk ends the run; finish() discards the partial video
                raise
            except _INPUT_ERRORS as exc:
                errors.add(label, "write", str(exc), it.index)
        report.write_s += time.perf_counter() - t0
        items.clear()
        report.tick()
        if on_progress:
            on_progress(report)

    complete = False
    n_read = 0
    try:
        while True:
            if should_stop and should_stop():
                report.stopped = True
                break
            if max_frames is not None and n_read >= max_frames:
                break
            t0 = time.perf_counter()
            frame = source.read()
            if frame is None:
                report.read_s += time.perf_counter() - t0
                break
            n_read += 1
            item = _FrameItem(frame.index, None if frame.image is None else to_float(frame.image), frame.error)
            report.read_s += time.perf_counter() - t0
            if not writer.as_video and item.image is not None:
                item.dst = writer.frame_path(frame.index)
                if item.dst.exists() and not options.overwrite:
                    report.skipped += 1
                    continue
            items.append(item)
            if sum(it.image is not None for it in items) >= batch:
                flush()
        flush()
        complete = source.live or not report.stopped
    finally:
        writer.finish(complete)
        report.tick()
    if report.stopped and not source.live and writer.as_video:
        report.note(f"interrupted: the partial video was discarded; rerun to write {out}")
    if source.end_reason and source.end_reason != "end" and not report.stopped:
        report.note(f"{label}: {source.end_reason} after {n_read} frames" if source.live else source.end_reason)
    if options.depth_video and writer.as_video and not saw_depth and report.processed:
        report.note(f"--depth-video: method {restorer.name!r} returns no depth; no depth video written")
    return report


def _same_shape_runs(items: list[_FrameItem]) -> list[list[_FrameItem]]:
    runs: list[list[_FrameItem]] = []
    for it in items:
        if runs and runs[-1][0].image.shape == it.image.shape:  # type: ignore[union-attr]
            runs[-1].append(it)
        else:
            runs.append([it])
    return runs


def _frame_error(item: _FrameItem, repeated: bool) -> str:
    what = item.error or "frame could not be decoded"
    return f"{what}; previous frame repeated in the video" if repeated else what
