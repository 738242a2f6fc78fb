"""``murk train``: retrain Joint-ID (the paper's experiment), or train the lite restorer, from a YAML config."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from murk.cli._common import QuietOpt, make_console, merge_flags
from murk.cli._jobs import print_summary


def train(
    config_file: Annotated[Path, typer.Option("--config", help="Training YAML (see configs/).")],
    steps: Annotated[int | None, typer.Option("--steps", help="Total optimiser steps (overrides epochs).")] = None,
    out: Annotated[Path | None, typer.Option("--out", help="Output folder (checkpoints, logs).")] = None,
    device: Annotated[str | None, typer.Option("--device", help="cpu, cuda or cuda:N.")] = None,
    data: Annotated[
        str | None,
        typer.Option(
            "--data",
            help="murk synth folder, Joint-ID list, clean RGB-D folder (online synthesis), 'scenes', or tar shards "
            "('out/shards/{000000..000199}.tar', or the index.json of 'murk synth --format webdataset').",
        ),
    ] = None,
    photos: Annotated[
        Path | None,
        typer.Option(
            "--photos",
            help="Folder of clean photographs mixed into the procedural scenes (data.photos; without depth: "
            "data.depth_from layout).",
        ),
    ] = None,
    eval_real: Annotated[
        Path | None, typer.Option("--eval-real", help="Folder of REAL underwater images scored with UIQM/UCIQE.")
    ] = None,
    resume: Annotated[
        bool,
        typer.Option(
            "--resume",
            help="Continue from OUT/latest.pt (bit-exact on CPU) with the run's own settings (other ones are refused); "
            "without it, a folder that holds a run is refused.",
        ),
    ] = False,
    stop_after: Annotated[
        int | None, typer.Option("--stop-after", help="Stop after N steps in this run (resume later with --resume).")
    ] = None,
    batch: Annotated[int | None, typer.Option("--batch", help="Samples per process per step.")] = None,
    epochs: Annotated[float | None, typer.Option("--epochs", help="Epochs (when --steps is not given).")] = None,
    precision: Annotated[str | None, typer.Option("--precision", help="fp32 or bf16.")] = None,
    seed: Annotated[int | None, typer.Option("--seed", help="Seed of everything random.")] = None,
    workers: Annotated[int | None, typer.Option("--workers", help="DataLoader workers per process.")] = None,
    quiet: QuietOpt = False,
) -> None:
    """Train Joint-ID (unchanged architecture and loss), or the lite real-time restorer (model.kind: lite, e.g.
    configs/train-lite-cpu.yaml), on synthetic underwater data.

    Single process, or DistributedDataParallel with: torchrun --nproc_per_node N -m murk train --config ...
    """
    from murk._config import load_yaml, merge
    from murk.data import resolve_builtin
    from murk.train.config import TrainConfig
    from murk.train.sources import check_sources

    flags = {
        "out": None if out is None else str(out),
        "eval_real": None if eval_real is None else str(eval_real),
        "photos": None if photos is None else str(photos),
    }
    values = {**locals(), **flags}
    config = merge_flags(load_yaml(TrainConfig, config_file), CONFIG_PATHS, values)
    resolved: dict[str, Any] = {"data": {"source": resolve_builtin(config.data.source)}}
    if config.eval.real:
        resolved["eval"] = {"real": resolve_builtin(config.eval.real)}
    if config.data.val_source:
        resolved["data"]["val_source"] = resolve_builtin(config.data.val_source)
    config = merge(config, resolved, where="config")
    check_sources(config)  # a missing data source answers here, before the trainer (and torch) is imported
    console = make_console(quiet)
    total = config.steps if config.steps is not None else "?"

    def on_log(rec: dict[str, Any]) -> None:
        if rec["kind"] == "train":
            console.print(
                f"step {rec['step']}/{total}  loss {rec['loss']:.4f}  lr {rec['lr']:.2e}  "
                f"{rec['images_per_s']:.1f} img/s",
                highlight=False,
            )
        else:
            shown = "  ".join(f"{k} {v:.4g}" for k, v in rec.items() if k not in ("kind", "step") and v is not None)
            console.print(f"eval @ {rec['step']}: {shown}", highlight=False)

    from murk.workflows.distill import train_network as run_train  # torch

    summary = run_train(config, resume=resume, stop_after=stop_after, on_log=on_log)
    detail = (
        f"{summary.steps_done}/{summary.total_steps} steps done, last loss {_loss_text(summary.last_loss)}, "
        f"{summary.images_per_s:.1f} img/s, best {_best_text(summary.best)} -> {summary.out_dir}"
    )
    raise typer.Exit(print_summary(summary, "step", detail=detail))


CONFIG_PATHS = {
    "steps": "steps",
    "batch": "batch",
    "epochs": "epochs",
    "precision": "precision",
    "seed": "seed",
    "device": "device",
    "out": "out",
    "data": "data.source",
    "photos": "data.photos",
    "workers": "data.workers",
    "eval_real": "eval.real",
}
"""Each flag's path in :class:`murk.train.config.TrainConfig` (flags override the --config file)."""


def _best_text(best: dict[str, Any] | None) -> str:
    """``val_psnr 16.28 at step 20`` from the run's best-checkpoint record; ``-`` before the first evaluation."""
    if not best:
        return "-"
    return f"{best.get('metric')} {best.get('value', float('nan')):.4g} at step {best.get('step')}"


def _loss_text(loss: float) -> str:
    return f"{loss:.4f}" if math.isfinite(loss) else "-"
