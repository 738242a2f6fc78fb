"""``murk compare``: the paper's evaluation on your own footage and checkpoints."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import DeviceOpt, QuietOpt, make_console, topic_option
from murk.cli._jobs import JobProgress, print_summary
from murk.enhance.choices import Policy, Precision


def compare(
    real_dir: Annotated[
        Path, typer.Argument(help="Folder (or one file) of REAL underwater images, or a ROS bag (--topic).")
    ],
    method: Annotated[
        list[str],
        typer.Option(
            "--method",
            help="[LABEL=]METHOD[:CHECKPOINT], repeatable: raw, post, jointid:CKPT, jointid+post:CKPT, "
            "retrained=jointid+post:runs/x/best.pt, and the paper's baselines udaformer:WEIGHTS, ursct:WEIGHTS "
            "(docs/baselines.md); per-method options after '?', e.g. ursct:W.pth?policy=official",
        ),
    ],
    out: Annotated[Path, typer.Option("--out", help="Report folder.")],
    box: Annotated[
        list[str] | None, typer.Option("--box", help="x,y,w,h zoom box in pixels (repeatable; default: automatic).")
    ] = None,
    recursive: Annotated[bool, typer.Option("--recursive", "-r", help="Search REAL_DIR recursively.")] = False,
    uiqm_preset: Annotated[str, typer.Option("--uiqm-preset", help="panetta2016, funie or jointid.")] = "panetta2016",
    uciqe_preset: Annotated[str, typer.Option("--uciqe-preset", help="uciqe_m or cielab_raw.")] = "uciqe_m",
    device: DeviceOpt = "cpu",
    precision: Annotated[
        Precision, typer.Option("--precision", help="Joint-ID precision: fp32, bf16 or fp16.")
    ] = "fp32",
    tile: Annotated[int | None, typer.Option("--tile", help="Joint-ID tile size for large images (px).")] = None,
    policy: Annotated[
        Policy,
        typer.Option(
            "--policy",
            help="udaformer/ursct: native (any size, default) or official (256x256 as their published test scripts).",
        ),
    ] = "native",
    trust_checkpoint: Annotated[
        bool, typer.Option("--trust-checkpoint", help="Allow pickled objects in checkpoints (trusted files only).")
    ] = False,
    save_outputs: Annotated[
        bool, typer.Option("--save-outputs", help="Also write restored/<label>/<stem>.png.")
    ] = False,
    title: Annotated[str, typer.Option("--title", help="Report title.")] = "murk compare",
    topic: Annotated[str | None, topic_option("REAL_DIR a ROS bag")] = None,
    every: Annotated[int, typer.Option("--every", min=1, help="REAL_DIR a ROS bag: every N-th frame.")] = 1,
    ref: Annotated[
        Path | None,
        typer.Option(
            "--ref",
            help="Folder of reference images matched to REAL_DIR's images by file stem: adds PSNR, SSIM and "
            "CIEDE2000 per image and method, and each method's paired difference to the raw input.",
        ),
    ] = None,
    max_side: Annotated[
        int | None,
        typer.Option("--max-side", min=8, help="Downscale images (and references) to this long side first (px)."),
    ] = None,
    snow_clean: Annotated[
        Path | None,
        typer.Option(
            "--snow-clean",
            help="Folder of snow-free images of the same scenes as REAL_DIR's snowy ones (matched by stem): adds "
            "the marine-snow residue on the known particle sites per image and method.",
        ),
    ] = None,
    quiet: QuietOpt = False,
) -> None:
    """Run every --method on every image; per-image UIQM (+ UICM/UISM/UIConM) and UCIQE, a per-method
    mean +- std table (Fig. 8), side-by-side grids with zoomed boxes (Figs. 7, 9), CSV, JSON and report.html.
    With --ref, PSNR/SSIM/CIEDE2000 against the references and paired differences to the raw input."""
    from murk.cli._common import flag_text, mean_std_text, resolve_device
    from murk.report.compare import real_images, run_compare
    from murk.report.figures import parse_box
    from murk.report.methods import parse_method

    console = make_console(quiet)
    specs = [parse_method(m) for m in method]
    boxes = [parse_box(b) for b in box or []]
    images = real_images(real_dir, out, recursive=recursive)
    options = {
        "device": resolve_device(device),
        "precision": precision,
        "tile": tile,
        "trust_checkpoint": trust_checkpoint,
        "policy": policy,
    }

    with JobProgress(console, "compare", total=len(images), unit="images") as progress:
        res = run_compare(
            images,
            specs,
            out,
            boxes=boxes,
            uiqm_preset=uiqm_preset,
            uciqe_preset=uciqe_preset,
            restorer_options=options,
            save_outputs=save_outputs,
            title=title,
            topic=topic,
            every=every,
            on_image=lambda i, n, name: progress.update(i, n),
            ref_dir=ref,
            max_side=max_side,
            snow_clean=snow_clean,
        )
    summary = make_console()
    tables: list[tuple[tuple[str, str], ...]] = []
    if ref is not None:
        tables.append((("PSNR dB", "psnr"), ("dPSNR vs raw", "d_psnr"), ("SSIM", "ssim"), ("CIEDE2000", "ciede2000")))
    if snow_clean is not None:
        tables.append(
            (
                ("snow residue", "snow_residue"),
                ("sites left", "snow_sites_left"),
                ("GMS away", "snow_free_gms"),
                ("colour residue", "snow_colour_residue"),
            )
        )
    for columns in tables:
        head = " ".join(f"{name:>18}" for name, _ in columns)
        summary.print(f"{'method':<28} {head}  n", highlight=False, soft_wrap=True)
        for s in specs:
            row = res.summary[s.label]
            cells = " ".join(mean_std_text(row[key]) for _, key in columns)
            summary.print(f"{s.label:<28} {cells}  {row[columns[0][1]]['n']}", highlight=False, soft_wrap=True)
    header = f"{'method':<28} {'UIQM mean +- std':>18} {'UCIQE mean +- std':>18}  n  flags"
    summary.print(header, highlight=False, soft_wrap=True)
    for s in specs:
        row = res.summary[s.label]
        u, c = row["uiqm"], row["uciqe"]
        summary.print(
            f"{s.label:<28} {mean_std_text(u)} {mean_std_text(c)}  {u['n']}  {flag_text(row.get('flags'))}",
            highlight=False,
            soft_wrap=True,
        )
    raise typer.Exit(print_summary(res, "image", detail=f"report: {Path(out) / 'report.html'}", console=summary))
