"""``murk synth --format webdataset``: the synthetic dataset as tar shards (WebDataset layout) plus an index.

Output layout (``OUT_DIR``)::

    shards/000000.tar            samples 0 .. N-1 (N = --samples-per-shard), then 000001.tar, ...
    index.json                   shard -> sample keys, counts, bytes; totals; the configuration
    config.yaml                  the resolved configuration, with format, samples_per_shard and the murk version
    errors.jsonl                 inputs that failed in the latest run (io/jobs.py schema; absent when none)
    .murk/shards-<tag>.jsonl     append-only logs of finished shards (what makes resuming possible)

A sample is variant ``k`` of clean image ``stem``; its key is ``<stem>_v<k>`` (dots in the stem become ``_``:
WebDataset splits a member name at the first dot) and its members are ``<key>.degraded.png``, ``.clean.png``,
``.depth.png`` (uint16 millimetres), ``.snow_alpha.png`` (marine_snow stage), ``.basic.png`` and
``.transmission.png`` (``save_intermediate``), and ``.json`` (the manifest record: every parameter).

Determinism: the samples are all (stem, variant) pairs sorted by stem, then variant, cut into consecutive runs
of N; sample (stem, k) is drawn from ``derive_seed(seed, stem, k)``; tar members have fixed names, order,
mtime (0), mode, uid/gid (0) and user/group names, and PNGs are encoded with a fixed zlib level. The bytes of a
shard therefore depend neither on the number of workers, nor on which process (``--shard i/N``, a SLURM array
task, a Ray task) wrote it.

Resume works at shard granularity: a shard is written to a temporary name and renamed when complete; a shard
that is logged as finished with nothing failed, whose file exists with the logged size, is never rewritten; any
other shard (missing, not logged, or with failed samples) is built again. ``--shard i/N`` (or SLURM array
variables) selects the shards ``j`` with ``j % N == i``.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from murk._config import dump_yaml
from murk._version import __version__
from murk.io.atomic import atomic_path, make_output_folder, remove_stale_temporaries, write_text_atomic
from murk.io.images import encode_png, to_uint
from murk.io.jobs import ErrorRecord, JobSummary
from murk.io.jsonl import append_jsonl, read_jsonl
from murk.io.pairs import RGBDSource
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

Backend = Literal["local", "ray"]
SHARDS_DIR = "shards"
INDEX_NAME = "index.json"
TAR_MTIME = 0
"""Modification time of every tar member (fixed so that the bytes are reproducible)."""
MEMBERS = ("degraded", "clean", "depth", "snow_alpha", "basic", "transmission")


def shard_name(index: int) -> str:
    """File name of shard ``index`` inside ``shards/`` (``000000.tar``; a brace pattern covers them)."""
    return f"{index:06d}.tar"


def sample_key(stem: str, variant: int) -> str:
    """The WebDataset key of variant ``variant`` of ``stem`` (dots would end the key early: they become ``_``)."""
    return f"{stem.replace('.', '_')}_v{variant}"


_KEY_RE = re.compile(r"_v\d+$")


def stem_of_key(key: str) -> str:
    """The (key-safe) stem of a sample key: ``<stem>_v<k>`` -> ``<stem>``."""
    return _KEY_RE.sub("", key)


@dataclass(frozen=True)
class ShardPlan:
    """One shard: its index and its samples (source, variant), in tar order."""

    index: int
    samples: tuple[tuple[RGBDSource, int], ...]

    @property
    def name(self) -> str:
        return shard_name(self.index)

    @property
    def keys(self) -> list[str]:
        return [sample_key(s.stem, k) for s, k in self.samples]


@dataclass
class ShardResult:
    """What building one shard produced (one line of the progress log)."""

    name: str
    keys: list[str]
    bytes: int
    sha256: str
    failures: list[ErrorRecord] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {
            "shard": self.name,
            "count": len(self.keys),
            "keys": self.keys,
            "bytes": self.bytes,
            "sha256": self.sha256,
            "failed": len(self.failures),
            "notes": self.notes,
        }


def plan_shards(sources: Sequence[RGBDSource], variants: int, samples_per_shard: int) -> list[ShardPlan]:
    """All (stem, variant) pairs sorted by stem then variant, cut into shards of ``samples_per_shard``.

    Raises:
        ValueError: ``samples_per_shard`` < 1, or two inputs whose keys collide (stems differing only by '.'/'_').
    """
    if isinstance(samples_per_shard, bool) or not isinstance(samples_per_shard, int) or samples_per_shard < 1:
        raise ValueError(f"--samples-per-shard: expected an integer >= 1, got {samples_per_shard!r}")
    ordered = sorted(sources, key=lambda s: s.stem)
    seen: dict[str, RGBDSource] = {}
    for s in ordered:
        k = sample_key(s.stem, 0)
        if k in seen:
            raise ValueError(
                f"{s.rgb_path}: its stem {s.stem!r} gives the same shard key as {seen[k].rgb_path} "
                f"({seen[k].stem!r}; dots become '_' in keys); rename one of them"
            )
        seen[k] = s
    pairs = [(s, k) for s in ordered for k in range(variants)]
    return [
        ShardPlan(i // samples_per_shard, tuple(pairs[i : i + samples_per_shard]))
        for i in range(0, len(pairs), samples_per_shard)
    ]


# ------------------------------------------------------------------------------------------ building one shard


def _png(image: np.ndarray, level: int) -> bytes:
    """PNG bytes of a uint8/uint16 RGB (H, W, 3) or (H, W) array (fixed level: deterministic)."""
    return encode_png(image, level)


def _depth_png(depth_m: np.ndarray, valid: np.ndarray) -> bytes:
    d = np.where(valid, depth_m, 0.0).astype(np.float64) * DEPTH_SCALE_OUT
    return encode_png(np.clip(np.rint(d), 0, 65535).astype(np.uint16))


def render_source_samples(
    source: RGBDSource, variants: Sequence[int], config: SynthConfig, bank: Any = None
) -> tuple[list[dict[str, Any]], list[ErrorRecord], str | None]:
    """Load one RGB-D pair and render ``variants``: one WebDataset sample dict (``__key__`` + bytes) each.

    The same per-sample work as :func:`murk.synth.runner.process_source` (same seeds, same parameters, the pieces
    of :mod:`murk.synth.common`), but the images go into memory instead of files. Returns (samples, failures,
    depth-range note).
    """
    from murk.synth.params import sample_variant, snow_sampler_for
    from murk.synth.render import depth_range, render

    try:
        rgb, depth, valid = load_source(source, config)
    except (ValueError, OSError) as exc:
        return [], [ErrorRecord(source.rgb_path, "read", str(exc), variant=int(k)) for k in variants], None
    note = depth_range_note(source, depth[valid])
    level = config.output.png_compression
    clean_png = _png(to_uint(rgb, 8), level)
    depth_png = _depth_png(depth, valid)
    snow_sampler = snow_sampler_for(config, bank) if "marine_snow" in config.stages else None
    h, w = depth.shape
    valid_fraction = float(valid.mean())
    span = depth_range(depth)  # checked once for all variants
    samples = []
    for k in variants:
        key = sample_key(source.stem, k)
        seed = derive_seed(config.seed, source.stem, k)
        params = sample_variant(np.random.default_rng(seed), config, snow_sampler=snow_sampler)
        res = render(
            rgb, depth, params, bank=bank, keep_intermediate=config.output.save_intermediate, depth_range_m=span
        )
        sample: dict[str, Any] = {
            "__key__": key,
            "degraded.png": _png(to_uint(res.degraded, 8), level),
            "clean.png": clean_png,
            "depth.png": depth_png,
        }
        if res.snow_alpha is not None:
            sample["snow_alpha.png"] = _png(to_uint(res.snow_alpha[:, :, None], 8)[:, :, 0], level)
        if config.output.save_intermediate:
            sample["basic.png"] = _png(to_uint(res.basic, 8), level)  # type: ignore[arg-type]
            sample["transmission.png"] = _png(to_uint(res.transmission, 8), level)  # type: ignore[arg-type]
        files = {m: f"{key}.{m}.png" for m in MEMBERS if f"{m}.png" in sample}
        info = variant_info(res, w, h, valid_fraction, note)
        record = manifest_record(source, k, seed, params, info, files)
        sample["json"] = json.dumps(record, sort_keys=True, separators=(",", ":")).encode("utf-8")
        samples.append(sample)
    return samples, [], note


def _write_tar(path: Path, samples: Sequence[dict[str, Any]]) -> tuple[int, str]:
    """Write ``samples`` as one tar atomically (fixed member metadata); returns (bytes, sha256)."""
    import webdataset as wds

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            writer = wds.TarWriter(f, user="murk", group="murk", mode=0o444, encoder=False, mtime=TAR_MTIME)
            try:
                for sample in samples:
                    writer.write(sample)
            except BaseException:
                with contextlib.suppress(Exception):  # the temporary file is deleted; the first error is raised
                    writer.close()
                raise
            writer.close()
        data = tmp.read_bytes()
    return len(data), hashlib.sha256(data).hexdigest()


def build_shard(plan: ShardPlan, config: SynthConfig, out_dir: str | Path, bank: Any = None) -> ShardResult:
    """Render every sample of ``plan`` and write ``shards/<name>`` atomically (samples whose input fails are left
    out and reported in the result; such a shard is built again by the next run)."""
    from murk._workers import stop_if_orphaned

    out = Path(out_dir)
    samples: list[dict[str, Any]] = []
    failures: list[ErrorRecord] = []
    notes: list[str] = []
    i = 0
    while i < len(plan.samples):  # consecutive samples of one stem: load the pair once
        source = plan.samples[i][0]
        ks = []
        while i < len(plan.samples) and plan.samples[i][0] == source:
            ks.append(plan.samples[i][1])
            i += 1
        stop_if_orphaned()
        got, errs, note = render_source_samples(source, ks, config, bank)
        samples.extend(got)
        failures.extend(errs)
        if note and note not in notes:
            notes.append(note)
    size, digest = _write_tar(out / SHARDS_DIR / plan.name, samples)
    return ShardResult(plan.name, [s["__key__"] for s in samples], size, digest, failures, notes)


_WORKER_BANK: Any = None


def init_shard_worker(bank_path: str | None, die_with_parent: bool = True) -> None:
    """Per-process set-up of a shard worker: one OpenCV thread, the particle bank loaded once."""
    global _WORKER_BANK
    if die_with_parent:
        from murk._workers import die_with_parent as _die

        _die()
    _WORKER_BANK = setup_worker(bank_path)


def build_shard_in_worker(plan: ShardPlan, config: SynthConfig, out_dir: str) -> ShardResult:
    """:func:`build_shard` with the bank loaded by :func:`init_shard_worker`."""
    return build_shard(plan, config, out_dir, _WORKER_BANK)


_TASK_BANKS: dict[str, Any] = {}


def build_shard_task(plan: ShardPlan, config: SynthConfig, out_dir: str, bank_path: str | None) -> ShardResult:
    """The body of one Ray task (:mod:`murk.synth.ray_backend`): :func:`build_shard` with one OpenCV thread and the
    particle bank loaded once per Ray worker process."""
    cv2.setNumThreads(1)
    bank = None
    if bank_path:
        if bank_path not in _TASK_BANKS:
            from murk.snow.bank import load_bank

            _TASK_BANKS[bank_path] = load_bank(bank_path)
        bank = _TASK_BANKS[bank_path]
    return build_shard(plan, config, out_dir, bank)


# ------------------------------------------------------------------------------------------ the run


def _progress_dir(out: Path) -> Path:
    return out / ".murk"


def load_finished(out: Path) -> dict[str, dict[str, Any]]:
    """Finished shards by name: logged with nothing failed, and the file present with the logged size."""
    done: dict[str, dict[str, Any]] = {}
    for log in sorted(_progress_dir(out).glob("shards-*.jsonl")):
        for rec in read_jsonl(log):
            path = out / SHARDS_DIR / rec["shard"]
            if rec.get("failed", 0) == 0 and path.is_file() and path.stat().st_size == rec["bytes"]:
                done[rec["shard"]] = rec
            else:
                done.pop(rec["shard"], None)
    return done


def check_shard_folder(out: Path, config: SynthConfig, samples_per_shard: int) -> None:
    """Refuse a folder written with another configuration, format or shard size (they would not be one dataset)."""
    import yaml

    path = out / "config.yaml"
    if not path.exists():
        return
    old = yaml.safe_load(path.read_text(encoding="utf-8")) or {}
    if old.get("format") != "webdataset":
        raise ValueError(
            f"{out}: this folder holds a loose-file dataset ('murk synth' without --format webdataset); use a new "
            "output folder for shards"
        )
    if old.get("samples_per_shard") != samples_per_shard:
        raise ValueError(
            f"{out}: this folder was written with --samples-per-shard {old.get('samples_per_shard')}, "
            f"got {samples_per_shard}; use the same value to resume, or a new output folder"
        )
    check_config_compatible(out, config)


def write_index(out: Path, plans: Sequence[ShardPlan], samples_per_shard: int, config: SynthConfig) -> dict[str, Any]:
    """Rebuild ``index.json`` from the progress logs (atomically): every finished shard with its keys."""
    from murk._config import to_dict

    done = load_finished(out)
    shards = []
    for p in plans:
        rec = done.get(p.name)
        if rec is not None and rec["keys"] == p.keys:
            shards.append({k: rec[k] for k in ("count", "keys", "bytes", "sha256")} | {"url": f"{SHARDS_DIR}/{p.name}"})
    index = {
        "format": "webdataset",
        "murk_version": __version__,
        "samples_per_shard": samples_per_shard,
        "shards_planned": len(plans),
        "shards_finished": len(shards),
        "complete": len(shards) == len(plans),
        "samples": sum(s["count"] for s in shards),
        "members": ["degraded.png", "clean.png", "depth.png", "json"]
        + (["snow_alpha.png"] if "marine_snow" in config.stages else [])
        + (["basic.png", "transmission.png"] if config.output.save_intermediate else []),
        "depth_scale": DEPTH_SCALE_OUT,
        "pattern": f"{SHARDS_DIR}/{{{shard_name(0)[:-4]}..{shard_name(max(len(plans) - 1, 0))[:-4]}}}.tar",
        "shards": shards,
        "config": {k: v for k, v in to_dict(config).items() if k != "workers"},  # workers do not change bytes
    }
    write_text_atomic(out / INDEX_NAME, json.dumps(index, indent=1) + "\n")
    return index


def write_shards(
    sources: Sequence[RGBDSource],
    out_dir: str | Path,
    config: SynthConfig,
    *,
    samples_per_shard: int,
    shard: Shard | None = None,
    bank_path: str | None = None,
    problems: Sequence[ErrorRecord] = (),
    backend: Backend = "local",
    ray_address: str | None = None,
    on_progress: Callable[[int, int], None] | None = None,
) -> JobSummary:
    """Generate (or resume) a sharded synthetic dataset. See the module docstring for the layout.

    Args:
        sources: the clean RGB-D pairs (all of them; ``shard`` picks its part of the tar shards).
        out_dir: output folder (created).
        config: the run's configuration (``config.workers`` local worker processes).
        samples_per_shard: samples per tar shard.
        shard: which tar shards this process writes (``j % count == index``; default: all).
        bank_path: particle bank file, required with the marine_snow stage.
        problems: input problems found before the run (unpaired files); reported in errors.jsonl.
        backend: ``local`` (worker processes) or ``ray`` (Ray tasks; needs ``murk[ray]``).
        ray_address: the Ray cluster to join (``ray.init(address=...)``); None starts a local one.
        on_progress: called as ``on_progress(shards_done, shards_total)`` after each shard.

    Returns:
        A :class:`~murk.io.jobs.JobSummary`: ``processed``/``skipped`` count samples, ``failed`` the error records.

    Raises:
        ValueError: a bad option, a folder written with another configuration, or one overlapping the inputs.
        OutputError: no space left on the device (a rerun resumes).
    """
    from murk.io.paths import check_output_location

    try:
        import webdataset  # noqa: F401
    except ImportError:
        raise ValueError(
            "--format webdataset: the webdataset package is not installed; pip install 'murk[webdataset]'"
        ) from None
    summary = JobSummary("synth")
    shard = Shard() if shard is None else shard
    if backend not in ("local", "ray"):
        raise ValueError(f"--backend: expected 'local' or 'ray', got {backend!r}")
    out = Path(out_dir)
    summary.out = out
    check_output_location(
        out, input_locations(sources), option="OUT_DIR", writes=(SHARDS_DIR, ".murk"), why=OVERLAP_WHY
    )
    check_snow_bank(config, bank_path)
    plans = plan_shards(sources, config.variants, samples_per_shard)
    make_output_folder(out)
    check_shard_folder(out, config, samples_per_shard)
    remove_stale_temporaries(out)
    write_text_atomic(
        out / "config.yaml",
        dump_yaml(config, format="webdataset", samples_per_shard=samples_per_shard, murk_version=__version__),
    )
    mine = [p for p in plans if p.index % shard.count == shard.index]
    done = load_finished(out)
    todo = [p for p in mine if not (p.name in done and done[p.name]["keys"] == p.keys)]
    summary.skipped = sum(len(p.samples) for p in mine) - sum(len(p.samples) for p in todo)
    failures = list(problems)
    log = _progress_dir(out) / f"shards-{shard.tag}.jsonl"
    finished = len(mine) - len(todo)
    if on_progress:
        on_progress(finished, len(mine))

    def collect(result: ShardResult) -> None:
        nonlocal finished
        append_jsonl(log, [result.to_json()])
        summary.processed += len(result.keys)
        failures.extend(result.failures)
        for note in result.notes:
            summary.note(note)
        finished += 1
        if on_progress:
            on_progress(finished, len(mine))

    if backend == "ray":
        from murk.synth.ray_backend import run_ray_tasks

        calls = [(p, config, str(out), bank_path) for p in todo]
        run_ray_tasks(build_shard_task, calls, address=ray_address, on_result=collect)
    elif config.workers <= 1 or len(todo) <= 1:
        init_shard_worker(bank_path, die_with_parent=False)
        for p in todo:
            collect(build_shard_in_worker(p, config, str(out)))
    else:
        import multiprocessing as mp
        from concurrent.futures import as_completed

        from murk._workers import worker_pool

        ctx = mp.get_context("spawn")
        # On an error (Ctrl+C, a full disk) the queued shards are cancelled and the workers stopped at once.
        with worker_pool(config.workers, mp_context=ctx, initializer=init_shard_worker, initargs=(bank_path,)) as ex:
            futures = [ex.submit(build_shard_in_worker, p, config, str(out)) for p in todo]
            for fut in as_completed(futures):
                collect(fut.result())
    write_index(out, plans, samples_per_shard, config)
    summary.failures = failures  # printed by the CLI; written to errors.jsonl (removed when none)
    summary.write_errors(out)
    return summary.finish()
