"""The dataset runner of ``murk synth``: workers, shards, resume, and the output folder's index files.

Output layout (``OUT_DIR``)::

    degraded/<stem>_v<k>.png     the synthetic underwater images
    clean/<stem>.png             the clean image (after --crop/--size)
    depth/<stem>.png             its depth, uint16 millimetres, 0 = invalid in the source
    snow_alpha/<stem>_v<k>.png   a_ms of Eq. (8) as 8-bit (marine_snow stage)
    basic/, transmission/        Eq. (1) result and T (--save-intermediate)
    manifest.jsonl               one line per variant: every parameter (see MANIFEST_FIELDS)
    train.txt                    Joint-ID list: "<input> <enhanced_gt> <depth_gt> <depth_scale>"
    metadata.jsonl               Hugging Face imagefolder metadata ("file_name" = the degraded image)
    config.yaml                  the resolved configuration, with the seed and murk version
    errors.jsonl                 inputs that failed in the latest run (rewritten by every run; absent when none)
    .murk/progress-*.jsonl       append-only logs that make resuming possible

Reproducibility: variant ``k`` of image ``stem`` is drawn from ``derive_seed(seed, stem, k)``, so the bytes
of every file depend neither on ``workers`` nor on interruptions; a rerun skips variants whose log record and
files exist; index files are rebuilt sorted at the end of every run (and of every shard).

Faults: the output folder may not be or lie inside a folder of input files, and its subfolders may not hold
input files (they would be overwritten or mixed with outputs; :func:`murk.io.paths.check_output_location`):
``murk synth RGBD_DIR RGBD_DIR`` is refused, ``RGBD_DIR/synth`` is fine; workers die with the parent
(:mod:`murk._workers`); a full disk stops the run with ``OutputError`` naming the file (queued work is
cancelled; what was finished is kept and a rerun resumes).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ThreadPoolExecutor, as_completed
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, Literal

import numpy as np

from murk._config import dump_yaml
from murk._version import __version__
from murk._workers import stop_if_orphaned, worker_pool
from murk.io.atomic import make_output_folder, remove_stale_temporaries, write_text_atomic
from murk.io.depth import write_depth_png
from murk.io.images import to_uint, write_rgb, write_uint
from murk.io.jobs import ErrorRecord, JobSummary
from murk.io.jsonl import append_jsonl, read_jsonl, write_jsonl
from murk.io.pairs import RGBDSource
from murk.io.paths import check_output_location
from murk.io.writer import BackgroundWriter
from murk.rng import derive_seed
from murk.synth.common import (
    DEPTH_SCALE_OUT,
    OVERLAP_WHY,
    Shard,
    check_config_compatible,
    check_snow_bank,
    depth_range_note,
    input_locations,
    load_source,
    manifest_record,
    setup_worker,
    variant_info,
)
from murk.synth.config import SynthConfig
from murk.synth.params import sample_variant, snow_sampler_for
from murk.synth.render import depth_range, render

DataFormat = Literal["files", "webdataset"]
"""``murk synth --format``: loose PNG folders or tar shards (:mod:`murk.synth.shards`)."""


@dataclass
class RunSummary(JobSummary):
    """What a run did: the job summary (:class:`murk.io.jobs.JobSummary`; processed/skipped count variants)
    and the number of clean images of this shard. ``notes`` warn about the inputs (implausible depth ranges)."""

    command: str = "synth"
    images: int = 0

    @property
    def out_dir(self) -> Path:
        return Path(self.out or ".")

    @property
    def variants_written(self) -> int:
        return self.processed

    @property
    def variants_skipped(self) -> int:
        return self.skipped

    @property
    def variants_per_s(self) -> float:
        return self.processed / self.wall_s if self.wall_s > 0 else 0.0


# ------------------------------------------------------------------------------------------ per-image work


def paths_for(stem: str, k: int) -> dict[str, str]:
    """Output paths of variant ``k`` of ``stem``, relative to the output folder."""
    return {
        "degraded": f"degraded/{stem}_v{k}.png",
        "clean": f"clean/{stem}.png",
        "depth": f"depth/{stem}.png",
        "snow_alpha": f"snow_alpha/{stem}_v{k}.png",
        "basic": f"basic/{stem}_v{k}.png",
        "transmission": f"transmission/{stem}_v{k}.png",
    }


_WORKER_BANK: Any = None


def _init_worker(bank_path: str | None) -> None:
    global _WORKER_BANK
    _WORKER_BANK = setup_worker(bank_path)


def _init_pool_worker(bank_path: str | None) -> None:
    from murk._workers import die_with_parent

    die_with_parent()
    _init_worker(bank_path)


def process_source(
    source: RGBDSource,
    variants: Sequence[int],
    config: SynthConfig,
    out_dir: str,
    bank: Any = None,
    loaded: Future[tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
) -> tuple[list[dict[str, Any]], list[ErrorRecord]]:
    """Load one RGB-D pair and write the requested variants; returns their manifest records (or a problem).

    ``loaded``: :func:`load_source` of ``source`` already submitted to a reader thread (the one-process run
    reads the next pair while this one renders); its errors are reported as a failed read, as here."""
    bank = _WORKER_BANK if bank is None else bank
    out = Path(out_dir)
    try:
        rgb, depth, valid = load_source(source, config) if loaded is None else loaded.result()
    except (ValueError, OSError) as exc:
        return [], [ErrorRecord(source.rgb_path, "read", str(exc))]
    note = depth_range_note(source, depth[valid])
    png = config.output.png_compression
    files0 = paths_for(source.stem, 0)
    writer = _writer()  # files are encoded and written on writer threads while the next variant renders
    try:
        if not (out / files0["clean"]).exists():
            writer.submit(partial(write_rgb, out / files0["clean"], rgb, png_compression=png))
        if not (out / files0["depth"]).exists():
            depth_out = np.where(valid, depth, 0.0)
            writer.submit(partial(write_depth_png, out / files0["depth"], depth_out, depth_scale=DEPTH_SCALE_OUT))
        snow_sampler = snow_sampler_for(config, bank) if "marine_snow" in config.stages else None
        records = []
        h, w = depth.shape
        valid_fraction = float(valid.mean())
        span = depth_range(depth)  # checked once for all variants
        for k in variants:
            stop_if_orphaned()  # a worker whose parent died stops here (see murk._workers)
            seed = derive_seed(config.seed, source.stem, k)
            params = sample_variant(np.random.default_rng(seed), config, snow_sampler=snow_sampler)
            res = render(
                rgb, depth, params, bank=bank, keep_intermediate=config.output.save_intermediate, depth_range_m=span
            )
            files = paths_for(source.stem, k)
            keep = {"degraded": files["degraded"], "clean": files["clean"], "depth": files["depth"]}
            group = []  # one variant's files, written in this order on one writer thread
            if res.snow_alpha is not None:
                alpha_u8 = to_uint(res.snow_alpha[:, :, None], 8)[:, :, 0]
                group.append(partial(write_uint, out / files["snow_alpha"], alpha_u8, png_compression=png))
                keep["snow_alpha"] = files["snow_alpha"]
            if config.output.save_intermediate:
                group.append(partial(write_rgb, out / files["basic"], res.basic, png_compression=png))  # type: ignore[arg-type]
                group.append(partial(write_rgb, out / files["transmission"], res.transmission, png_compression=png))  # type: ignore[arg-type]
                keep.update(basic=files["basic"], transmission=files["transmission"])
            # last: its presence marks the variant done
            group.append(partial(write_rgb, out / files["degraded"], res.degraded, png_compression=png))
            writer.submit(*group)
            info = variant_info(res, w, h, valid_fraction, note)
            records.append(manifest_record(source, k, seed, params, info, keep))
    except BaseException:
        with contextlib.suppress(Exception):  # the first error wins; the queued writes still finish
            writer.drain()
        raise
    writer.drain()  # the records are returned (and logged as done) only once every file is complete
    return records, []


_WRITER: BackgroundWriter | None = None


def _writer() -> BackgroundWriter:
    """This process's writer threads (created on first use; worker processes each have their own)."""
    global _WRITER
    if _WRITER is None:
        _WRITER = BackgroundWriter(threads=WRITER_THREADS)
    return _WRITER


