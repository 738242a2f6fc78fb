"""``murk eval`` as a library call: UIQM/UCIQE of images, PSNR/SSIM against references matched by stem,
input-vs-output restoration measures and flags (``inputs``), depth errors; the per-column statistics
(:func:`murk.metrics.stats.column_stats`, shared with ``murk compare``) and the JSON/CSV writers.

What is scored, in which column order, comes from the metric table (:mod:`murk.metrics.table`): its default rows
of each kind the inputs allow (no-reference always, full-reference with ``ref``, restoration measures with
``inputs``, depth errors with ``depth``), or the rows picked by :attr:`EvalOptions.metrics`.

Failures (an unreadable file, no matching reference, a size mismatch) are :class:`murk.io.jobs.ErrorRecord`
lines (stage ``score`` or ``depth``; the message without the path, which ``input`` holds); :func:`run_eval`
writes them to ``errors.jsonl`` beside the JSON/CSV output when one is given (rewritten by every run).
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from murk.io.jobs import ErrorRecord, JobSummary
from murk.metrics import table
from murk.metrics.table import Metric, Needs

NEEDED_BY: dict[Needs, str] = {
    "reference": "--ref (reference images)",
    "input": "--input (the raw inputs)",
    "depth": "--depth and --depth-ref",
    "snow_pair": "murk compare --snow-clean (pairs of the same scene without and with snow)",
}
"""What each kind of metric needs besides IMAGES, as the usage error says it."""


@dataclass(frozen=True)
class EvalOptions:
    """How images and depth are scored.

    Attributes:
        uiqm_preset, uciqe_preset: metric presets (``docs/metrics.md``).
        resize: (width, height) to resize to with Pillow bicubic before UIQM/UCIQE, or None.
        ssim_window: ``gaussian`` (11x11, sigma 1.5) or ``uniform`` (7x7).
        depth_scale: raw units per metre of integer depth images.
        recursive: search folders recursively.
        metrics: the metric names to score (:mod:`murk.metrics.table`), or None: the default rows.
    """

    uiqm_preset: str = "panetta2016"
    uciqe_preset: str = "uciqe_m"
    resize: tuple[int, int] | None = None
    ssim_window: str = "gaussian"
    depth_scale: float = 1000.0
    recursive: bool = False
    metrics: tuple[str, ...] | None = None

    def __post_init__(self) -> None:
        from murk.metrics.reference import SSIM_WINDOWS

        if self.metrics is not None:
            table.pick(self.metrics)  # unknown names: ValueError naming the nearest
        if self.ssim_window not in SSIM_WINDOWS:
            raise ValueError(f"--ssim-window: expected one of {', '.join(SSIM_WINDOWS)}, got {self.ssim_window!r}")
        if not (math.isfinite(self.depth_scale) and self.depth_scale > 0):
            raise ValueError(f"--depth-scale: expected a finite number > 0, got {self.depth_scale}")

    def meta(self) -> dict[str, Any]:
        """The settings recorded in the JSON output."""
        return {
            "uiqm_preset": self.uiqm_preset,
            "uciqe_preset": self.uciqe_preset,
            "resize": list(self.resize) if self.resize else None,
            "ssim_window": self.ssim_window,
            "depth_scale": self.depth_scale,
            **({"metrics": list(self.metrics)} if self.metrics is not None else {}),
        }

    def chosen(self, needs: Needs) -> list[Metric]:
        """The rows of kind ``needs`` to score: the picked ones, or the default ones."""
        picked = table.pick(self.metrics)
        return table.metrics(needs, default=True) if picked is None else [m for m in picked if m.needs == needs]


@dataclass
class EvalResult(JobSummary):
    """The job summary (``processed`` counts scored files) and the rows: one per image, one per depth map."""

    command: str = "eval"
    images: list[dict[str, Any]] = field(default_factory=list)
    depth: list[dict[str, Any]] = field(default_factory=list)
    options: EvalOptions = field(default_factory=EvalOptions)


def parse_presets(values: Sequence[str]) -> tuple[str, str]:
    """(UIQM preset, UCIQE preset) from names given in any order, at most one per metric."""
    from murk.metrics import UCIQE_PRESETS, UIQM_PRESETS

    uiqm_p, uciqe_p = "panetta2016", "uciqe_m"
    seen: set[str] = set()
    for v in values:
        name = v.strip()
        if name in UIQM_PRESETS:
            kind = "uiqm"
            uiqm_p = name
        elif name in UCIQE_PRESETS:
            kind = "uciqe"
            uciqe_p = name
        else:
            raise ValueError(
                f"--preset: expected a UIQM preset ({', '.join(UIQM_PRESETS)}) or a UCIQE preset "
                f"({', '.join(UCIQE_PRESETS)}), got {v!r}"
            )
        if kind in seen:
            raise ValueError(f"--preset: two {kind.upper()} presets given; give at most one per metric")
        seen.add(kind)
    return uiqm_p, uciqe_p


def evaluate(
    images: Sequence[Path] = (),
    *,
    ref: Path | None = None,
    inputs: Path | None = None,
    depth: Path | None = None,
    depth_ref: Path | None = None,
    options: EvalOptions | None = None,
    topic: str | None = None,
    every: int = 1,
    on_progress: Callable[[int, int], None] | None = None,
) -> EvalResult:
    """Score ``images`` (files and/or folders; ROS bags: every ``every``-th frame of ``topic``, decode failures
    recorded) and depth maps; see the module docstring.

    Raises:
        ValueError: a usage error (``--ref``/``--input`` without images, ``--depth`` without ``--depth-ref``,
            nothing to evaluate); InputFileError: a path or folder with nothing to score.
    """
    opts = options or EvalOptions()
    if (depth is None) != (depth_ref is None):
        raise ValueError("--depth and --depth-ref: give both (predicted and ground-truth depth) or neither")
    if ref is not None and not images:
        raise ValueError("--ref: needs IMAGES (the predictions to compare with the references)")
    if inputs is not None and not images:
        raise ValueError("--input: needs IMAGES (the restored images to compare with their raw inputs)")
    if not images and depth is None:
        raise ValueError("nothing to evaluate: give IMAGES (files or folders) and/or --depth PRED --depth-ref GT")
    given: dict[Needs, bool] = {"reference": ref is not None, "input": inputs is not None, "depth": depth is not None}
    for needs, flag in NEEDED_BY.items():
        missing = [m.name for m in opts.chosen(needs)] if opts.metrics is not None and not given.get(needs) else []
        if missing:
            raise ValueError(f"--metrics {','.join(missing)}: needs {flag}")
    result = EvalResult(options=opts)
    if images:
        from murk.io.rosbag import bag_frames_as_files

        with bag_frames_as_files(images, topic, every=every) as frames:
            for failure in frames.errors:
                result.add_failure(failure)
            files = _collect_images(frames.paths, opts.recursive)
            refs = _index_folder(ref, opts.recursive, "--ref", "reference") if ref is not None else None
            raws = _index_folder(inputs, opts.recursive, "--input", "raw input") if inputs is not None else None
            _score_images(files, refs, raws, opts, result, on_progress)
    if depth is not None and depth_ref is not None:
        _score_depth(depth, depth_ref, opts, result)
    result.processed = len(result.images) + len(result.depth)
    return result.finish()


def run_eval(
    images: Sequence[Path] = (),
    *,
    json_out: Path | None = None,
    csv_out: Path | None = None,
    **kwargs: Any,
) -> EvalResult:
    """:func:`evaluate`, then the JSON/CSV outputs and, beside them, ``errors.jsonl`` (removed when nothing
    failed; without an output file the failures are only returned).

    Raises:
        ValueError: what :func:`evaluate` raises; before any work, a ``json_out`` or ``csv_out`` that is an input
            file (named, or an existing image or depth file inside an input folder)."""
    from murk.io.images import IMAGE_SUFFIXES
    from murk.io.paths import check_output_file

    read = [*images, *(kwargs.get(k) for k in ("ref", "inputs", "depth", "depth_ref"))]  # every path evaluate reads
    for option, out in (("--json", json_out), ("--csv", csv_out)):
        if out is not None:
            check_output_file(out, read, option=option, suffixes=(*IMAGE_SUFFIXES, ".npy", ".exr"))
    result = evaluate(images, **kwargs)
    if json_out is not None:
        write_eval_json(json_out, result)
    if csv_out is not None:
        write_eval_csv(csv_out, result)
    target = json_out or csv_out
    if target is not None:
        result.write_errors(target.parent)
    return result


# ----------------------------------------------------------------------------------------------------------
# file discovery


def _collect_images(paths: Sequence[Path], recursive: bool) -> list[tuple[str, Path]]:
    """(display name, path) of every image named or found in the given folders; usage error if none."""
    from murk.errors import InputFileError
    from murk.io import list_images

    found: list[tuple[str, Path]] = []
    for p in paths:
        if p.is_dir():
            inside = list_images(p, recursive=recursive, unusable=True)
            if not inside:
                hint = "" if recursive else " (use --recursive for subfolders)"
                raise InputFileError(p, f"no image files in this folder{hint}")
            found.extend((str(f.relative_to(p)), f) for f in inside)
        elif p.is_file() or os.path.lexists(p):  # a FIFO, device or broken link: its reader records why
            found.append((str(p), p))
        else:
            raise InputFileError(p, "no such file or folder")
    return found


def _index_folder(folder: Path, recursive: bool, option: str, what: str) -> dict[str, list[Path]]:
    """Images of ``folder`` by file stem (for --ref and --input)."""
    from murk.errors import InputFileError
    from murk.io import list_images

    if not folder.is_dir():
        raise InputFileError(folder, f"{option}: expected a folder of {what} images")
    index: dict[str, list[Path]] = {}
    for f in list_images(folder, recursive=recursive):
        index.setdefault(f.stem, []).append(f)
    return index


def _match(path: Path, index: dict[str, list[Path]], option: str, what: str) -> Path:
    """The one image of ``index`` with the stem of ``path``; a file failure when there is none or several."""
    from murk.errors import InputFileError

    matches = index.get(path.stem, [])
    if not matches:
        raise InputFileError(path, f"no {what} image with stem {path.stem!r} in {option}")
    if len(matches) > 1:
        shown = ", ".join(str(m) for m in matches)
        raise InputFileError(path, f"several {what} images with stem {path.stem!r} in {option}: {shown}")
    return matches[0]


def _read_same_size(path: Path, other: Path, shape: tuple[int, ...], what: str) -> Any:
    """Read ``other`` (decoded RGB); a file failure for ``path`` when its size differs from ``shape``."""
    from murk.errors import InputFileError
    from murk.io import read_image

    rgb, _ = read_image(other)
    if rgb.shape != shape:
        raise InputFileError(
            path,
            f"size {shape[1]}x{shape[0]} differs from the {what} {other} ({rgb.shape[1]}x{rgb.shape[0]})",
        )
    return rgb


def _depth_files(path: Path, recursive: bool) -> dict[str, list[Path]]:
    """Depth files by stem; a stem with several files (``x.npy`` and ``x.png``) keeps them all, so that the
    caller reports it as ambiguous instead of silently scoring one of them."""
    from murk.errors import InputFileError
    from murk.io.listing import walk_files
    from murk.io.pairs import DEPTH_SUFFIXES

    if path.is_file():
        return {path.stem: [path]}
    if not path.is_dir():
        raise InputFileError(path, "no such file or folder")
    out: dict[str, list[Path]] = {}
    for f in walk_files(path, recursive=recursive):
        if f.suffix.lower() in DEPTH_SUFFIXES and not f.name.startswith("."):
            out.setdefault(f.stem, []).append(f)
    if not out:
        raise InputFileError(path, "no depth files in this folder")
    return out


def _one(stem: str, files: list[Path]) -> Path:
    from murk.errors import InputFileError

    if len(files) > 1:
        names = ", ".join(str(f) for f in sorted(files))
        raise InputFileError(files[0], f"ambiguous stem {stem!r}: {names} share it; rename or remove all but one")
    return files[0]


# ----------------------------------------------------------------------------------------------------------
# scoring


def _score_images(
    files: list[tuple[str, Path]],
    refs: dict[str, list[Path]] | None,
    inputs: dict[str, list[Path]] | None,
    opts: EvalOptions,
    out: EvalResult,
    on_progress: Callable[[int, int], None] | None,
) -> None:
    import numpy as np

    from murk.io import read_image, to_float, to_uint
    from murk.metrics import flags, join_flags, pil_bicubic_resize

    noref, ref_rows, input_rows = opts.chosen("none"), opts.chosen("reference"), opts.chosen("input")
    settings = {
        "uiqm": {"preset": opts.uiqm_preset},
        "uciqe": {"preset": opts.uciqe_preset},
        "ssim": {"window": opts.ssim_window},
    }
    for done, (name, path) in enumerate(files, start=1):
        row: dict[str, Any] = {"file": name}
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                rgb, _ = read_image(path)
                peak = 255.0 if rgb.dtype == np.uint8 else 65535.0
                scored = rgb
                if opts.resize is not None:
                    u8 = rgb if rgb.dtype == np.uint8 else to_uint(to_float(rgb), 8)
                    scored, peak = pil_bicubic_resize(u8, opts.resize), 255.0
                native = [m for m in noref if m.data_range == "native"]
                values = table.compute(native, scored, data_range=peak, settings=settings)
                unit = [m for m in noref if m.data_range != "native"]
                values.update(table.compute(unit, to_float(scored), data_range=1.0, settings=settings) if unit else {})
                row.update({m.name: values[m.name] for m in noref})
                if refs is not None:
                    ref_path = _match(path, refs, "--ref", "reference")
                    ref_rgb = _read_same_size(path, ref_path, rgb.shape, "reference")
                    pred01, ref01 = to_float(rgb), to_float(ref_rgb)
                    row["ref"] = str(ref_path)
                    row.update(table.compute(ref_rows, pred01, ref01, data_range=1.0, settings=settings))
                if inputs is not None:
                    input_path = _match(path, inputs, "--input", "raw input")
                    raw_rgb = _read_same_size(path, input_path, rgb.shape, "raw input")
                    results: dict[str, Any] = {}
                    row["input"] = str(input_path)
                    row.update(table.compute(input_rows, to_float(raw_rgb), to_float(rgb), results=results))
                    if _MEASURES in results:  # the flags read every restoration measure
                        row["flags"] = join_flags(flags(results[_MEASURES]))
            row["warnings"] = sorted({str(w.message) for w in caught})
            for msg in row["warnings"]:
                out.note(f"{name}: {msg}")
            out.images.append(row)
        except (ValueError, OSError) as exc:
            out.add_failure(ErrorRecord(str(path), "score", _problem(exc)))
        if on_progress:
            on_progress(done, len(files))


_MEASURES = "murk.metrics.fidelity:restoration_measures"


def _score_depth(pred: Path, gt: Path, opts: EvalOptions, out: EvalResult) -> None:
    from murk.errors import InputFileError
    from murk.io import read_depth

    if pred.is_file() != gt.is_file():
        raise ValueError("--depth and --depth-ref: give two files or two folders")
    preds = _depth_files(pred, opts.recursive)
    gts = _depth_files(gt, opts.recursive)
    pairs = [(stem, ps) for stem, ps in preds.items()] if pred.is_dir() else [(next(iter(gts)), [pred])]
    scale = opts.depth_scale
    for stem, ps in pairs:
        p = ps[0]
        try:
            p = _one(stem, ps)
            if stem not in gts:
                raise InputFileError(p, f"no ground-truth depth with stem {stem!r} in --depth-ref")
            g = _one(stem, gts[stem])
            d_pred, d_ref = read_depth(p, depth_scale=scale), read_depth(g, depth_scale=scale)
            if d_pred.shape != d_ref.shape:
                raise InputFileError(
                    p,
                    f"size {d_pred.shape[1]}x{d_pred.shape[0]} differs from the reference depth {g} "
                    f"({d_ref.shape[1]}x{d_ref.shape[0]})",
                )
            errs = table.compute(opts.chosen("depth"), d_pred, d_ref)
            out.depth.append({"file": str(p), "ref": str(g), **errs})
        except (ValueError, OSError) as exc:
            out.add_failure(ErrorRecord(str(p), "depth", _problem(exc)))


def _problem(exc: Exception) -> str:
    """The error message without the file path (which the error record holds separately)."""
    from murk.errors import InputFileError

    return exc.problem if isinstance(exc, InputFileError) else str(exc)


# ----------------------------------------------------------------------------------------------------------
# statistics and writers


def columns(rows: list[dict[str, Any]]) -> list[str]:
    """The metric columns present in ``rows``, in the order of the metric table."""
    present = {k for r in rows for k in r}
    return [c for c in table.names() if c in present]


def summarize(rows: list[dict[str, Any]]) -> dict[str, dict[str, float | int]]:
    """Mean, population std and count of each metric column over ``rows`` (:func:`murk.metrics.stats.column_stats`).

    Infinite values (PSNR of an exact copy) are left out of mean/std and counted in ``n_inf``. With --input,
    ``flags`` holds the flag counts of :func:`murk.metrics.count_flags`.
    """
    from murk.metrics import count_flags
    from murk.metrics.stats import column_stats

    summary: dict[str, dict[str, float | int]] = {}
    for col in columns(rows):
        st = column_stats(r[col] for r in rows if col in r)
        entry: dict[str, float | int] = {"n": st.n}
        if st.n_finite:
            entry["mean"] = st.mean
            entry["std"] = st.std
        if st.n_inf:
            entry["n_inf"] = st.n_inf
        summary[col] = entry
    if any("flags" in r for r in rows):
        summary["flags"] = dict(count_flags(r["flags"] for r in rows if "flags" in r))
    return summary


def _jsonable(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return "inf" if v > 0 else ("-inf" if v < 0 else "nan")
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_jsonable(x) for x in v]
    return v


def write_eval_json(path: Path, result: EvalResult) -> None:
    """Rows, summary, settings and failures (``errors.jsonl`` records) as one JSON file, atomically."""
    import json

    from murk import __version__
    from murk.io import write_text_atomic

    doc = {
        "murk_version": __version__,
        **result.options.meta(),
        "images": result.images,
        "depth": result.depth,
        "summary": {"images": summarize(result.images), "depth": summarize(result.depth)},
        "errors": [r.to_json() for r in result.failures],
    }
    write_text_atomic(path, json.dumps(_jsonable(doc), indent=1, allow_nan=False) + "\n")


def write_eval_csv(path: Path, result: EvalResult) -> None:
    """One row per scored file, atomically."""
    import csv
    import io

    from murk.io import write_text_atomic

    rows = result.images + result.depth
    paired = any("input" in r for r in rows)  # --input adds the raw input's path and the flags
    cols = ["file", "ref", *(["input"] if paired else []), *columns(rows), *(["flags"] if paired else []), "warnings"]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({**r, "warnings": "; ".join(r.get("warnings", []))})
    write_text_atomic(path, buf.getvalue())
