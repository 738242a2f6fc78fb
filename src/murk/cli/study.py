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
    quiet: QuietOpt = False,
) -> None:
    """Train models that differ ONLY in the training data's synthesis stages, then evaluate and report them.

    Rerun the same command to continue a killed study: finished models are not retrained.
    """
    from murk.report.study import run_study

    console = make_console(quiet)
    result = run_study(config_file, out, train_only=train_only, on_event=lambda m: console.print(m, highlight=False))
    raise typer.Exit(print_summary(result, "arm", detail=result.message.removeprefix("study: ")))
