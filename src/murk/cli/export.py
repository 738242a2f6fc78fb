"""``murk export``: a Joint-ID or ``lite`` checkpoint to an ONNX file (dynamic batch, height and width)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import QuietOpt, make_console

VERIFY_TOLERANCE = 1e-3
"""Max absolute difference (depth in metres, enhanced in [0, 1]) allowed between ONNX Runtime and torch."""


def export(
    checkpoint: Annotated[
        Path,
        typer.Option("--checkpoint", "-c", help="Joint-ID checkpoint (murk's or the official .pth), or a lite one."),
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
    quiet: QuietOpt = False,
) -> None:
    """Export a Joint-ID or lite checkpoint to ONNX (dynamic batch, height and width).

    Joint-ID: the graph takes 'image' (B, 3, H, W), normalised, H and W multiples of 32, and returns 'depth_m'
    and 'enhanced'. Run it with: murk enhance IMAGES --out OUT --method jointid --checkpoint model.onnx

    lite (told apart by the file's format): the folded network; 'image' is RGB in [0, 1], H and W multiples of
    16, the output 'enhanced'. Run it with: murk enhance IMAGES --out OUT --method lite --checkpoint lite.onnx

    udaformer, ursct (--model): the paper's baselines for ONE frame size (--size; dynamic batch): 'image' is
    what the network takes (UDAformer BGR, URSCT-SESR RGB, [0, 1]), the output 'enhanced' (unclamped). Their
    size-dependent window padding and masks are traced as constants, so the graph rejects or miscomputes other
    sizes; murk's torch restorers (--method udaformer/ursct) take any size.
    """
    import torch

    from murk.models.jointid import load_checkpoint, normalize_input
    from murk.models.jointid.onnx_export import OnnxJointID, compare_onnx, export_onnx
    from murk.models.lite.checkpoint import is_lite_checkpoint

    console = make_console(quiet)
    if out.suffix.lower() != ".onnx":
        raise ValueError(f"--out: expected a file name ending in .onnx, got {str(out)!r}")
    if network in ("udaformer", "ursct"):
        _export_baseline(network, checkpoint, out, size, opset, verify, trust_checkpoint, console)
        return
    if network != "auto":
        raise ValueError(f"--model: expected auto, udaformer or ursct, got {network!r}")
    if is_lite_checkpoint(checkpoint):
        from murk.models.lite.onnx_export import export_lite_checkpoint

        done = export_lite_checkpoint(checkpoint, out, opset=opset, verify=verify, trust=trust_checkpoint)
        console.print(f"exported lite {checkpoint} (folded: {done.parameters:,} parameters) to {out} (opset {opset})")
        for (h, w), diff in done.max_abs_diff.items():
            console.print(f"verified {h}x{w}: max |onnx - torch| enhanced {diff:.2e}")
        typer.echo(str(out))
        return
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


def _export_baseline(
    name: str, checkpoint: Path, out: Path, size: str, opset: int, verify: bool, trust: bool, console: object
) -> None:
    """UDAformer or URSCT-SESR weights -> a fixed-size ONNX graph (dynamic batch), verified with ONNX Runtime."""
    from murk.cli._common import parse_size
    from murk.models.baseline_onnx import export_baseline_onnx

    w, h = parse_size(size, option="--size")
    if name == "udaformer":
        from murk.models.udaformer import load_udaformer

        net = load_udaformer(checkpoint, trust=trust)
    else:
        from murk.models.ursct_sesr import load_ursct
        from murk.models.ursct_sesr.network import SIZE_MULTIPLE

        if h != w or h % SIZE_MULTIPLE:
            raise ValueError(f"--size: ursct needs a square size that is a multiple of {SIZE_MULTIPLE}, got {size!r}")
        net = load_ursct(checkpoint, trust=trust, img_size=h)
    done = export_baseline_onnx(net, out, size_hw=(h, w), opset=opset, verify=verify)
    console.print(  # type: ignore[attr-defined]
        f"exported {name} {checkpoint} ({done.parameters:,} parameters) to {out} (opset {opset}; fixed {w}x{h}, "
        "dynamic batch: the graph only takes this size)"
    )
    for b, diff in done.max_abs_diff.items():
        console.print(f"verified batch {b} at {w}x{h}: max |onnx - torch| {diff:.2e}")  # type: ignore[attr-defined]
        if diff > VERIFY_TOLERANCE:
            raise ValueError(
                f"{out}: ONNX Runtime differs from torch by {diff:.3g} (tolerance {VERIFY_TOLERANCE}); the export "
                "is not trustworthy"
            )
    typer.echo(str(out))
