"""``murk snow``: marine-snow particle banks cut from real underwater footage (Sec. 4.2 of the paper)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import QuietOpt, command_group, make_console, topic_option
from murk.cli._jobs import JobProgress, print_summary

app = command_group("Marine-snow particle banks from real underwater images and video.")


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
    topic: Annotated[str | None, topic_option("ROS bag inputs")] = None,
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
    listed in BANK_errors.jsonl beside the bank (exit code 1; rewritten by every run). BANK_preview/ may lie inside
    an input folder: its images, and those of every earlier bank's X_preview/ beside X.npz, are not read as footage.
    """
    import numpy as np

    from murk.snow.extract import ExtractConfig
    from murk.workflows.snow_extract import extract_snow_bank

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
    with JobProgress(make_console(quiet), "snow extract", unit="frames") as progress:
        res = extract_snow_bank(
            inputs, out, config, every=every, topic=topic, scale=(lo, hi), preview=preview, on_progress=progress.update
        )
    bank = res.bank
    assert bank is not None  # (extract_snow_bank raises when no particle was found)
    areas = bank.areas_px
    detail = (
        f"{len(bank)} particles (area median {np.median(areas):.0f} px, max {areas.max()} px), bank {bank.bank_id} "
        f"-> {out}" + (f"; previews in {res.preview_dir}" if res.preview_dir else "")
    )
    raise typer.Exit(print_summary(res, "frame", detail=detail))


@app.command("relight")
def relight(
    bank: Annotated[str, typer.Argument(help="A particle bank (.npz) or builtin:snow-real.")],
    out: Annotated[Path, typer.Option("--out", help="The relit bank to write (.npz).")],
    luma: Annotated[str, typer.Option("--luma", help="a,b: each particle's mean luma, drawn from a to b (0-255).")] = (
        "120,230"
    ),
    seed: Annotated[int, typer.Option("--seed", help="Seed of the per-particle draws.")] = 0,
) -> None:
    """Relight a bank cut from dark footage: each particle grey with its own luma pattern, mean luma from a to b.

    Particles cut from dark water are too dim for Eq. (7), which composites them with their own colours; real
    marine snow is bright. Shapes and sizes are kept; the new bank records the range, the seed and the bank it
    came from (docs/snow.md).
    """
    from murk.snow.relight import relight_bank_file

    try:
        lo, hi = (float(v) for v in luma.split(","))
    except ValueError:
        raise ValueError(f"--luma: expected a,b (e.g. 120,230), got {luma!r}") from None
    b = relight_bank_file(bank, out, (lo, hi), seed=seed)
    typer.echo(f"{len(b)} particles relit to luma {lo:g}-{hi:g}, bank {b.bank_id} -> {out}")


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
                "relight": b.meta.get("relight"),
                "subpixel_at_0.3-0.6": msg,
            },
            indent=2,
        )
    )
