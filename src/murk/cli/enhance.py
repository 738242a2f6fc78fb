"""``murk enhance``: restore images, folders, video files and live streams with a registered method."""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.markup import escape

from murk.cli._common import EXIT_OK, EXIT_PARTIAL, DeviceOpt, QuietOpt, make_console, resolve_device
from murk.enhance.choices import HEMode, ImageFormat, Policy, Precision, VideoBackendChoice

EXIT_INTERRUPTED = 130


def method_options(
    *,
    device: str,
    batch: int,
    he: str,
    sigma_px: float,
    lam: float,
    clahe_clip: float,
    clahe_tiles: int,
    checkpoint: str | None = None,
    precision: str = "fp32",
    tile: int | None = None,
    overlap: int = 64,
    trust_checkpoint: bool = False,
    compile: bool = False,
    policy: str = "native",
) -> dict[str, Any]:
    """The command's settings handed to ``--method`` as ``shared`` (each stage takes the ones it declares;
    options written after ``?`` in the spec must be declared). New method options (checkpoint, precision,
    tiling, ...) are added here and in :func:`enhance`."""
    return {
        "device": device,
        "batch": batch,
        "he": he,
        "sigma_px": sigma_px,
        "lam": lam,
        "clahe_clip": clahe_clip,
        "clahe_tiles": clahe_tiles,
        "checkpoint": checkpoint,
        "precision": precision,
        "tile": tile,
        "overlap": overlap,
        "trust_checkpoint": trust_checkpoint,
        "compile": compile,
        "policy": policy,
    }


