"""``murk export``: a Joint-ID checkpoint to an ONNX file (dynamic batch, height and width)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import QuietOpt, make_console

VERIFY_TOLERANCE = 1e-3
"""Max absolute difference (depth in metres, enhanced in [0, 1]) allowed between ONNX Runtime and torch."""


def export(
    checkpoint: Annotated[
        Path, typer.Option("--checkpoint", "-c", help="Joint-ID checkpoint (murk's or the official .pth).")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="The .onnx file to write.")],
    opset: Annotated[int, typer.Option("--opset", help="ONNX opset version (>= 14).")] = 17,
    verify: Annotated[
        bool,
        typer.Option(
            "--verify/--no-verify",
            help="Run the file with ONNX Runtime on two sizes and compare with torch (fails above 1e-3).",
        ),
    ] = True,
    trust_checkpoint: Annotated[
        bool,
        typer.Option(
            "--trust-checkpoint",
            help="Allow arbitrary pickled objects in the checkpoint (runs code from the file: trusted files only).",
        ),
    ] = False,
    quiet: QuietOpt = False,
) -> None:
    """Export a Joint-ID checkpoint to ONNX (dynamic batch, height and width).

    The graph takes 'image' (B, 3, H, W), normalised, H and W multiples of 32, and returns 'depth_m' and
    'enhanced'. Run it with: murk enhance IMAGES --out OUT --method jointid --checkpoint model.onnx
    """
    import torch

    from murk.models.jointid import load_checkpoint, normalize_input
    from murk.models.jointid.onnx_export import OnnxJointID, compare_onnx, export_onnx

    console = make_console(quiet)
    if out.suffix.lower() != ".onnx":
        raise ValueError(f"--out: expected a file name ending in .onnx, got {str(out)!r}")
    model = load_checkpoint(checkpoint, trust=trust_checkpoint)
    n_params = sum(p.numel() for p in model.parameters())
    console.print(f"loaded {checkpoint} ({n_params:,} parameters); exporting to {out} (opset {opset})")
    export_onnx(model, out, opset=opset)
    if verify:
        runner = OnnxJointID(out)
        g = torch.Generator().manual_seed(0)
        for h, w in ((64, 96), (96, 64)):
            x = normalize_input(torch.rand(1, 3, h, w, generator=g))
            diff = compare_onnx(model, runner, x)
            worst = max(diff.values())
            console.print(
                f"verified {h}x{w}: max |onnx - torch| depth {diff['depth_m']:.2e} m, enhanced {diff['enhanced']:.2e}"
            )
            if worst > VERIFY_TOLERANCE:
                raise ValueError(
                    f"{out}: ONNX Runtime differs from torch by {worst:.3g} at {h}x{w} (tolerance "
                    f"{VERIFY_TOLERANCE}); the export is not trustworthy"
                )
    typer.echo(str(out))
