"""The image job of ``murk enhance``: restore planned image files (:func:`murk.enhance.inputs.plan_images`) in
batches of equal size, written with their size, format and bit depth (16-bit PNG/TIFF stays 16-bit unless
another format is asked for); depth maps and previews when the method returns depth.

What a method estimates on the way (``Restored.facts``: the ``water`` method's water, veil colour, attenuation and
visibility) is appended to ``estimates.jsonl``, one line per restored image (``image``, ``output`` and the facts);
an image restored again by a later run gets another line, the newest last.

Reliability: unreadable inputs are recorded in ``errors.jsonl`` (:mod:`murk.io.jobs`; rewritten by every run)
and skipped; rerunning skips images whose output exists (``overwrite=True`` redoes them; an existing output that
is empty or not an image is recorded as an error and left as it is); a full disk stops the
run with :class:`murk.errors.OutputError`, never a truncated file under a final name.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from murk.enhance.inputs import ImageJob
from murk.enhance.job_common import (
    ESTIMATES_NAME,
    INPUT_ERRORS,
    RESTORE_ERRORS,
    SIXTEEN_BIT_SUFFIXES,
    EnhanceReport,
    OutputOptions,
    ProgressFn,
    StopFn,
    restore_batch,
    without_path,
    write_depth_outputs,
)
from murk.enhance.preview import side_by_side
from murk.enhance.restorer import Restorer
from murk.errors import OutputError
from murk.io.atomic import make_output_folder, remove_stale_temporaries
from murk.io.images import BitDepth, not_an_image, read_image, to_float, to_uint, write_uint
from murk.io.jobs import ErrorLog, ErrorRecord
from murk.io.jsonl import append_jsonl, json_safe
from murk.io.listing import real_path


@dataclass
class _Loaded:
    job: ImageJob
    image: np.ndarray
    bits: BitDepth


def enhance_images(
    jobs: Sequence[ImageJob],
    restorer: Restorer,
    out_dir: Path,
    options: OutputOptions | None = None,
    *,
    batch: int = 1,
    on_progress: ProgressFn | None = None,
    should_stop: StopFn | None = None,
) -> EnhanceReport:
    """Restore image files (see :func:`plan_images`) in batches of equal-size images.

    Existing outputs are skipped unless ``options.overwrite``; failures are recorded in
    ``out_dir/errors.jsonl`` (rewritten by each run) and the run continues. ``should_stop`` is polled between
    images.

    Raises:
        OutputError: no space left on the device; the run stops (finished outputs are kept, none is partial).
    """
    options = options or OutputOptions()
    if batch < 1:
        raise ValueError(f"batch: expected >= 1, got {batch}")
    report = EnhanceReport(total=len(jobs), out=out_dir)
    errors = ErrorLog(out_dir, summary=report)
    make_output_folder(out_dir)
    remove_stale_temporaries(out_dir)
    errors.start()
    pending: list[_Loaded] = []
    claimed: dict[Path, Path] = {}
    converted: dict[str, int] = {}  # read_image's notes (grayscale -> RGB, alpha dropped): how many images each

    def flush() -> None:
        if pending:
            _restore_and_write_images(pending, restorer, out_dir, options, report, errors)
            pending.clear()
        report.tick()
        if on_progress:
            on_progress(report)

    for job in jobs:
        if should_stop and should_stop():
            report.stopped = True
            break
        key = real_path(job.dst)
        if key in claimed:
            errors.add(ErrorRecord(str(job.src), "plan", f"output {job.dst} is already written from {claimed[key]}"))
            continue
        claimed[key] = job.src
        if job.dst.exists() and not options.overwrite:
            problem = not_an_image(job.dst)
            if problem:  # murk writes atomically, so this is someone else's file: neither done nor to replace
                errors.add(
                    ErrorRecord(
                        str(job.src), "plan", f"output {job.dst} exists and {problem}; pass --overwrite to replace it"
                    )
                )
                continue
            report.skipped += 1
            if len(jobs) == 1:
                report.note(f"{job.dst} exists; skipped (use --overwrite to redo it)")
            continue
        t0 = time.perf_counter()
        try:
            raw, info = read_image(job.src)
            image = to_float(raw)
        except INPUT_ERRORS as exc:
            errors.add(ErrorRecord(str(job.src), "read", without_path(exc, job.src)))
            continue
        finally:
            report.read_s += time.perf_counter() - t0
        for note in info.notes:
            converted[note] = converted.get(note, 0) + 1
        bits: BitDepth = 16 if info.bit_depth == 16 and job.dst.suffix.lower() in SIXTEEN_BIT_SUFFIXES else 8
        if pending and pending[0].image.shape != image.shape:
            flush()
        pending.append(_Loaded(job, image, bits))
        if len(pending) >= batch:
            flush()
    flush()
    for note, count in sorted(converted.items()):  # the outputs are RGB: say so rather than change formats silently
        report.note(f"{count} input image(s): {note}; their outputs are 3-channel RGB")
    return report


def _restore_and_write_images(
    items: list[_Loaded],
    restorer: Restorer,
    out_dir: Path,
    options: OutputOptions,
    report: EnhanceReport,
    errors: ErrorLog,
) -> None:
    t0 = time.perf_counter()
    try:
        result = restore_batch(restorer, np.stack([it.image for it in items]))
    except RESTORE_ERRORS as exc:
        for it in items:
            errors.add(ErrorRecord(str(it.job.src), "restore", f"{type(exc).__name__}: {exc}"))
        return
    finally:
        report.restore_s += time.perf_counter() - t0
    t0 = time.perf_counter()
    for i, it in enumerate(items):
        try:
            if result.depth_m is not None and options.depth:
                write_depth_outputs(out_dir, it.job.stem, result.depth_m[i], options)
            image = result.images[i]
            if options.side_by_side:
                image = side_by_side(it.image, image)
            if result.facts is not None:  # before the image, which marks the image done
                facts = json_safe({"image": str(it.job.src), "output": str(it.job.dst), **result.facts[i]})
                append_jsonl(out_dir / ESTIMATES_NAME, [facts])
                report.note(f"what {restorer.name} estimated per image: {out_dir / ESTIMATES_NAME}")
            write_uint(it.job.dst, to_uint(image, it.bits), jpeg_quality=options.jpeg_quality)  # last: marks done
            report.processed += 1
        except OutputError:  # a full disk ends the run (every later write would fail too)
            raise
        except INPUT_ERRORS as exc:
            errors.add(ErrorRecord(str(it.job.src), "write", without_path(exc, it.job.dst)))
    report.write_s += time.perf_counter() - t0
