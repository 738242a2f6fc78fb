"""``murk study``: the paper's ablation (models differing only in the training data's stages), trained and
evaluated by one resumable command."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import QuietOpt, make_console
from murk.cli._jobs import print_summary


def study(
    config_file: Annotated[Path, typer.Argument(help="Study YAML (see configs/study-paper-cpu.yaml).")],
    out: Annotated[Path, typer.Option("--out", help="Study folder (models, configs, report).")],
    train_only: Annotated[
        bool, typer.Option("--train-only", help="Train the arms and stop (evaluate later by rerunning).")
    ] = False,
    real_pairs: Annotated[
        Path | None,
        typer.Option(
            "--real-pairs",
            help="Real paired photographs (input/ and reference/, or a folder of such sets): every arm is also "
            "scored with PSNR, SSIM and CIEDE2000 against the references (overrides eval.real_pairs).",
        ),
    ] = None,
    snow_pairs: Annotated[
        Path | None,
        typer.Option(
            "--snow-pairs",
            help="Real scenes with and without marine snow (snowy/ and clean/, matched by stem): every arm's snow "
            "residue on the known particle sites (overrides eval.snow_pairs).",
        ),
    ] = None,
    quiet: QuietOpt = False,
) -> None:
    """Train models that differ ONLY in the training data's synthesis stages, then evaluate and report them.

    Rerun the same command to continue a killed study: finished models are not retrained.
    """
    from murk.report.study import run_study

    console = make_console(quiet)
    result = run_study(
        config_file,
        out,
        train_only=train_only,
        on_event=lambda m: console.print(m, highlight=False),
        real_pairs=real_pairs,
        snow_pairs=snow_pairs,
    )
    raise typer.Exit(print_summary(result, "arm", detail=result.message.removeprefix("study: ")))
