"""``murk snow``: marine-snow particle banks cut from real underwater footage (Sec. 4.2 of the paper)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from murk.cli._common import EXIT_PARTIAL, MurkGroup, QuietOpt, make_console

app = typer.Typer(
    cls=MurkGroup,
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode="rich",
    help="Marine-snow particle banks from real underwater images and video.",
)

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".m4v", ".webm", ".mpg", ".mpeg", ".ts")


def _list_inputs(inputs: list[Path]) -> list[Path | tuple[str, str]]:
    """In input order: the files to read (image files and videos as given, the images of folders, recursively;
    each file once) and, where an input cannot be used, its (path, problem)."""
    from murk.io.images import list_images
    from murk.io.rosbag import is_bag

    entries: list[Path | tuple[str, str]] = []
    seen: set[str] = set()
    for inp in inputs:
        if is_bag(inp):  # a ROS bag (its frames are read by _frames)
            inside = [inp]
        elif inp.is_dir():
            try:
                inside = list_images(inp, recursive=True)
            except OSError as exc:
                entries.append((str(inp), f"cannot list folder ({exc.strerror or exc})"))
                continue
            if not inside:
                entries.append((str(inp), "folder holds no images"))
        elif inp.is_file():
            inside = [inp]
        else:
            entries.append((str(inp), "not found"))
            continue
        for f in inside:
            real = os.path.realpath(f)
            if real not in seen:
                seen.add(real)
                entries.append(f)
    return entries


def _frames(
    entries: list[Path | tuple[str, str]], every: int, problems: list[tuple[str, str]], topic: str | None = None
) -> Iterator[tuple[dict[str, Any], Any]]:
    """Yield (description, uint8 RGB) for image files, videos and ROS bag topics (every N-th frame); problems in
    input order."""
    import cv2

    from murk.errors import InputFileError
    from murk.io.images import read_image
    from murk.io.rosbag import is_bag, iter_frames

    for f in entries:
        if isinstance(f, tuple):
            problems.append(f)
            continue
        if is_bag(f):  # issue 17: frames of --topic, every N-th message
            try:
                for frame in iter_frames(f, topic, every=every):
                    if frame.image is None:
                        problems.append((f"{f}:{topic}", f"frame {frame.index}: {frame.error}"))
                        continue
                    rgb = frame.image if frame.image.dtype == "uint8" else (frame.image // 257).astype("uint8")
                    yield {"path": str(f), "frame": frame.message}, rgb
            except InputFileError as exc:  # no such topic, unreadable bag: recorded like an unreadable file
                problems.append((str(f), exc.problem))
            continue
        if f.suffix.lower() in VIDEO_SUFFIXES:
            cap = cv2.VideoCapture(str(f))
            if not cap.isOpened():
                problems.append((str(f), "cannot open video"))
                continue
            i = 0
            try:
                while True:
                    try:
                        ok, bgr = cap.read()
                    except cv2.error as exc:
                        problems.append((str(f), f"frame {i}: cannot decode ({str(exc).strip().splitlines()[-1]})"))
                        break
                    if not ok:
                        break
                    if i % every == 0:
                        yield {"path": str(f), "frame": i}, bgr[:, :, ::-1].copy()
                    i += 1
            finally:
                cap.release()
            if i == 0:
                problems.append((str(f), "video has no readable frame"))
            continue
        try:
            raw, _ = read_image(f)
        except (ValueError, OSError, MemoryError) as exc:  # unreadable or corrupt: recorded, skipped
            why = str(exc) if isinstance(exc, ValueError) else f"cannot read image ({exc})"
            problems.append((str(f), why))
            continue
        if raw.dtype != "uint8":
            raw = (raw // 257).astype("uint8")
        yield {"path": str(f)}, raw


@app.command("extract")
def extract(
    inputs: Annotated[
        list[Path],
        typer.Argument(help="Image files, folders, video files or ROS bags (--topic) of REAL underwater footage."),
    ],
    out: Annotated[Path, typer.Option("--out", help="The bank file to write (.npz).")],
    method: Annotated[
        str, typer.Option("--method", help="threshold (fixed, the paper's), adaptive, or tophat.")
    ] = "threshold",
    threshold: Annotated[
        int | None,
        typer.Option(
            "--threshold",
            help="0-255: grey level (threshold, default 70), top-hat response (tophat, 20), "
            "offset above the local mean (adaptive, 12).",
        ),
    ] = None,
    open_px: Annotated[int, typer.Option("--open-px", help="Opening kernel size (< 2 = off).")] = 2,
    close_px: Annotated[int, typer.Option("--close-px", help="Closing kernel size (< 2 = off).")] = 3,
    min_area: Annotated[int, typer.Option("--min-area", help="Smallest particle kept, pixels.")] = 2,
    max_area: Annotated[int, typer.Option("--max-area", help="Largest particle kept, pixels.")] = 400,
    max_elongation: Annotated[
        float, typer.Option("--max-elongation", help="Drop components longer than this times their width (0 = off).")
    ] = 3.0,
    block_px: Annotated[int, typer.Option("--block-px", help="Window of the adaptive method (odd).")] = 31,
    tophat_px: Annotated[int, typer.Option("--tophat-px", help="Structuring element of the top-hat.")] = 15,
    max_coverage: Annotated[
        float, typer.Option("--max-coverage", help="Reject frames whose mask covers more than this fraction.")
    ] = 0.25,
    every: Annotated[int, typer.Option("--every", help="Use every N-th video or bag frame.")] = 10,
    topic: Annotated[
        str | None, typer.Option("--topic", help="ROS bag inputs: the image topic (omit it to list them).")
    ] = None,
    scale: Annotated[
        str, typer.Option("--scale", help="The resize range used at synthesis, for the sub-pixel check.")
    ] = "0.3,0.6",
    preview: Annotated[
        bool, typer.Option("--preview/--no-preview", help="Write each source beside its mask into BANK_preview/.")
    ] = True,
    quiet: QuietOpt = False,
) -> None:
    """Cut marine-snow particles out of real footage into a particle bank for 'murk synth --snow-bank'.

    Grayscale -> binarise (--method) -> opening, closing -> connected components -> particles (original colours
    where the mask is 1). The preview shows, per source, the image beside its mask: white = kept particles,
    grey = components dropped by the area or elongation filters. Unreadable or rejected inputs are skipped and
    listed in BANK_errors.jsonl beside the bank (exit code 1; rewritten by every run). BANK_preview/ may not lie
    inside an input folder (it would be read back on a rerun).
    """
    import cv2
    import numpy as np

    from murk.io import write_jsonl
    from murk.io.images import write_uint
    from murk.io.paths import check_output_location, output_names
    from murk.snow.bank import extract_bank, save_bank
    from murk.snow.extract import ExtractConfig

    console = make_console(quiet)
    if every < 1:
        raise ValueError(f"--every: expected >= 1, got {every}")
    try:
        lo, hi = (float(v) for v in scale.split(","))
    except ValueError:
        raise ValueError(f"--scale: expected a,b (e.g. 0.3,0.6), got {scale!r}") from None
    config = ExtractConfig(
        method=method,  # type: ignore[arg-type]
        threshold=threshold,
        block_px=block_px,
        tophat_px=tophat_px,
        open_px=open_px,
        close_px=close_px,
        min_area_px=min_area,
        max_area_px=max_area,
        max_elongation=max_elongation,
        max_coverage=max_coverage,
    )
    preview_dir = out.with_name(out.stem + "_preview")
    if preview:  # folders are listed recursively: previews inside one would be read back as footage on a rerun
        check_output_location(
            preview_dir,
            [p for p in inputs if p.is_dir()],
            option=f"--out {out}: the preview folder",
            why="its previews would be read back as footage on a rerun (or use --no-preview)",
        )
    read_problems: list[tuple[str, str]] = []
    entries = _list_inputs(inputs)
    files = [e for e in entries if isinstance(e, Path)]
    names = {str(p): n for p, n in output_names(files).items()}  # a/x.jpg and b/x.jpg: two previews
    count = {"frames": 0}

    def on_frame(desc: dict[str, Any], rgb: Any, ex: Any) -> None:
        count["frames"] += 1
        if not preview:
            return
        vis = np.zeros(rgb.shape[:2], np.uint8)
        if ex is not None:
            vis[ex.mask] = 90
            for p in ex.particles:
                h, w = p.mask.shape
                vis[p.y : p.y + h, p.x : p.x + w][p.mask] = 255
        panel = np.hstack([rgb, cv2.cvtColor(vis, cv2.COLOR_GRAY2RGB)])
        if panel.shape[1] > 1600:
            f = 1600 / panel.shape[1]
            panel = cv2.resize(panel, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
        name = names[desc["path"]] + (f"_f{desc['frame']:06d}" if "frame" in desc else "")
        write_uint(preview_dir / f"{name}.jpg", panel, jpeg_quality=90)

    try:
        report = extract_bank(_frames(entries, every, read_problems, topic), config, scale=(lo, hi), on_frame=on_frame)
    except ValueError as exc:  # no particle at all: say which inputs could not even be read
        raise ValueError(_nothing_extracted(inputs, read_problems, count["frames"], str(exc))) from None
    save_bank(report.bank, out)
    problems = read_problems + report.problems
    errors_path = out.with_name(out.stem + "_errors.jsonl")
    if problems:
        write_jsonl(errors_path, [{"input": path, "error": _line(path, why)} for path, why in problems])
    elif errors_path.exists():
        errors_path.unlink()  # from an earlier run of the same command
    areas = report.bank.areas_px
    console = make_console()  # the summary prints even with --quiet
    console.print(
        f"snow extract: {count['frames']} frames, {len(report.bank)} particles (area median {np.median(areas):.0f} px, "
        f"max {areas.max()} px), bank {report.bank.bank_id} -> {out}"
        + (f"; previews in {preview_dir}" if preview else ""),
        soft_wrap=True,
    )
    for w in report.warnings:
        console.print(f"[yellow]warning:[/] {w}", soft_wrap=True)
    if problems:
        for path, why in problems[:10]:
            console.print(f"  [red]skipped:[/] {_line(path, why)}", soft_wrap=True)
        console.print(f"  all {len(problems)} skipped input(s): {errors_path}", soft_wrap=True)
        raise typer.Exit(EXIT_PARTIAL)


def _line(path: str, why: str) -> str:
    """``path: why``, unless ``why`` already starts with the path."""
    return why if why.startswith(path) else f"{path}: {why}"


def _nothing_extracted(inputs: list[Path], problems: list[tuple[str, str]], frames: int, why: str) -> str:
    """The one-line error when no particle was found: names the inputs, and the unreadable ones first."""
    listed = "; ".join(_line(p, w) for p, w in problems[:3])
    more = f" and {len(problems) - 3} more" if len(problems) > 3 else ""
    if frames == 0:
        if not listed:
            names = ", ".join(map(str, inputs[:5])) + (f" and {len(inputs) - 5} more" if len(inputs) > 5 else "")
            return f"{names}: no image or video frame to extract particles from"
        return f"{listed}{more} (no image or video frame left to extract particles from)"
    return why + (f"; {len(problems)} input(s) could not be read: {listed}{more}" if problems else "")


@app.command("info")
def info(bank: Annotated[Path, typer.Argument(help="A particle bank (.npz).")]) -> None:
    """Print a bank's id, particle count, size distribution and sources."""
    import json

    import numpy as np

    from murk.snow.bank import load_bank, subpixel_report

    b = load_bank(bank)
    sizes = b.sizes_px()
    _, msg = subpixel_report(b, (0.3, 0.6))
    typer.echo(
        json.dumps(
            {
                "bank_id": b.bank_id,
                "particles": len(b),
                "area_px": {"median": float(np.median(b.areas_px)), "max": int(b.areas_px.max())},
                "size_px": {"median": float(np.median(sizes)), "p90": float(np.percentile(sizes, 90))},
                "sources": b.meta.get("sources", []),
                "extract": b.meta.get("extract", {}),
                "subpixel_at_0.3-0.6": msg,
            },
            indent=2,
        )
    )
