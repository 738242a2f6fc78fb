"""The frame job of ``murk enhance``: restore the frames of a video file, a camera or a stream into a video
(source frame rate) or numbered images; optionally a coloured depth video. What a method estimates per frame
(``Restored.facts``: the ``water`` method's water) goes to ``<out-stem>_estimates.jsonl`` beside a video output, or to
``estimates.jsonl`` in a folder of frames: one line per frame written (``input``, ``frame``, ``output`` and the facts;
:class:`_EstimatesLog`).

Reliability: a broken frame is recorded in ``errors.jsonl`` and replaced by the previous output frame so the
video keeps its length and timing; video files are written atomically (complete or absent), live recordings
directly and flushed (see :mod:`murk.io.video`); a full disk stops the run with :class:`murk.errors.OutputError`.
"""

from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from murk.enhance.frame_overlap import InOrder, one_thread_per_call, restore_threads
from murk.enhance.frames_u8 import restore_frames, to_u8
from murk.enhance.job_common import (
    ESTIMATES_NAME,
    INPUT_ERRORS,
    RESTORE_ERRORS,
    EnhanceReport,
    OutputOptions,
    ProgressFn,
    StopFn,
    read_frames,
    write_depth_outputs,
)
from murk.enhance.preview import colorize_depth, side_by_side
from murk.enhance.restorer import Restorer
from murk.errors import OutputError
from murk.io.atomic import TMP_PREFIX, make_output_folder, no_space_as_error, write_text_atomic
from murk.io.images import IMAGE_SUFFIXES, to_float, to_uint, write_uint
from murk.io.jobs import ErrorLog, ErrorRecord
from murk.io.jsonl import dumps, json_safe
from murk.io.readahead import ReadAhead
from murk.io.video import DEFAULT_FPS, VIDEO_SUFFIXES, WRITABLE_VIDEO_SUFFIXES, FrameSource, VideoSink, av_available
from murk.io.writer import BackgroundWriter

WRITE_BEHIND = 4
"""Restored frames that may wait for the write-behind thread (bounded memory; the restorer waits beyond)."""


@dataclass
class _FrameItem:
    index: int
    image: np.ndarray | None  # RGB as decoded (uint8; uint16 from some bags)
    error: str | None = None
    dst: Path | None = None
    replay: bool = False  # written by an earlier run: restored again only to carry the method's state over time