WRITER_THREADS = 2
"""Writer threads per process: PNG encoding (about as long as rendering a variant) overlaps the rendering."""


# ---------------------------------------------------------------------------------------------- the run


def _progress_dir(out_dir: Path) -> Path:
    return out_dir / ".murk"


def load_records(out_dir: Path) -> dict[tuple[str, int], dict[str, Any]]:
    """All variant records of every progress log in ``out_dir`` whose files still exist, by (stem, variant)."""
    records: dict[tuple[str, int], dict[str, Any]] = {}
    for log in sorted(_progress_dir(out_dir).glob("progress-*.jsonl")):
        for rec in read_jsonl(log):
            files = [rec[k] for k in ("degraded", "clean", "depth", "snow_alpha", "basic", "transmission") if k in rec]
            if all((out_dir / f).exists() for f in files):
                records[(rec["stem"], int(rec["variant"]))] = rec
    return records


def write_index(out_dir: Path, records: dict[tuple[str, int], dict[str, Any]]) -> None:
    """Rebuild manifest.jsonl, train.txt and metadata.jsonl (sorted by stem, variant) atomically."""
    ordered = [records[k] for k in sorted(records)]
    write_jsonl(out_dir / "manifest.jsonl", ordered)
    write_text_atomic(
        out_dir / "train.txt",
        "".join(f"{r['degraded']} {r['clean']} {r['depth']} {DEPTH_SCALE_OUT:g}\n" for r in ordered),
    )
    meta_keys = ("stem", "variant", "water_type", "H", "D", "clean", "depth", "snow_alpha", "N_p", "rho")
    write_jsonl(
        out_dir / "metadata.jsonl",
        [{"file_name": r["degraded"], **{k: r[k] for k in meta_keys if k in r}} for r in ordered],
    )


