"""``murk water``: the water in underwater images (veil colour, attenuation, visibility in metres), and training
the estimator that gives it."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import QuietOpt, command_group, make_console

app = command_group("The water in underwater images: veil colour, attenuation per channel, visibility in metres.")


@app.command("estimate")
def estimate(
    inputs: Annotated[list[Path], typer.Argument(help="Underwater image files or folders of images.")],
    json_out: Annotated[Path | None, typer.Option("--json", help="Also write the estimates here (JSON lines).")] = None,
    estimator: Annotated[
        Path | None, typer.Option("--estimator", help="Water estimator weights (.npz; default: shipped).")
    ] = None,
    quiet: QuietOpt = False,
) -> None:
    """Estimate each image's water from the image and Joint-ID's distance map (docs/models/water.md). The figures
    are what restores best with that distance map on murk's synthetic water, not a calibrated measurement. One line
    per image on stdout (unless --quiet); errors on stderr."""
    from murk.io.jobs import ErrorRecord
    from murk.models.water import MEASURABLE_FACTOR
    from murk.workflows.water_estimate import estimate_water

    try:
        results = estimate_water(inputs, estimator=estimator, json_out=json_out)
    except ValueError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    failed = 0
    for r in results:
        if isinstance(r, ErrorRecord):
            failed += 1
            typer.echo(f"error: {r.error}", err=True)
            continue
        d = r.as_dict()
        veil = " ".join(f"{v:.2f}" for v in d["veil_rgb"])  # type: ignore[attr-defined]
        att = " ".join(f"{v:.3f}" for v in d["attenuation_per_m"])  # type: ignore[attr-defined]
        seen = (
            f"visibility {r.view.water.visibility_m:.1f} m"
            if r.view.measurable
            else f"visibility beyond {MEASURABLE_FACTOR * r.view.far_distance_m:.0f} m (haze too faint to measure)"
        )
        if not quiet:
            typer.echo(f"{r.path}: veil RGB {veil}, attenuation RGB {att} /m, {seen}")
    if failed:
        raise typer.Exit(1)


@app.command("train")
def train(
    config_file: Annotated[
        Path, typer.Option("--config", help="Training YAML whose data.synthesis makes the water (see configs/).")
    ],
    out: Annotated[Path, typer.Option("--out", help="Output folder (water.npz, log.jsonl, samples.npz).")],
    scenes: Annotated[int, typer.Option("--scenes", help="Synthetic scenes to learn from.")] = 4000,
    steps: Annotated[int, typer.Option("--steps", help="Optimiser steps.")] = 4000,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the scenes and the training.")] = 7,
    quiet: QuietOpt = False,
) -> None:
    """Train the water estimator on murk's synthetic water with the shipped Joint-ID's distance maps."""
    from murk._config import load_yaml
    from murk.train.config import TrainConfig
    from murk.train.water import WaterTrainSettings
    from murk.workflows.water_train import train_water

    console = make_console(quiet)
    try:
        cfg = load_yaml(TrainConfig, config_file)
        settings = WaterTrainSettings(steps=steps, seed=seed)
        result = train_water(
            out, synthesis=cfg.data.synthesis, scenes=scenes, seed=seed, settings=settings,
            progress=lambda msg: console.print(msg, markup=False, highlight=False),
        )  # fmt: skip
    except ValueError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(2) from None
    typer.echo(result.summary())
