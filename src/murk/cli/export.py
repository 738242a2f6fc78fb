"""``murk export``: a Joint-ID, ``lite`` or baseline checkpoint to an ONNX file of one input, the image in [0, 1]."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import QuietOpt, make_console
from murk.enhance.choices import Exposure


def export(
    checkpoint: Annotated[
        Path,
        typer.Option("--checkpoint", "-c", help="Joint-ID checkpoint (murk's or the official .pth), or a lite one."),
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="The .onnx file to write.")],
    opset: Annotated[
        int, typer.Option("--opset", help="ONNX opset version (>= 14, at most what the installed torch exports).")
    ] = 17,
    verify: Annotated[
        bool,
        typer.Option(
            "--verify/--no-verify",
            help="Run the file with ONNX Runtime on random frames of a few sizes and compare with murk's torch "
            "restorer (fails above 1e-3; lite: 1e-4).",
        ),
    ] = True,
    trust_checkpoint: Annotated[
        bool,
        typer.Option(
            "--trust-checkpoint",
            help="Allow arbitrary pickled objects in the checkpoint (runs code from the file: trusted files only).",
        ),
    ] = False,
    network: Annotated[
        str,
        typer.Option(
            "--model",
            help="auto (a Joint-ID or lite checkpoint, told apart by the file), or one of the paper's baselines: "
            "udaformer, ursct (fixed --size, dynamic batch; docs/baselines.md).",
        ),
    ] = "auto",
    size: Annotated[
        str,
        typer.Option(
            "--size", help="udaformer/ursct: the graph's fixed frame size WxH (ursct: square, a multiple of 128)."
        ),
    ] = "256x256",
    exposure: Annotated[
        Exposure | None,
        typer.Option(
            "--exposure",
            help="lite only: input (the default: the graph keeps the input's exposure, as 'murk enhance --method "
            "lite' does) or network (the network's own, as lite?exposure=network).",
        ),
    ] = None,
    quiet: QuietOpt = False,
) -> None:
    """Export a Joint-ID or lite checkpoint to ONNX: one input, the image, any size (dynamic batch, height, width).

    Every graph takes ONE input 'image' (B, 3, H, W) float32 RGB in [0, 1] and returns the restored frames as
    murk's restorer computes them (padding, normalisation, working image and clamping are inside the graph).

    Joint-ID: outputs 'depth_m' (metres) and 'enhanced'. Run it with: murk enhance IMAGES --out OUT --method
    jointid --checkpoint model.onnx

    lite (told apart by the file's format): output 'enhanced' (the working image is made inside the graph). Run it
    with: murk enhance IMAGES --out OUT --method lite --checkpoint lite.onnx, or with ONNX Runtime alone.

    udaformer, ursct (--model): the paper's baselines for ONE frame size (--size; dynamic batch), output
    'enhanced'. Their size-dependent window padding and masks are traced as constants, so the graph rejects or
    miscomputes other sizes; murk's torch restorers (--method udaformer/ursct) take any size.
    """
    from murk.cli._common import parse_size
    from murk.models.export import EXPORT_MODELS, export_checkpoint

    console = make_console(quiet)
    if network not in EXPORT_MODELS:
        raise ValueError(f"--model: expected {', '.join(EXPORT_MODELS[:-1])} or {EXPORT_MODELS[-1]}, got {network!r}")
    w, h = parse_size(size, option="--size")
    done = export_checkpoint(
        checkpoint,
        out,
        model=network,
        size_hw=(h, w),
        opset=opset,
        verify=verify,
        trust=trust_checkpoint,
        exposure=exposure,
    )
    folded = "folded: " if done.kind == "lite" else ""
    fixed = (
        f"; fixed {done.fixed_size_hw[1]}x{done.fixed_size_hw[0]}, dynamic batch: the graph only takes this size"
        if done.fixed_size_hw
        else ""
    )
    console.print(
        f"exported {done.kind} {checkpoint} ({folded}{done.parameters:,} parameters) to {out} (opset {opset}{fixed})"
    )
    for check in done.checks:
        diffs = ", ".join(f"{name} {diff:.2e}" for name, diff in check.max_abs_diff.items())
        console.print(f"verified {check.label}: max |onnx - torch| {diffs}")
    typer.echo(str(out))
