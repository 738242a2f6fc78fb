"""``murk synth``: clean RGB-D -> synthetic underwater dataset (Eqs. 1-8 of the paper)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import QuietOpt, make_console, merge_flags, parse_size
from murk.cli._jobs import JobProgress, print_summary


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
    depth_from: Annotated[
        str | None,
        typer.Option(
            "--depth-from",
            help="file (RGBD_DIR's depth/, default) or layout: RGBD_DIR holds clean photographs without depth "
            "(rgb/ or the folder itself), each given a ground-plane layout's distance (docs/synthesis.md).",
        ),
    ] = None,
    invalid_depth: Annotated[
        str | None, typer.Option("--invalid-depth", help="fill (nearest valid, default), far, or fail.")
    ] = None,
    crop: Annotated[
        int | None, typer.Option("--crop", help="Trim PX pixels from every border (NYU's white frame).")
    ] = None,
    snow_bank: Annotated[
        Path | None,
        typer.Option(
            "--snow-bank",
            help="Particle bank from 'murk snow extract' or 'murk snow relight', or builtin:snow-real / "
            "builtin:snow-small (default builtin:snow: 17,888 real-footage particles, relit).",
        ),
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
    from murk._config import load_yaml
    from murk.synth.common import Shard
    from murk.synth.config import SynthConfig
    from murk.synth.runner import synthesize

    if list_file is not None and len(paths) != 1:
        raise ValueError("with --list give exactly one argument, OUT_DIR")
    if list_file is None and len(paths) != 2:
        raise ValueError("expected RGBD_DIR OUT_DIR (or --list FILE OUT_DIR)")
    flags = dict(locals())  # the parameters by name; CONFIG_PATHS says which config field each one sets
    flags["water_types"] = None if water_types is None else water_types.split(",")
    flags["stages"] = None if stages is None else stages.split(",")
    flags["size"] = None if size is None else list(parse_size(size))
    flags["snow_bank"] = None if snow_bank is None else str(snow_bank)
    config = load_yaml(SynthConfig, config_file) if config_file else SynthConfig()
    config = merge_flags(config, CONFIG_PATHS, flags)
    shard_obj = Shard.parse(shard)
    where = f" (shard {shard_obj.index}/{shard_obj.count})" if shard_obj.count > 1 else ""
    shards = data_format == "webdataset"
    with JobProgress(make_console(quiet), f"synth{where}", unit="shards" if shards else "variants") as progress:
        summary = synthesize(
            paths[-1],
            config,
            rgbd=None if list_file is not None else paths[0],
            list_file=list_file,
            shard=shard_obj,
            data_format=data_format,  # type: ignore[arg-type]
            samples_per_shard=samples_per_shard,
            backend=backend,  # type: ignore[arg-type]
            ray_address=ray_address,
            on_progress=lambda done, total: progress.update(done, total),
        )
    rate = summary.processed / summary.wall_s if summary.wall_s > 0 else 0.0
    if shards:
        detail = f"{rate:.1f} samples/s{where} -> {summary.out}"
        raise typer.Exit(print_summary(summary, "sample", detail=detail))
    detail = f"{summary.images} clean images, {summary.variants_per_s:.1f} variants/s -> {summary.out_dir}"  # type: ignore[attr-defined]
    raise typer.Exit(print_summary(summary, "variant", detail=detail))


CONFIG_PATHS = {
    "variants": "variants",
    "stages": "stages",
    "seed": "seed",
    "workers": "workers",
    "water_types": "medium.water_types",
    "distance_mode": "medium.distance_mode",
    "fs_mode": "forward_scatter.mode",
    "save_intermediate": "output.save_intermediate",
    "depth_scale": "input.depth_scale",
    "depth_encoding": "input.depth_encoding",
    "depth_relative": "input.depth_relative",
    "depth_from": "input.depth_from",
    "invalid_depth": "input.invalid_depth",
    "crop": "input.crop_px",
    "size": "input.size",
    "snow_bank": "marine_snow.bank",
}
"""Each flag's path in :class:`murk.synth.config.SynthConfig` (flags override the --config file)."""
