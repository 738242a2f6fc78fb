"""``murk eval``: UIQM/UCIQE of images, PSNR/SSIM against references, input-vs-output restoration measures
and flags (``--input``), depth errors; table, CSV and JSON.

The work is :func:`murk.report.evaluate.run_eval`. Exit codes: 0 = every file was scored; 1 = some files
failed (listed on stderr, and in ``errors.jsonl`` beside the ``--json``/``--csv`` output when one is given; each
run rewrites it, or removes it when nothing failed); 2 = bad usage (unknown preset, missing path, nothing to
evaluate).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from murk.cli._common import QuietOpt, make_console, parse_size, topic_option
from murk.cli._jobs import JobProgress, print_summary
from murk.metrics import table

_METRICS_HELP = (
    "Comma-separated metrics to score instead of the default ones (each needs what it scores against: --ref, "
    f"--input or --depth): {', '.join(table.names(default=True))}; off by default: "
    f"{', '.join(n for n in table.names(default=False) if table.get(n).needs != 'snow_pair')}. See --list-metrics."
)


def evaluate(
    images: Annotated[
        list[Path] | None,
        typer.Argument(
            help="Image files and/or folders. Scored with UIQM (and its terms) and UCIQE; with --ref they are "
            "the predictions."
        ),
    ] = None,
    ref: Annotated[
        Path | None,
        typer.Option("--ref", help="Folder of reference images matched to IMAGES by file stem: adds PSNR and SSIM."),
    ] = None,
    input_dir: Annotated[
        Path | None,
        typer.Option(
            "--input",
            help="Folder of the raw input images matched to IMAGES (their restorations) by file stem: adds the "
            "restoration measures (artefact ratios, structure GMS, particles, cast, luminance, contrast; full "
            "resolution, not --resize) and their flags.",
        ),
    ] = None,
    depth: Annotated[
        Path | None,
        typer.Option("--depth", help="Predicted depth: a file or a folder (uint16 PNG in mm, or .npy in metres)."),
    ] = None,
    depth_ref: Annotated[
        Path | None,
        typer.Option("--depth-ref", help="Ground-truth depth: a file or a folder matched to --depth by stem."),
    ] = None,
    preset: Annotated[
        list[str] | None,
        typer.Option(
            "--preset",
            help="UIQM preset (panetta2016 = default, funie, jointid) and/or UCIQE preset (uciqe_m = default, "
            "cielab_raw); repeat to set both, e.g. --preset funie --preset cielab_raw.",
        ),
    ] = None,
    resize: Annotated[
        str | None,
        typer.Option(
            "--resize",
            help="WxH: resize with Pillow bicubic before UIQM/UCIQE (FUnIE-GAN's measure_uiqm.py uses 256x256).",
        ),
    ] = None,
    depth_scale: Annotated[
        float, typer.Option("--depth-scale", help="Raw units per metre of integer depth images (1000 = mm).")
    ] = 1000.0,
    recursive: Annotated[bool, typer.Option("--recursive", "-r", help="Search folders recursively.")] = False,
    ssim_window: Annotated[
        str, typer.Option("--ssim-window", help="gaussian (11x11, sigma 1.5; default) or uniform (7x7).")
    ] = "gaussian",
    csv_out: Annotated[Path | None, typer.Option("--csv", help="Write one row per file to this CSV file.")] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write rows, summary, presets and errors to this JSON file.")
    ] = None,
    topic: Annotated[str | None, topic_option("ROS bags among IMAGES")] = None,
    every: Annotated[int, typer.Option("--every", min=1, help="ROS bags among IMAGES: every N-th frame.")] = 1,
    metrics: Annotated[str | None, typer.Option("--metrics", help=_METRICS_HELP)] = None,
    list_metrics: Annotated[
        bool,
        typer.Option(
            "--list-metrics", help="List every metric (label, unit, direction, what it needs, data range) and exit."
        ),
    ] = False,
    quiet: QuietOpt = False,
) -> None:
    """Score images: UIQM (Eq. 10, with UICM/UISM/UIConM) and UCIQE; PSNR/SSIM with --ref; restoration measures
    and flags against the raw inputs with --input; depth errors with --depth/--depth-ref. Prints a per-file
    table and mean +- std (population std over files)."""
    from murk.report.evaluate import EvalOptions, parse_presets, run_eval

    if list_metrics:
        typer.echo(table.describe())
        raise typer.Exit(0)
    uiqm_preset, uciqe_preset = parse_presets(preset or [])
    options = EvalOptions(
        uiqm_preset=uiqm_preset,
        uciqe_preset=uciqe_preset,
        resize=parse_size(resize, option="--resize") if resize is not None else None,
        ssim_window=ssim_window,
        depth_scale=depth_scale,
        recursive=recursive,
        metrics=tuple(m.name for m in table.pick(metrics) or ()) if metrics is not None else None,
    )
    with JobProgress(make_console(quiet), "scoring images", unit="images") as progress:
        result = run_eval(
            images or [],
            ref=ref,
            inputs=input_dir,
            depth=depth,
            depth_ref=depth_ref,
            options=options,
            topic=topic,
            every=every,
            json_out=json_out,
            csv_out=csv_out,
            on_progress=progress.update,
        )
    _print_tables(result, quiet)
    raise typer.Exit(print_summary(result, "file"))


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return "inf" if math.isinf(v) else f"{v:.4f}"
    return str(v)


def _print_tables(result: Any, quiet: bool) -> None:
    """Per-file rows (unless --quiet) and the mean/std rows of each table, on stdout."""
    from rich.console import Console
    from rich.table import Table

    from murk.report.evaluate import columns, summarize

    stdout = Console(highlight=False, soft_wrap=False, width=10_000)
    for title, rows in (("images", result.images), ("depth", result.depth)):
        if not rows:
            continue
        cols = columns(rows)
        summary = summarize(rows)
        counts = summary.get("flags")  # only with --input
        table = Table(title=f"{title} ({len(rows)})", title_justify="left", box=None, pad_edge=False)
        table.add_column("file", overflow="fold")
        for c in cols:
            table.add_column(c, justify="right")
        if counts is not None:
            table.add_column("flags")
        if not quiet:
            for r in rows:
                flag_cell = [r.get("flags", "")] if counts is not None else []
                table.add_row(r["file"], *(_fmt(r[c]) if c in r else "" for c in cols), *flag_cell)
            table.add_section()
        flag_total = [f"{counts['flagged']}/{counts['n']} flagged"] if counts is not None else []
        table.add_row("mean", *(_fmt(summary[c].get("mean", math.nan)) for c in cols), *flag_total)
        table.add_row("std", *(_fmt(summary[c].get("std", math.nan)) for c in cols), *([""] * len(flag_total)))
        stdout.print(table)