OUTPUT_FOLDERS = ("degraded", "clean", "depth", "snow_alpha", "basic", "transmission", ".murk")
"""The subfolders a run writes into: no input file may lie in one."""


def run_synthesis(
    sources: Sequence[RGBDSource],
    out_dir: str | Path,
    config: SynthConfig,
    *,
    shard: Shard = Shard(),
    bank_path: str | None = None,
    problems: Sequence[ErrorRecord] = (),
    on_progress: Callable[[int, int], None] | None = None,
) -> RunSummary:
    """Generate (or resume) a synthetic dataset. See the module docstring for the output layout.

    Args:
        sources: the clean RGB-D pairs (all of them; the shard picks its part).
        out_dir: output folder (created).
        config: the run's configuration.
        shard: which part of the sorted inputs this process handles.
        bank_path: particle bank file, required when the marine_snow stage is on.
        problems: input problems found before the run (unpaired files); reported in errors.jsonl.
        on_progress: called as ``on_progress(variants_done, variants_total)`` after each image.

    Raises:
        ValueError: ``out_dir`` overlaps the folders of the input files (see above); a bad bank or configuration.
        OutputError: no space left on the device (the message names the file; a rerun resumes).
    """
    out = Path(out_dir)
    check_output_location(out, input_locations(sources), option="OUT_DIR", writes=OUTPUT_FOLDERS, why=OVERLAP_WHY)
    check_snow_bank(config, bank_path)
    make_output_folder(out)
    check_config_compatible(out, config)
    remove_stale_temporaries(out)
    write_text_atomic(out / "config.yaml", dump_yaml(config, murk_version=__version__))
    mine = sorted(sources, key=lambda s: s.stem)[shard.index :: shard.count]
    done = load_records(out)
    todo: list[tuple[RGBDSource, list[int]]] = []
    summary = RunSummary(out=out, images=len(mine), failures=list(problems), failed=len(problems))
    for s in mine:
        missing = [k for k in range(config.variants) if (s.stem, k) not in done]
        summary.skipped += config.variants - len(missing)
        if missing:
            todo.append((s, missing))
    log = _progress_dir(out) / f"progress-{shard.tag}.jsonl"
    total = len(mine) * config.variants
    finished = summary.skipped
    if on_progress:
        on_progress(finished, total)

    def collect(records: list[dict[str, Any]], errs: list[ErrorRecord], n_asked: int) -> None:
        nonlocal finished
        append_jsonl(log, records)
        summary.processed += len(records)
        for err in errs:
            summary.add_failure(err)
        finished += n_asked
        if on_progress:
            on_progress(finished, total)

    if config.workers <= 1 or len(todo) <= 1:
        _init_worker(bank_path)
        # One reader thread decodes the next pair while this one renders (OpenCV's decoders release the GIL).
        with ThreadPoolExecutor(1, thread_name_prefix="murk-reader") as reader:
            ahead = [reader.submit(load_source, s, config) for s, _ in todo[:1]]
            for i, (s, ks) in enumerate(todo):
                if i + 1 < len(todo):
                    ahead.append(reader.submit(load_source, todo[i + 1][0], config))
                collect(*process_source(s, ks, config, str(out), loaded=ahead.pop(0)), len(ks))
    else:
        import multiprocessing as mp

        ctx = mp.get_context("spawn")
        # On an error (Ctrl+C, a full disk) the queued images are cancelled and the workers stopped at once.
        with worker_pool(config.workers, mp_context=ctx, initializer=_init_pool_worker, initargs=(bank_path,)) as ex:
            futures = {ex.submit(process_source, s, ks, config, str(out)): len(ks) for s, ks in todo}
            for fut in as_completed(futures):
                collect(*fut.result(), futures[fut])
    final = load_records(out)
    write_index(out, final)
    summary.notes = sorted({r["depth_warning"] for r in final.values() if r.get("depth_warning")})
    summary.write_errors(out)
    return summary.finish()


