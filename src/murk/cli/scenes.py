"""``murk scenes``: write procedural construction-site RGB-D scenes in the ``murk synth`` input layout
(the work is :func:`murk.scenes.dataset.write_scenes`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from murk.cli._common import QuietOpt, make_console, parse_size
from murk.cli._jobs import JobProgress, print_summary


def scenes(
    out_dir: Annotated[Path, typer.Argument(help="Output folder (rgb/, depth/, scenes.jsonl).")],
    count: Annotated[int, typer.Option("--count", "-n", min=1, help="Number of scenes.")] = 100,
    size: Annotated[str, typer.Option("--size", help="Image size WIDTHxHEIGHT.")] = "640x480",
    seed: Annotated[int, typer.Option("--seed", help="Global seed; scene i uses derive_seed(seed, i).")] = 0,
    workers: Annotated[int, typer.Option("--workers", "-j", min=1, help="Worker processes.")] = 1,
    config: Annotated[
        Path | None, typer.Option("--config", help="YAML file with SceneConfig fields (murk.scenes.SceneConfig).")
    ] = None,
    textures: Annotated[
        Path | None, typer.Option("--textures", help="Folder of images used as surface textures (optional).")
    ] = None,
    rgb_format: Annotated[str, typer.Option("--rgb-format", help="png (lossless) or jpg.")] = "png",
    quiet: QuietOpt = False,
) -> None:
    """Generate procedural underwater construction-site scenes: clean RGB + exact metric distance.

    The output folder is a clean RGB-D input of [bold]murk synth[/]: rgb/, depth/ (uint16 mm), scenes.jsonl.

    Depth = line-of-sight distance along each pixel's ray (not z-depth), in near_m..far_m (default
    0.3-15 m); a ray that hits nothing gets far_m.
    """
    from murk._config import read_yaml
    from murk.scenes import SceneConfig
    from murk.scenes.dataset import load_textures

    console = make_console(quiet)
    wh = parse_size(size)
    fmt = rgb_format.lower()
    if fmt not in ("png", "jpg"):
        raise ValueError(f"--rgb-format: expected png or jpg, got {rgb_format!r}")
    cfg_dict: dict[str, Any] = {} if config is None else read_yaml(config, what="SceneConfig fields")
    texture_problems: list[Any] = []
    tex = load_textures(textures, texture_problems) if textures is not None else {}
    if tex:
        cfg_dict = {**cfg_dict, "texture_names": sorted(tex)}
    cfg = SceneConfig.from_dict(cfg_dict, where=str(config) if config is not None else "scene config")

    from murk.scenes.dataset import write_scenes

    with JobProgress(console, "scenes", total=count, unit="scenes") as progress:
        result = write_scenes(
            out_dir,
            count=count,
            size=wh,
            seed=seed,
            workers=workers,
            config=cfg,
            textures=tex,
            rgb_format=fmt,
            on_progress=lambda done, total: progress.update(done, total),
            texture_problems=texture_problems,
        )
    raise typer.Exit(print_summary(result, "scene", detail=f"-> {out_dir}"))
