"""``murk detail``: train the detail network (the learned local residual of the ``detail`` method)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import QuietOpt, command_group, make_console, print_error

app = command_group("The detail stage: a learned local residual that takes away what a global colour map cannot.")


@app.command("train")
def train(
    config_files: Annotated[
        list[Path],
        typer.Option("--config", help="Training YAML whose data.synthesis makes the water; repeat to mix waters."),
    ],
    out: Annotated[Path, typer.Option("--out", help="Output folder (detail.npz, log.jsonl, samples.npz).")],
    scenes: Annotated[
        int, typer.Option("--scenes", help="Synthetic scenes to learn from (shared by the configs).")
    ] = 1000,
    steps: Annotated[int, typer.Option("--steps", help="Optimiser steps.")] = 2000,
    channels: Annotated[int, typer.Option("--channels", help="Width of the hidden convolutions.")] = 24,
    base: Annotated[str, typer.Option("--base", help="The method whose restorations it learns to improve.")] = "lite",
    stages: Annotated[
        str | None,
        typer.Option("--stages", help="Synthesis stages for every config, comma-separated (e.g. basic,camera)."),
    ] = None,
    eq1_share: Annotated[
        float,
        typer.Option(
            "--eq1-share",
            help="Share in [0, 1] of each config's scenes degraded without its forward_scatter and marine_snow stages.",
        ),
    ] = 0.0,
    crops: Annotated[
        str,
        typer.Option(
            "--crops",
            help="Training crops cut from the frame padded once, as inference pads it ('frame'), or each crop padded "
            "at its own edges ('own', as the first shipped weights).",
        ),
    ] = "frame",
    photos: Annotated[
        Path | None,
        typer.Option("--photos", help="Folder of clean photographs, each also degraded in every part's water."),
    ] = None,
    specks: Annotated[
        float,
        typer.Option(
            "--specks",
            help="Small sharp details (dots, strokes, small ellipses) per megapixel painted on every procedural clean "
            "scene, so that the network sees small bright things that must stay (0: none).",
        ),
    ] = 0.0,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the scenes and the training.")] = 7,
    quiet: QuietOpt = False,
) -> None:
    """Train the detail network on a base method's restorations of murk's synthetic water (docs/models/detail.md)."""
    from murk.train.detail import DetailTrainSettings
    from murk.workflows.detail_train import train_detail

    console = make_console(quiet)
    try:
        settings = DetailTrainSettings(steps=steps, channels=channels, seed=seed, crops=crops)
        result = train_detail(
            out,
            configs=config_files,
            stages=None if stages is None else stages.split(","),
            eq1_share=eq1_share,
            photos=photos,
            specks_per_mpx=specks,
            base=base,
            scenes=scenes,
            settings=settings,
            seed=seed,
            progress=lambda msg: console.print(msg, markup=False, highlight=False),
        )
    except ValueError as exc:
        print_error(str(exc))
        raise typer.Exit(2) from None
    typer.echo(result.summary())