class _EstimatesLog:
    """The per-frame estimates of one run. For a video file (written atomically) the lines are held and written, all
    at once and atomically, when the video is committed: an interrupted run leaves the previous video and its
    estimates as they were, and a committed video without estimates removes an older file. Otherwise (a live
    recording, a folder of frames) each line is appended as its frame is written, flushed, and fsynced at the end; a
    live recording starts the file anew (it replaces the previous recording), a folder appends (a frame restored
    again gets another line, the newest last)."""

    def __init__(self, path: Path, *, atomic: bool, fresh: bool) -> None:
        self.path, self.atomic, self.fresh = path, atomic, fresh
        self.lines: list[str] = []
        self.file: TextIO | None = None

    def add(self, record: dict[str, Any]) -> None:
        line = dumps(json_safe(record)) + "\n"  # a NaN figure becomes null, never a failed frame
        if self.atomic:
            self.lines.append(line)
            return
        with no_space_as_error(self.path, "estimates file"):
            if self.file is None:
                make_output_folder(self.path.parent)
                self.file = open(self.path, "w" if self.fresh else "a", encoding="utf-8")
            self.file.write(line)
            self.file.flush()

    def close(self, commit: bool) -> None:
        """End the run: ``commit`` when the video (or recording) is kept."""
        if self.file is not None:
            try:
                with no_space_as_error(self.path, "estimates file"):
                    os.fsync(self.file.fileno())
            finally:
                self.file.close()
                self.file = None
        elif self.fresh and commit:
            self.path.unlink(missing_ok=True)  # the recording replaced the previous one, which had estimates
        if self.atomic and commit:
            if self.lines:
                write_text_atomic(self.path, "".join(self.lines))
            else:
                self.path.unlink(missing_ok=True)


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
        self.owed = 0
        """Broken frames before the first written one: the first good frame is written that many more times."""
        self.estimates = (
            out.with_name(f"{out.stem}_estimates.jsonl") if self.as_video else out / ESTIMATES_NAME
        )  # what the method estimated per frame
        atomic = self.as_video and not source.live
        self.estimates_log = _EstimatesLog(self.estimates, atomic=atomic, fresh=self.as_video and source.live)
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

    def record(self, label: str, index: int, facts: dict[str, Any]) -> None:
        """Record one frame's estimates (after the frame is written, so every line names a frame that exists)."""
        output = self.out if self.as_video else self.frame_path(index)
        self.estimates_log.add({"input": label, "frame": index, "output": str(output), **facts})

    def write(self, index: int, frame_u8: np.ndarray, depth_m: np.ndarray | None) -> None:
        copies = 1 + self.owed if self.as_video else 1  # a video's broken leading frames take this frame
        if depth_m is not None and self.options.depth:
            write_depth_outputs(self.out_dir, f"{self.stem}_{index:06d}", depth_m, self.options)
            if self.options.depth_video and self.as_video:
                preview = to_uint(colorize_depth(depth_m, self.options.depth_range_m), 8)
                if self.depth_sink is None:
                    path = self.out.with_name(f"{self.out.stem}_depth{self.out.suffix}")
                    self.depth_sink = self._open(path, (preview.shape[1], preview.shape[0]))
                self.last_depth = self._fit(preview, self.depth_sink)
                for _ in range(copies):
                    self.depth_sink.write(self.last_depth)
        if not self.as_video:
            write_uint(self.frame_path(index), frame_u8, jpeg_quality=self.options.jpeg_quality)
            return
        if self.sink is None:
            self.sink = self._open(self.out, (frame_u8.shape[1], frame_u8.shape[0]))
        frame_u8 = self._fit(frame_u8, self.sink)
        for _ in range(copies):
            self.sink.write(frame_u8)
        self.last, self.owed = frame_u8, 0

    def repeat_last(self) -> bool:
        """Write the previous frame again (keeps a video's length and timing); False when there is none. In a
        video a broken frame before any written one is owed instead: the first good frame takes its place too."""
        if self.sink is None or self.last is None:
            self.owed += int(self.as_video)
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
            self.estimates_log.close(commit=False)
            raise
        self.estimates_log.close(commit=complete)

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
    read_ahead: bool = True,
) -> EnhanceReport:
    """Restore the frames of ``source`` into a video (``out`` with a video suffix) or numbered images (``out``
    a folder: ``<name>_<index:06d>.<format>``).

    A video from a finite source is written atomically: when ``should_stop`` interrupts it, the partial video
    is discarded. A live source is recorded directly and closed cleanly on disconnect, on ``max_frames`` and
    on ``should_stop``. Broken frames are recorded in ``errors.jsonl`` and, in a video, replaced by the
    previous output frame (broken frames before the first good one by that frame), so that it keeps the source's
    length.

    With ``read_ahead`` (default) frames are decoded in a background thread while the previous ones are
    restored (:class:`murk.io.readahead.ReadAhead`); for a live source only the newest frame waits, and frames
    the source delivered while restoration was busy are counted in ``report.dropped``. A file's frames are then
    restored two at a time when the method allows it (:func:`murk.enhance.frame_overlap.restore_threads`: a
    reentrant CPU method without state over time, torch and OpenCV on one thread per call meanwhile) and written
    in frame order; the outputs are those of one frame at a time.

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
    report = EnhanceReport(out=out)
    if source.frame_count is not None:
        report.total = min(source.frame_count, max_frames) if max_frames else source.frame_count
    elif max_frames is not None:
        report.total = max_frames
    if out.suffix.lower() in IMAGE_SUFFIXES:
        raise ValueError(
            f"--out {out}: frames are written to a video file or a folder, not an image file; name a video "
            f"({', '.join(WRITABLE_VIDEO_SUFFIXES)}) or a folder"
        )
    writer = _FrameWriter(source, out, options, report)
    if writer.as_video and out.suffix.lower() not in WRITABLE_VIDEO_SUFFIXES:
        raise ValueError(
            f"--out {out}: cannot write {out.suffix} videos; use one of {', '.join(WRITABLE_VIDEO_SUFFIXES)}"
        )
    if writer.backend == "av" and not av_available():
        raise ValueError("--video-backend av needs PyAV: pip install 'murk[video]'")
    errors = ErrorLog(writer.out_dir, summary=report)
    label = getattr(source, "label", source.name)
    if writer.as_video and out.exists() and not options.overwrite:
        if source.live:
            raise ValueError(f"{out}: exists; pass --overwrite to replace it")
        report.skipped = source.frame_count or 1  # counted in frames, the unit of the summary line
        report.note(f"{out} exists; skipped (use --overwrite to redo it)")
        return report
    if not writer.as_video and source.live and writer.frame_path(0).exists() and not options.overwrite:
        raise ValueError(f"{writer.frame_path(0)}: exists (an earlier recording); pass --overwrite or another --out")
    if options.depth_video and not writer.as_video:
        report.note("--depth-video applies to video outputs; depth previews are in depth_preview/")
    make_output_folder(writer.out_dir)
    for stale in writer.out_dir.glob(f"{TMP_PREFIX}*-{out.name}"):
        stale.unlink(missing_ok=True)
    errors.start()

    items: list[_FrameItem] = []
    saw_depth = False
    Output = tuple[np.ndarray, np.ndarray | None, dict[str, Any] | None]  # image, depth, facts
    Outputs = dict[int, Output]

    def restore_items(batch_items: list[_FrameItem]) -> tuple[list[_FrameItem], Outputs, float]:
        """Restore one batch (on a restore thread when frames overlap); a failed group marks its frames."""
        outputs: Outputs = {}
        t0 = time.perf_counter()
        for group in _same_shape_runs([it for it in batch_items if it.image is not None]):
            try:
                images = [it.image for it in group]
                frames = images[0][None] if len(images) == 1 else np.stack(images)  # type: ignore[index,arg-type]
                result = restore_frames(restorer, frames)
            except RESTORE_ERRORS as exc:
                for it in group:
                    it.error = f"restore failed: {type(exc).__name__}: {exc}"
                continue
            for j, it in enumerate(group):
                depth = None if result.depth_m is None else result.depth_m[j]
                outputs[it.index] = (result.images[j], depth, None if result.facts is None else result.facts[j])
        return batch_items, outputs, time.perf_counter() - t0

    def hand_on(done: tuple[list[_FrameItem], Outputs, float]) -> None:
        """Queue a restored batch's frames for the writer, in frame order."""
        nonlocal saw_depth
        batch_items, outputs, restore_s = done
        report.restore_s += restore_s
        t0 = time.perf_counter()
        for it in batch_items:
            if it.replay:  # its file exists (counted as skipped); restoring it kept the temporal average exact
                continue
            if it.index in outputs:
                saw_depth |= outputs[it.index][1] is not None
            # encoded and written on the write-behind thread, in frame order, while the next frames restore
            behind.submit(partial(write_item, it, outputs.get(it.index)))
        report.write_s += time.perf_counter() - t0  # the wait for the writer, when it is the slowest stage
        report.tick()
        if on_progress:
            on_progress(report)

    def flush() -> None:
        if not items:
            return
        batch_items = items[:]
        items.clear()
        for done in restoring.submit(partial(restore_items, batch_items)):
            hand_on(done)

    def write_item(it: _FrameItem, output: Output | None) -> None:
        """Write one frame (or repeat the previous one for a broken frame) and record what failed."""
        if output is None:
            repeated = writer.repeat_last()
            stage = "read" if it.image is None else "restore"
            errors.add(ErrorRecord(label, stage, _frame_error(it, repeated, owed=writer.owed > 0), frame=it.index))
            return
        image, depth, facts = output  # uint8
        panel = side_by_side(_as_u8(it.image), image) if options.side_by_side else image  # type: ignore[arg-type]
        try:
            writer.write(it.index, panel, depth)
            report.processed += 1
            if facts is not None:
                writer.record(label, it.index, facts)
                report.note(f"what {restorer.name} estimated per frame: {writer.estimates}")
        except OutputError:  # a full disk ends the run; finish() discards the partial video
            raise
        except INPUT_ERRORS as exc:
            errors.add(ErrorRecord(label, "write", str(exc), frame=it.index))

    complete = False
    n_read = 0
    reader: FrameSource = ReadAhead(source) if read_ahead else source
    # decode (ReadAhead), restore (here or on the restore threads) and encode (this write-behind thread) overlap;
    # one writer thread keeps the frame order, and at most WRITE_BEHIND frames wait, so memory stays bounded and
    # nothing is dropped
    behind = BackgroundWriter(threads=1 if read_ahead else 0, max_pending=WRITE_BEHIND)
    # a file's frames may restore two at a time (frame_overlap.restore_threads), the results taken in frame order;
    # a live source restores one at a time, the newest frame each time
    restoring: InOrder[tuple[list[_FrameItem], Outputs, float]] = InOrder(
        restore_threads(restorer) if read_ahead and not source.live else 1
    )
    threads = one_thread_per_call() if restoring.threads > 1 else contextlib.nullcontext()
    with threads, restorer.sequence():  # one video: methods with state over time carry it from frame to frame
        try:
            for frame in read_frames(reader, report, should_stop, max_frames):
                n_read += 1
                item = _FrameItem(frame.index, frame.image, frame.error)
                if not writer.as_video and item.image is not None:
                    item.dst = writer.frame_path(frame.index)
                    if item.dst.exists() and not options.overwrite:
                        report.skipped += 1
                        if not restorer.carries_state:
                            continue
                        item.replay = True  # the next frames' average over time includes this one
                items.append(item)
                if sum(it.image is not None for it in items) >= batch:
                    flush()
            flush()
            for done in restoring.drain():
                hand_on(done)
            complete = source.live or not report.stopped
        finally:
            restoring.close()
            if isinstance(reader, ReadAhead):
                reader.stop()
                report.dropped = reader.dropped
            try:
                behind.close()  # every queued frame is written before the video is closed
            except BaseException:
                writer.finish(False)  # a full disk while writing: the partial video is discarded
                raise
            writer.finish(complete)
            report.tick()
    if report.dropped:
        report.note(
            f"{label}: {report.dropped} frame(s) dropped: the source delivered them faster than {restorer.name} "
            "restored (the newest frame is always the one restored)"
        )
    if report.stopped and not source.live and writer.as_video:
        report.note(f"interrupted: the partial video was discarded; rerun to write {out}")
    if source.end_reason and source.end_reason != "end" and not report.stopped:
        report.note(f"{label}: {source.end_reason} after {n_read} frames" if source.live else source.end_reason)
    if options.depth_video and writer.as_video and not saw_depth and report.processed:
        report.note(f"--depth-video: method {restorer.name!r} returns no depth; no depth video written")
    return report


def _as_u8(image: np.ndarray) -> np.ndarray:
    """A decoded frame as uint8 (the input half of a side-by-side panel)."""
    return image if image.dtype == np.uint8 else to_u8(to_float(image))


def _same_shape_runs(items: list[_FrameItem]) -> list[list[_FrameItem]]:
    runs: list[list[_FrameItem]] = []
    for it in items:
        if runs and runs[-1][0].image.shape == it.image.shape:  # type: ignore[union-attr]
            runs[-1].append(it)
        else:
            runs.append([it])
    return runs


def _frame_error(item: _FrameItem, repeated: bool, *, owed: bool = False) -> str:
    what = item.error or "frame could not be decoded"
    if repeated:
        return f"{what}; previous frame repeated in the video"
    return f"{what}; the next good frame takes its place in the video" if owed else what