def enhance(
    input: Annotated[
        str,
        typer.Argument(
            help="An image, a folder, a glob ('dive/**/*.jpg'), a video file, a camera index (0) or a stream URL "
            "(rtsp://..., http://...).",
            show_default=False,
        ),
    ],
    out: Annotated[
        Path,
        typer.Option(
            "--out",
            "-o",
            help="Output folder (images, or frames of a video/stream), a video file (x.mp4, x.avi, x.mkv) for "
            "videos and streams, or an image file for a single image.",
            show_default=False,
        ),
    ],
    method: Annotated[
        str,
        typer.Option(
            "--method",
            "-m",
            help="Restoration method; chain with '+' (e.g. jointid+post); method options after '?' "
            "(e.g. post?lam=0.5,he=rgb; a misspelt one is an error).",
        ),
    ] = "post",
    recursive: Annotated[bool, typer.Option("--recursive", "-r", help="Include subfolders of a folder.")] = False,
    format: Annotated[
        ImageFormat | None,
        typer.Option("--format", help="Image format of outputs (default: as input; jpg for frames)."),
    ] = None,
    side_by_side: Annotated[bool, typer.Option("--side-by-side", help="Write input|output panels.")] = False,
    max_frames: Annotated[
        int | None, typer.Option("--max-frames", min=1, help="Stop after this many frames (or images).")
    ] = None,
    device: DeviceOpt = "cpu",
    batch: Annotated[int, typer.Option("--batch", min=1, help="Frames restored together (GPU throughput).")] = 1,
    overwrite: Annotated[
        bool, typer.Option("--overwrite", help="Redo outputs that exist (default: skip them, so reruns resume).")
    ] = False,
    he: Annotated[
        HEMode, typer.Option("--he", help="post: equalise luma (y, colours kept), each channel (rgb), or CLAHE.")
    ] = "y",
    sigma_px: Annotated[float, typer.Option("--sigma-px", min=0.0, help="post: LoG sigma in pixels (Eq. 9).")] = 1.0,
    lam: Annotated[float, typer.Option("--lambda", min=0.0, help="post: edge-enhancement weight (Eq. 9).")] = 0.3,
    clahe_clip: Annotated[float, typer.Option("--clahe-clip", min=0.0, help="post --he clahe: clip limit.")] = 2.0,
    clahe_tiles: Annotated[int, typer.Option("--clahe-tiles", min=1, help="post --he clahe: tiles per side.")] = 8,
    checkpoint: Annotated[
        Path | None,
        typer.Option(
            "--checkpoint",
            help="jointid: weights (a murk checkpoint from 'murk train', the official joint_id_ckpt.pth, or an "
            ".onnx export run with ONNX Runtime); lite: a 'murk train' lite checkpoint or its .onnx export. "
            "Default: the weights shipped with murk.",
        ),
    ] = None,
    precision: Annotated[
        Precision, typer.Option("--precision", help="jointid: fp32, or bf16/fp16 autocast (GPU).")
    ] = "fp32",
    tile: Annotated[
        int | None, typer.Option("--tile", min=32, help="jointid: run large frames in tiles of this size (px).")
    ] = None,
    overlap: Annotated[int, typer.Option("--overlap", min=0, help="jointid: tile overlap in px (blended).")] = 64,
    trust_checkpoint: Annotated[
        bool,
        typer.Option(
            "--trust-checkpoint",
            help="jointid: allow arbitrary pickled objects in the checkpoint (runs code; trusted files only).",
        ),
    ] = False,
    compile_model: Annotated[
        bool, typer.Option("--compile", help="jointid: torch.compile the network (GPU; slow first frames).")
    ] = False,
    policy: Annotated[
        Policy,
        typer.Option(
            "--policy",
            help="udaformer/ursct: native (any size, output at the input size) or official (the published test "
            "script: resized to 256x256, output 256x256; docs/baselines.md).",
        ),
    ] = "native",
    depth: Annotated[
        bool,
        typer.Option("--depth/--no-depth", help="Write depth/ and depth_preview/ when the method estimates depth."),
    ] = True,
    depth_video: Annotated[
        bool, typer.Option("--depth-video", help="Also write <out>_depth.<ext>, a coloured depth video.")
    ] = False,
    fps: Annotated[
        float | None, typer.Option("--fps", min=0.001, help="Frame rate of video outputs (default: the source's).")
    ] = None,
    video_backend: Annotated[
        VideoBackendChoice,
        typer.Option(
            "--video-backend",
            help="Video writer: opencv, av (PyAV; kill-safe fragmented MP4), auto (av for live streams if installed).",
        ),
    ] = "auto",
    quiet: QuietOpt = False,
) -> None:
    """Restore underwater images, folders, videos and live streams (Eq. 9 post-processing by default).

    Prints processed/skipped/failed counts, frames per second and read/restore/write milliseconds per frame.
    Unreadable inputs go to errors.jsonl in the output folder (exit code 1); reruns skip finished outputs.
    """
    from murk.enhance.pipeline import (
        OutputOptions,
        enhance_frames,
        enhance_images,
        plan_images,
        resolve_input,
    )
    from murk.enhance.restorer import create, weights_of
    from murk.io.video import CaptureSource

    dev = resolve_device(device)
    restorer = create(
        method,
        shared=method_options(
            device=dev,
            batch=batch,
            he=he,
            sigma_px=sigma_px,
            lam=lam,
            clahe_clip=clahe_clip,
            clahe_tiles=clahe_tiles,
            checkpoint=None if checkpoint is None else str(checkpoint),
            precision=precision,
            tile=tile,
            overlap=overlap,
            trust_checkpoint=trust_checkpoint,
            compile=compile_model,
            policy=policy,
        ),
    )
    options = OutputOptions(
        format=format,
        side_by_side=side_by_side,
        overwrite=overwrite,
        depth=depth,
        depth_video=depth_video,
        video_backend=video_backend,
        fps=fps,
    )
    console = make_console(quiet)
    summary = make_console(False)
    weights = weights_of(restorer)
    if weights:
        stage = next(s.name for s in getattr(restorer, "stages", [restorer]) if getattr(s, "weights", None))
        what = {"jointid": "the 'small' Joint-ID murk trained", "lite": "the 'lite' network murk trained"}.get(stage)
        shipped = f" (shipped with murk: {what}, docs/models.md)" if checkpoint is None and what else ""
        console.print(f"{stage} weights: {weights}{shipped}", soft_wrap=True, highlight=False)
    inp = resolve_input(input, recursive=recursive, exclude=out)
    with _stop_on_signals() as stop:
        if inp.kind == "images":
            jobs, out_dir = plan_images(inp, out, options.format)
            jobs = jobs[:max_frames] if max_frames else jobs
            with _Display(console, f"{restorer.name}: {inp.label}", total=len(jobs), live=False) as display:
                report = enhance_images(
                    jobs, restorer, out_dir, options, batch=batch, on_progress=display.update, should_stop=stop
                )
        else:
            with CaptureSource(inp.target) as source:  # type: ignore[arg-type]
                total = source.frame_count if max_frames is None else min(source.frame_count or max_frames, max_frames)
                with _Display(console, f"{restorer.name}: {inp.label}", total=total, live=source.live) as display:
                    report = enhance_frames(
                        source,
                        restorer,
                        out,
                        options,
                        batch=batch,
                        max_frames=max_frames,
                        on_progress=display.update,
                        should_stop=stop,
                    )
    _print_summary(summary, report)
    live = inp.kind == "stream"
    if report.failed:
        raise typer.Exit(EXIT_PARTIAL)
    if report.stopped and not live:
        summary.print("interrupted; rerun the same command to resume", soft_wrap=True)
        raise typer.Exit(EXIT_INTERRUPTED)
    raise typer.Exit(EXIT_OK)


