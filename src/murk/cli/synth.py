"""``murk synth``: clean RGB-D -> synthetic underwater dataset (Eqs. 1-8 of the paper)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from murk.cli._common import EXIT_PARTIAL, QuietOpt, make_console, parse_size


def synth(
    paths: Annotated[
        list[Path],
        typer.Argument(
            help="RGBD_DIR OUT_DIR. RGBD_DIR holds rgb/ (or color/) and depth/ matched by stem, or is a NYU-v2 "
            "labeled .mat file. With --list give only OUT_DIR.",
            show_default=False,
            metavar="[RGBD_DIR] OUT_DIR",
        ),
    ],
    list_file: Annotated[
        Path | None, typer.Option("--list", help="File of 'rgb_path depth_path' lines instead of RGBD_DIR.")
    ] = None,
    config_file: Annotated[
        Path | None, typer.Option("--config", help="YAML with any option of the run; flags given here override it.")
    ] = None,
    variants: Annotated[int | None, typer.Option("--variants", help="Variants per clean image (default 8).")] = None,
    water_types: Annotated[
        str | None, typer.Option("--water-types", help="'all' or a comma list of I,IA,IB,II,III,1C,3C,5C,7C,9C.")
    ] = None,
    stages: Annotated[
        str | None,
        typer.Option(
            "--stages", help="Comma list of basic,forward_scatter,marine_snow (default basic,forward_scatter)."
        ),
    ] = None,
    fs_mode: Annotated[
        str | None, typer.Option("--fs-mode", help="approx (the paper's Eqs. 5-6, default) or exact (Eq. 4).")
    ] = None,
    distance_mode: Annotated[
        str | None,
        typer.Option(
            "--distance-mode", help="normalized (depth/max mapped to 0.3-H m, default) or metric (true depth)."
        ),
    ] = None,
    seed: Annotated[int | None, typer.Option("--seed", help="Global seed (default 0).")] = None,
    workers: Annotated[int | None, typer.Option("--workers", help="Worker processes (default 1).")] = None,
    shard: Annotated[
        str | None,
        typer.Option("--shard", help="i/N: this process handles part i of N (default: SLURM array variables if set)."),
    ] = None,
    size: Annotated[
        str | None, typer.Option("--size", help="WxH: centre-crop to that aspect ratio, then resize.")
    ] = None,
    save_intermediate: Annotated[
        bool | None, typer.Option("--save-intermediate", help="Also write basic/ and transmission/.")
    ] = None,
    depth_scale: Annotated[
        float | None,
        typer.Option("--depth-scale", help="Raw depth units per metre: 1000 (mm, default), TUM 5000, KITTI 256."),
    ] = None,
    depth_encoding: Annotated[
        str | None,
        typer.Option(
            "--depth-encoding",
            help="linear (value / --depth-scale, default), sun (SUN RGB-D bit-rotated PNG) or kinect-disparity "
            "(raw NYU-v2 Kinect disparity, e.g. its .pgm dumps).",
        ),
    ] = None,
    depth_relative: Annotated[
        bool | None, typer.Option("--depth-relative", help="Depth is 8-bit RELATIVE (larger = farther).")
    ] = None,
    invalid_depth: Annotated[
        str | None, typer.Option("--invalid-depth", help="fill (nearest valid, default), far, or fail.")
    ] = None,
    crop: Annotated[
        int | None, typer.Option("--crop", help="Trim PX pixels from every border (NYU's white frame).")
    ] = None,
    snow_bank: Annotated[
        Path | None,
        typer.Option("--snow-bank", help="Particle bank from 'murk snow extract' (default: the shipped one)."),
    ] = None,
    data_format: Annotated[
        str,
        typer.Option(
            "--format",
            help="files (loose PNG folders, default) or webdataset (tar shards + index.json; docs/scale.md).",
        ),
    ] = "files",
    samples_per_shard: Annotated[
        int, typer.Option("--samples-per-shard", min=1, help="Samples per tar shard (--format webdataset).")
    ] = 256,
    backend: Annotated[
        str, typer.Option("--backend", help="local (worker processes) or ray (Ray tasks; --format webdataset).")
    ] = "local",
    ray_address: Annotated[
        str | None, typer.Option("--ray-address", help="Ray cluster to join (e.g. auto); default: a local Ray.")
    ] = None,
    quiet: QuietOpt = False,
) -> None:
    """Turn clean RGB-D images into a synthetic underwater training set.

    Writes degraded/, clean/, depth/ (uint16 mm), manifest.jsonl, train.txt (Joint-ID list), metadata.jsonl
    and config.yaml into OUT_DIR. Rerunning the same command resumes; results do not depend on --workers.
    """
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    from murk._config import load_yaml, merge
    from murk.data import default_snow_bank
    from murk.io.pairs import discover, read_list
    from murk.synth.config import SynthConfig
    from murk.synth.runner import Shard, run_synthesis

    console = make_console(quiet)
    if list_file is not None:
        if len(paths) != 1:
            raise ValueError("with --list give exactly one argument, OUT_DIR")
        out_dir = paths[0]
        sources, problems = read_list(list_file), []
    else:
        if len(paths) != 2:
            raise ValueError("expected RGBD_DIR OUT_DIR (or --list FILE OUT_DIR)")
        sources, problems = discover(paths[0])
        out_dir = paths[1]
    config = load_yaml(SynthConfig, config_file) if config_file else SynthConfig()
    overrides: dict[str, Any] = {}
    medium: dict[str, Any] = {}
    inp: dict[str, Any] = {}
    for key, value in (("variants", variants), ("stages", stages), ("seed", seed), ("workers", workers)):
        if value is not None:
            overrides[key] = value
    if water_types is not None:
        medium["water_types"] = water_types.split(",")
    if distance_mode is not None:
        medium["distance_mode"] = distance_mode
    if fs_mode is not None:
        overrides["forward_scatter"] = {"mode": fs_mode}
    if save_intermediate is not None:
        overrides["output"] = {"save_intermediate": save_intermediate}
    for key, value in (
        ("depth_scale", depth_scale),
        ("depth_encoding", depth_encoding),
        ("depth_relative", depth_relative),
        ("invalid_depth", invalid_depth),
        ("crop_px", crop),
    ):
        if value is not None:
            inp[key] = value
    if size is not None:
        inp["size"] = list(parse_size(size))
    if snow_bank is not None:
        overrides["marine_snow"] = {"bank": str(snow_bank)}
    if medium:
        overrides["medium"] = medium
    if inp:
        overrides["input"] = inp
    if isinstance(overrides.get("stages"), str):
        overrides["stages"] = overrides["stages"].split(",")
    config = merge(config, overrides, where="command line")
    bank_path = None
    if "marine_snow" in config.stages:
        bank_path = config.marine_snow.bank or str(default_snow_bank())
    shard_obj = Shard.parse(shard)
    if not sources:
        why = "; ".join(f"{p.path}: {p.error}" for p in problems[:3])
        raise ValueError(
            f"{paths[0] if list_file is None else list_file}: no RGB-D pairs found" + (f" ({why})" if why else "")
        )

    if data_format not in ("files", "webdataset"):
        raise ValueError(f"--format: expected files or webdataset, got {data_format!r}")
    if data_format == "files" and (backend != "local" or ray_address):
        raise ValueError("--backend ray and --ray-address need --format webdataset")
    if data_format == "webdataset":
        from murk.synth.shards import describe, write_shards

        with Progress(TextColumn("[bold]synth[/]"), BarColumn(), MofNCompleteColumn(), TextColumn("shards"),
                      TimeRemainingColumn(), console=console, transient=True) as progress:  # fmt: skip
            bar = progress.add_task("synth", total=None)
            job = write_shards(
                sources, out_dir, config, samples_per_shard=samples_per_shard, shard=shard_obj, bank_path=bank_path,
                problems=problems, backend=backend,  # type: ignore[arg-type]
                ray_address=ray_address, on_progress=lambda d, t: progress.update(bar, completed=d, total=t),
            )  # fmt: skip
        make_console().print(describe(job, shard_obj), soft_wrap=True)
        for note in job.notes[:10]:
            make_console().print(f"  [yellow]warning:[/] {note}", soft_wrap=True)
        if job.failed:
            raise typer.Exit(EXIT_PARTIAL)
        return

    with Progress(
        TextColumn("[bold]synth[/]"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("variants"),
        TimeRemainingColumn(),
        console=console,
        transient=True,
    ) as progress:
        task = progress.add_task("synth", total=None)

        def on_progress(done: int, total: int) -> None:
            progress.update(task, completed=done, total=total)

        summary = run_synthesis(
            sources, out_dir, config, shard=shard_obj, bank_path=bank_path, problems=problems, on_progress=on_progress
        )
    where = f" (shard {shard_obj.index}/{shard_obj.count})" if shard_obj.count > 1 else ""
    console = make_console()  # the summary prints even with --quiet
    console.print(
        f"synth{where}: {summary.images} images, {summary.variants_written} variants written, "
        f"{summary.variants_skipped} already done, {len(summary.failures)} failed, "
        f"{summary.variants_per_s:.1f} variants/s -> {summary.out_dir}",
        soft_wrap=True,
    )
    for note in summary.notes[:10]:
        console.print(f"  [yellow]warning:[/] {note}", soft_wrap=True)
    if summary.failures:
        for p in summary.failures[:10]:
            console.print(f"  [red]failed:[/] {p.path}: {p.error}", markup=True, soft_wrap=True)
        console.print(f"  all failures: {Path(summary.out_dir) / 'errors.jsonl'}", soft_wrap=True)
        raise typer.Exit(EXIT_PARTIAL)
