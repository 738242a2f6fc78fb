"""``murk enhance``: restore images, folders, video files and live streams with a registered method."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer
from rich.markup import escape

from murk.cli._common import (
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_PARTIAL,
    DeviceOpt,
    QuietOpt,
    make_console,
    resolve_device,
    stop_on_signals,
    topic_option,
)
from murk.cli._jobs import JobProgress, print_summary
from murk.enhance.choices import BagStorage, HEMode, ImageFormat, Policy, Precision, VideoBackendChoice
from murk.enhance.methods import methods_help

FLAGS = {
    "he": "--he",
    "sigma_px": "--sigma-px",
    "lam": "--lambda",
    "clahe_clip": "--clahe-clip",
    "clahe_tiles": "--clahe-tiles",
    "temporal": "--temporal",
    "checkpoint": "--checkpoint",
    "precision": "--precision",
    "tile": "--tile",
    "overlap": "--overlap",
    "trust_checkpoint": "--trust-checkpoint",
    "compile": "--compile",
    "policy": "--policy",
}
"""Method options the command has flags for, by option name."""


def method_options(*, device: str, batch: int, **given: Any) -> dict[str, Any]:
    """The command's settings handed to ``--method`` as ``shared``: device and batch, plus the method flags the
    user set (None, or False for a switch, means not set: the method's own default applies). Each stage takes
    the ones it declares; a set flag that no stage declares is an error (``create(..., given=...)``)."""
    unknown = set(given) - set(FLAGS)
    if unknown:
        raise ValueError(f"method_options: no flag for {sorted(unknown)}")
    return {"device": device, "batch": batch} | {k: v for k, v in given.items() if v is not None and v is not False}


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
            help="Restoration method (default lite, what murk recommends for real footage); chain with '+' (e.g. "
            "jointid+post); blend two restorations of the same input with '|' and the second one's weight (e.g. "
            "jointid_net|lite@0.3; '|' binds tighter than '+', parentheses group); method options after '?' "
            "(e.g. post?lam=0.5,he=rgb; a misspelt one is an error). post?preset=paper is Eq. 9 exactly; the "
            "default preset 'real' applies 30 % of the equalisation. jointid re-expresses the network's output as a "
            "local affine map of the input and averages lite's restoration in by default (the preset "
            "jointid_net|lite@lite_blend; jointid?refine=0,lite_blend=0: the network alone; docs/enhance.md). "
            "Methods: " + methods_help() + ".",
        ),
    ] = "lite",
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
        HEMode | None,
        typer.Option("--he", help="post: equalise luma (y, colours kept; default), each channel (rgb), or CLAHE."),
    ] = None,
    sigma_px: Annotated[
        float | None, typer.Option("--sigma-px", min=0.0, help="post: LoG sigma in pixels, > 0 (Eq. 9; default 1.0).")
    ] = None,
    lam: Annotated[
        float | None,
        typer.Option(
            "--lambda",
            min=0.0,
            help="post: edge-enhancement weight (Eq. 9; default: the preset's, 0.1 real, 0.3 paper).",
        ),
    ] = None,
    clahe_clip: Annotated[
        float | None, typer.Option("--clahe-clip", min=0.0, help="post --he clahe: clip limit, > 0 (default 2.0).")
    ] = None,
    clahe_tiles: Annotated[
        int | None, typer.Option("--clahe-tiles", min=1, help="post --he clahe: tiles per side (default 8).")
    ] = None,
    temporal: Annotated[
        float | None,
        typer.Option(
            "--temporal",
            min=0.0,
            max=0.99,
            help="lite, post; videos, cameras, streams, bags: weight of the previous frames in an average of the "
            "per-frame estimates (lite's maps, post's equalisation); 0 = each frame on its own (default); 0.8 "
            "steadies a live picture (~5-frame time constant).",
        ),
    ] = None,
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
        Precision | None, typer.Option("--precision", help="jointid: fp32 (default), or bf16/fp16 autocast (GPU).")
    ] = None,
    tile: Annotated[
        int | None,
        typer.Option(
            "--tile",
            min=0,
            help="jointid: run large frames in tiles of this size (px, a multiple of 32; 0: whole frames).",
        ),
    ] = None,
    overlap: Annotated[
        int | None, typer.Option("--overlap", min=0, help="jointid: tile overlap in px (blended; default 64).")
    ] = None,
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
        Policy | None,
        typer.Option(
            "--policy",
            help="udaformer/ursct: native (default: any size, output at the input size) or official (the published "
            "test script: resized to 256x256, output 256x256; docs/baselines.md).",
        ),
    ] = None,
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
    topic: Annotated[str | None, topic_option("ROS bag input")] = None,
    every: Annotated[int, typer.Option("--every", min=1, help="ROS bag input: every N-th frame of the topic.")] = 1,
    out_topic: Annotated[
        str | None, typer.Option("--out-topic", help="Bag output: topic of restored frames (<topic>/restored).")
    ] = None,
    depth_topic: Annotated[
        str | None, typer.Option("--depth-topic", help="Bag output: topic of 32FC1 depth in metres (<topic>/depth).")
    ] = None,
    storage: Annotated[
        BagStorage | None, typer.Option("--storage", help="ROS 2 bag output: mcap or sqlite3 (default: as input).")
    ] = None,
    copy_topics: Annotated[
        list[str] | None,
        typer.Option(
            "--copy-topics",
            help="Bag output: copy these topics unchanged (repeatable; camera_info = every CameraInfo; all).",
        ),
    ] = None,
    quiet: QuietOpt = False,
) -> None:
    """Restore underwater images, folders, videos, live streams and ROS bags (lite by default).

    Prints processed/skipped/failed counts, frames per second and read/restore/write milliseconds per frame.
    Unreadable inputs go to errors.jsonl in the output folder (exit code 1); reruns skip finished outputs.
    What the water method estimates goes to estimates.jsonl (images, frames) or <out-stem>_estimates.jsonl (a video).
    """
    from murk.enhance.job_common import OutputOptions
    from murk.enhance.restorer import check, create
    from murk.enhance.run import BagOptions, run_enhance, weights_line

    dev = resolve_device(device)
    given = {
        "he": he,
        "sigma_px": sigma_px,
        "lam": lam,
        "clahe_clip": clahe_clip,
        "clahe_tiles": clahe_tiles,
        "temporal": temporal,
        "checkpoint": None if checkpoint is None else str(checkpoint),
        "precision": precision,
        "tile": tile,
        "overlap": overlap,
        "trust_checkpoint": trust_checkpoint,
        "compile": compile_model,
        "policy": policy,
    }
    shared = method_options(device=dev, batch=batch, **given)
    flags = {k: FLAGS[k] for k in shared if k in FLAGS}
    check(method, shared=shared, given=flags)  # names and options, before anything is loaded
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

    def build() -> Any:  # called by run_enhance once INPUT is found: a missing input answers before torch loads
        restorer = create(method, shared=shared, given=flags)
        line = weights_line(restorer, shipped=checkpoint is None)
        if line:
            console.print(line, soft_wrap=True, highlight=False)
        return restorer

    def display(title: str, unit: str, total: int | None, live: bool) -> JobProgress:
        return JobProgress(console, title, total=total, unit=unit, live=live, status=_status_line, rate=_rate)

    with stop_on_signals() as stop:
        inp, report = run_enhance(
            input,
            out,
            build,
            options,
            recursive=recursive,
            batch=batch,
            max_frames=max_frames,
            should_stop=stop,
            display=display,
            bag=BagOptions(
                topic=topic,
                every=every,
                out_topic=out_topic,
                depth_topic=depth_topic,
                storage=storage,
                copy_topics=tuple(copy_topics or ()),
            ),
        )
    _print_summary(summary, report, "image" if inp.kind == "images" else "frame")
    live = inp.kind == "stream"
    if report.failed:
        raise typer.Exit(EXIT_PARTIAL)
    if report.stopped and not live:
        summary.print("interrupted; rerun the same command to resume", soft_wrap=True)
        raise typer.Exit(EXIT_INTERRUPTED)
    raise typer.Exit(EXIT_OK)


def _print_summary(console: Any, report: Any, unit: str) -> int:
    ms = report.stage_ms()
    if report.processed == 0:  # nothing restored (all skipped or failed): no rate to report
        detail = ""
    else:
        detail = (
            f"{report.fps:.2f} {unit}s/s; per {unit}: read {ms['read']:.1f} ms, restore {ms['restore']:.1f} ms, "
            f"write {ms['write']:.1f} ms"
        )
    code = print_summary(report, unit, detail=detail, console=console)
    for path in report.outputs:
        console.print(f"wrote {escape(str(path))}", soft_wrap=True)
    return code


def _rate(report: Any) -> str:
    return f"{report.fps:.1f} f/s"


def _status_line(report: Any) -> str:
    ms = report.stage_ms()
    done = report.processed + report.skipped
    of = f"/{report.total}" if report.total else ""
    failed = f", {report.failed} failed" if report.failed else ""
    return (
        f"{done}{of} frames{failed} | {report.fps:.1f} f/s | read {ms['read']:.0f} ms, "
        f"restore {ms['restore']:.0f} ms, write {ms['write']:.0f} ms"
    )