def synthesize(
    out_dir: str | Path,
    config: SynthConfig,
    *,
    rgbd: str | Path | None = None,
    list_file: str | Path | None = None,
    shard: Shard = Shard(),
    data_format: DataFormat = "files",
    samples_per_shard: int = 256,
    backend: Literal["local", "ray"] = "local",
    ray_address: str | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> JobSummary:
    """``murk synth`` as one call: find the clean pairs (a folder or NYU ``.mat`` file ``rgbd``, or a list file),
    pick the particle bank (``config.marine_snow.bank``, else the shipped one) and run :func:`run_synthesis`
    (``data_format="files"``: loose PNG folders, returns a :class:`RunSummary`) or
    :func:`murk.synth.shards.write_shards` (``"webdataset"``: tar shards, locally or on Ray).

    Raises:
        ValueError: neither or both of ``rgbd`` and ``list_file``; no pair found (the first problems named);
            an unknown ``data_format``; ``backend``/``ray_address`` without ``data_format="webdataset"``.
    """
    from murk.io.pairs import discover, read_list

    if (rgbd is None) == (list_file is None):
        raise ValueError("give either RGBD_DIR or --list FILE")
    if data_format not in ("files", "webdataset"):
        raise ValueError(f"--format: expected files or webdataset, got {data_format!r}")
    if data_format == "files" and (backend != "local" or ray_address):
        raise ValueError("--backend ray and --ray-address need --format webdataset")
    if list_file is not None:
        if config.input.depth_from == "layout":
            raise ValueError("--depth-from layout reads a folder of photographs: give RGBD_DIR, not --list")
        sources, problems = read_list(list_file), list[ErrorRecord]()
    else:
        sources, problems = discover(rgbd, config.input.depth_from)  # type: ignore[arg-type]
    if not sources:
        why = "; ".join(f"{p.input}: {p.error}" for p in problems[:3])
        raise ValueError(
            f"{rgbd if list_file is None else list_file}: no RGB-D pairs found" + (f" ({why})" if why else "")
        )
    bank_path = None
    if "marine_snow" in config.stages:
        from murk.data import default_snow_bank

        bank_path = config.marine_snow.bank or str(default_snow_bank())
    unused_bank = config.marine_snow.bank and "marine_snow" not in config.stages
    if data_format == "webdataset":
        from murk.synth.shards import write_shards

        summary = write_shards(
            sources,
            out_dir,
            config,
            samples_per_shard=samples_per_shard,
            shard=shard,
            bank_path=bank_path,
            problems=problems,
            backend=backend,
            ray_address=ray_address,
            on_progress=on_progress,
        )
    else:
        summary = run_synthesis(
            sources, out_dir, config, shard=shard, bank_path=bank_path, problems=problems, on_progress=on_progress
        )
    if unused_bank:
        summary.note(f"--snow-bank {config.marine_snow.bank} was not used: marine_snow is not among the stages")
    return summary