def _print_summary(console: Any, report: Any) -> None:
    ms = report.stage_ms()
    parts = [f"{report.processed} processed"]
    if report.skipped:
        parts.append(f"{report.skipped} skipped (output exists)")
    if report.failed:
        parts.append(f"[red]{report.failed} failed[/] (see {escape(str(report.errors_path))})")
    console.print(
        f"enhance: {', '.join(parts)} in {report.wall_s:.1f} s; {report.fps:.2f} frames/s; per frame: "
        f"read {ms['read']:.1f} ms, restore {ms['restore']:.1f} ms, write {ms['write']:.1f} ms",
        soft_wrap=True,
    )
    for path in report.outputs:
        console.print(f"wrote {escape(str(path))}", soft_wrap=True)
    for note in report.notes:
        console.print(f"note: {escape(note)}", soft_wrap=True)


class _Display:
    """A progress bar (files, on a terminal), a live line (streams, on a terminal), or a plain status line
    every 10 s (headless logs)."""

    def __init__(self, console: Any, title: str, *, total: int | None, live: bool) -> None:
        self.console, self.title, self.total, self.live = console, title, total, live
        self.interactive = console.is_terminal and not console.quiet
        self._last = time.monotonic()
        self._progress: Any = None
        self._live: Any = None

    def __enter__(self) -> _Display:
        if self.interactive and not self.live:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            self._progress = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[rate]}"),
                TimeRemainingColumn(),
                console=self.console,
            )
            self._progress.start()
            self._task = self._progress.add_task(escape(self.title), total=self.total, rate="")
        elif self.interactive:
            from rich.live import Live

            self._live = Live("", console=self.console, refresh_per_second=4, transient=True)
            self._live.start()
        return self

    def update(self, report: Any) -> None:
        now = time.monotonic()
        if self._progress is not None:
            self._progress.update(
                self._task, completed=report.processed + report.skipped + report.failed, rate=f"{report.fps:.1f} f/s"
            )
            return
        line = _status_line(self.title, report)
        if self._live is not None:
            if now - self._last >= 0.25:
                self._live.update(line)
                self._last = now
        elif not self.console.quiet and now - self._last >= 10.0:
            self.console.print(line, soft_wrap=True)
            self._last = now

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()
        if self._live is not None:
            self._live.stop()


def _status_line(title: str, report: Any) -> str:
    ms = report.stage_ms()
    done = report.processed + report.skipped
    of = f"/{report.total}" if report.total else ""
    failed = f", {report.failed} failed" if report.failed else ""
    return escape(
        f"{title}: {done}{of} frames{failed} | {report.fps:.1f} f/s | read {ms['read']:.0f} ms, "
        f"restore {ms['restore']:.0f} ms, write {ms['write']:.0f} ms"
    )


@contextlib.contextmanager
def _stop_on_signals() -> Iterator[Any]:
    """Yield a ``should_stop`` callable set by SIGINT/SIGTERM, so outputs are closed cleanly; a second
    Ctrl+C raises KeyboardInterrupt at once. Outside the main thread no handler is installed."""
    flag = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield flag.is_set
        return

    def handler(signum: int, frame: Any) -> None:
        if flag.is_set() and signum == signal.SIGINT:
            raise KeyboardInterrupt
        flag.set()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield flag.is_set
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
