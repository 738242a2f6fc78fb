"""``murk eval``: UIQM/UCIQE of images, PSNR/SSIM against references, input-vs-output restoration measures
and flags (``--input``), depth errors; table, CSV and JSON.

Exit codes: 0 = every file was scored; 1 = some files failed (listed on stderr, and in ``errors.jsonl`` beside
the ``--json``/``--csv`` output when one is given; each run rewrites it, or removes it when nothing failed); 2 =
bad usage (unknown preset, missing path, nothing to evaluate).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import typer

from murk.cli._common import EXIT_OK, EXIT_PARTIAL, QuietOpt, make_console, parse_size, print_error

_NOREF_COLUMNS = ("uiqm", "uicm", "uism", "uiconm", "uciqe", "sigma_c", "con_l", "mu_s")
_REF_COLUMNS = ("psnr", "ssim")


@dataclass
class _Outcome:
    """Rows, errors and warnings gathered by one ``murk eval`` run."""

    images: list[dict[str, Any]] = field(default_factory=list)
    depth: list[dict[str, Any]] = field(default_factory=list)
    errors: list[dict[str, str]] = field(default_factory=list)


def evaluate(
    images: Annotated[
        list[Path] | None,
        typer.Argument(
            help="Image files and/or folders. Scored with UIQM (and its terms) and UCIQE; with --ref they are "
            "the predictions."
        ),
    ] = None,
    ref: Annotated[
        Path | None,
        typer.Option("--ref", help="Folder of reference images matched to IMAGES by file stem: adds PSNR and SSIM."),
    ] = None,
    input_dir: Annotated[
        Path | None,
        typer.Option(
            "--input",
            help="Folder of the raw input images matched to IMAGES (their restorations) by file stem: adds the "
            "restoration measures (artefact ratios, structure GMS, particles, cast, luminance, contrast; full "
            "resolution, not --resize) and their flags.",
        ),
    ] = None,
    depth: Annotated[
        Path | None,
        typer.Option("--depth", help="Predicted depth: a file or a folder (uint16 PNG in mm, or .npy in metres)."),
    ] = None,
    depth_ref: Annotated[
        Path | None,
        typer.Option("--depth-ref", help="Ground-truth depth: a file or a folder matched to --depth by stem."),
    ] = None,
    preset: Annotated[
        list[str] | None,
        typer.Option(
            "--preset",
            help="UIQM preset (panetta2016 = default, funie, jointid) and/or UCIQE preset (uciqe_m = default, "
            "cielab_raw); repeat to set both, e.g. --preset funie --preset cielab_raw.",
        ),
    ] = None,
    resize: Annotated[
        str | None,
        typer.Option(
            "--resize",
            help="WxH: resize with Pillow bicubic before UIQM/UCIQE (FUnIE-GAN's measure_uiqm.py uses 256x256).",
        ),
    ] = None,
    depth_scale: Annotated[
        float, typer.Option("--depth-scale", help="Raw units per metre of integer depth images (1000 = mm).")
    ] = 1000.0,
    recursive: Annotated[bool, typer.Option("--recursive", "-r", help="Search folders recursively.")] = False,
    ssim_window: Annotated[
        str, typer.Option("--ssim-window", help="gaussian (11x11, sigma 1.5; default) or uniform (7x7).")
    ] = "gaussian",
    csv_out: Annotated[Path | None, typer.Option("--csv", help="Write one row per file to this CSV file.")] = None,
    json_out: Annotated[
        Path | None, typer.Option("--json", help="Write rows, summary, presets and errors to this JSON file.")
    ] = None,
    topic: Annotated[
        str | None, typer.Option("--topic", help="ROS bags among IMAGES: the image topic (omit it to list them).")
    ] = None,
    every: Annotated[int, typer.Option("--every", min=1, help="ROS bags among IMAGES: every N-th frame.")] = 1,
    quiet: QuietOpt = False,
) -> None:
    """Score images: UIQM (Eq. 10, with UICM/UISM/UIConM) and UCIQE; PSNR/SSIM with --ref; restoration measures
    and flags against the raw inputs with --input; depth errors with --depth/--depth-ref. Prints a per-file
    table and mean +- std (population std over files)."""
    from murk.metrics import UCIQE_PRESETS, UIQM_PRESETS
    from murk.metrics.reference import SSIM_WINDOWS

    uiqm_preset, uciqe_preset = _parse_presets(preset or [], UIQM_PRESETS, UCIQE_PRESETS)
    size_wh = parse_size(resize, option="--resize") if resize is not None else None
    if ssim_window not in SSIM_WINDOWS:
        raise ValueError(f"--ssim-window: expected one of {', '.join(SSIM_WINDOWS)}, got {ssim_window!r}")
    if not (math.isfinite(depth_scale) and depth_scale > 0):
        raise ValueError(f"--depth-scale: expected a finite number > 0, got {depth_scale}")
    if (depth is None) != (depth_ref is None):
        raise ValueError("--depth and --depth-ref: give both (predicted and ground-truth depth) or neither")
    if ref is not None and not images:
        raise ValueError("--ref: needs IMAGES (the predictions to compare with the references)")
    if input_dir is not None and not images:
        raise ValueError("--input: needs IMAGES (the restored images to compare with their raw inputs)")
    if not images and depth is None:
        raise ValueError("nothing to evaluate: give IMAGES (files or folders) and/or --depth PRED --depth-ref GT")

    console = make_console(quiet)
    out = _Outcome()
    if images:
        images, _bags = _bag_frames(images, topic, every, out)  # (its temporary folders live until we return)
        files = _collect_images(images, recursive)
        refs = _index_folder(ref, recursive, "--ref", "reference") if ref is not None else None
        inputs = _index_folder(input_dir, recursive, "--input", "raw input") if input_dir is not None else None
        _score_images(files, refs, inputs, uiqm_preset, uciqe_preset, size_wh, ssim_window, out, console)
    if depth is not None and depth_ref is not None:
        _score_depth(depth, depth_ref, depth_scale, recursive, out, console)

    _print_tables(out, quiet)
    meta = {
        "uiqm_preset": uiqm_preset,
        "uciqe_preset": uciqe_preset,
        "resize": list(size_wh) if size_wh else None,
        "ssim_window": ssim_window,
        "depth_scale": depth_scale,
    }
    if json_out is not None:
        _write_json(json_out, out, meta)
    if csv_out is not None:
        _write_csv(csv_out, out)
    folder = (json_out or csv_out).parent if (json_out or csv_out) is not None else None
    if folder is not None and not out.errors:
        (folder / "errors.jsonl").unlink(missing_ok=True)  # the failures of an earlier run, not of this one
    if out.errors:
        for e in out.errors:
            print_error(f"{e['file']}: {e['error']}")
        if folder is not None:
            from murk.io import write_jsonl

            write_jsonl(folder / "errors.jsonl", out.errors)
            console.print(f"{len(out.errors)} file(s) failed; listed in {folder / 'errors.jsonl'}")
        raise typer.Exit(EXIT_PARTIAL)
    raise typer.Exit(EXIT_OK)


# ----------------------------------------------------------------------------------------------------------
# argument parsing


def _parse_presets(values: list[str], uiqm_presets: tuple[str, ...], uciqe_presets: tuple[str, ...]) -> tuple[str, str]:
    uiqm_p, uciqe_p = "panetta2016", "uciqe_m"
    seen: set[str] = set()
    for v in values:
        name = v.strip()
        if name in uiqm_presets:
            kind = "uiqm"
            uiqm_p = name
        elif name in uciqe_presets:
            kind = "uciqe"
            uciqe_p = name
        else:
            raise ValueError(
                f"--preset: expected a UIQM preset ({', '.join(uiqm_presets)}) or a UCIQE preset "
                f"({', '.join(uciqe_presets)}), got {v!r}"
            )
        if kind in seen:
            raise ValueError(f"--preset: two {kind.upper()} presets given; give at most one per metric")
        seen.add(kind)
    return uiqm_p, uciqe_p


# ----------------------------------------------------------------------------------------------------------
# file discovery


def _bag_frames(images: list[Path], topic: str | None, every: int, out: _Outcome) -> tuple[list[Path], Any]:
    """ROS bags among IMAGES become temporary folders of their frames (issue 17; deleted with the returned
    object); frames that fail to decode are recorded as errors."""
    from murk.io.rosbag import export_bag_frames, is_bag

    if not any(is_bag(p) for p in images):
        return images, None
    bags = export_bag_frames(images, topic, every=every)
    out.errors += [{"file": e.input, "error": f"frame {e.frame}: {e.error}"} for e in bags.errors]
    return bags.paths, bags


def _collect_images(paths: list[Path], recursive: bool) -> list[tuple[str, Path]]:
    """(display name, path) of every image named or found in the given folders; usage error if none."""
    from murk.errors import InputFileError
    from murk.io import list_images

    found: list[tuple[str, Path]] = []
    for p in paths:
        if p.is_dir():
            inside = list_images(p, recursive=recursive)
            if not inside:
                hint = "" if recursive else " (use --recursive for subfolders)"
                raise InputFileError(p, f"no image files in this folder{hint}")
            found.extend((str(f.relative_to(p)), f) for f in inside)
        elif p.is_file():
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
        raise InputFileError(path, f"several {what} images with stem {path.stem!r}: {matches}")
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
    uiqm_preset: str,
    uciqe_preset: str,
    size_wh: tuple[int, int] | None,
    ssim_window: str,
    out: _Outcome,
    console: Any,
) -> None:
    import numpy as np
    from rich.progress import Progress

    from murk.io import read_image, to_float, to_uint
    from murk.metrics import flags, join_flags, pil_bicubic_resize, psnr, restoration_measures, ssim, uciqe, uiqm

    with Progress(console=console, transient=True) as progress:
        task = progress.add_task("scoring images", total=len(files))
        for name, path in files:
            row: dict[str, Any] = {"file": name}
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    rgb, _ = read_image(path)
                    peak = 255.0 if rgb.dtype == np.uint8 else 65535.0
                    scored = rgb
                    if size_wh is not None:
                        u8 = rgb if rgb.dtype == np.uint8 else to_uint(to_float(rgb), 8)
                        scored, peak = pil_bicubic_resize(u8, size_wh), 255.0
                    q = uiqm(scored, data_range=peak, preset=uiqm_preset)  # type: ignore[arg-type]
                    c = uciqe(scored, data_range=peak, preset=uciqe_preset)  # type: ignore[arg-type]
                    row.update({k: getattr(q, k) for k in _NOREF_COLUMNS[:4]})
                    row.update({k: getattr(c, k) for k in _NOREF_COLUMNS[4:]})
                    if refs is not None:
                        ref_path = _match(path, refs, "--ref", "reference")
                        ref_rgb = _read_same_size(path, ref_path, rgb.shape, "reference")
                        pred01, ref01 = to_float(rgb), to_float(ref_rgb)
                        row["ref"] = str(ref_path)
                        row["psnr"] = psnr(pred01, ref01, data_range=1.0)
                        row["ssim"] = ssim(pred01, ref01, data_range=1.0, window=ssim_window)  # type: ignore[arg-type]
                    if inputs is not None:
                        input_path = _match(path, inputs, "--input", "raw input")
                        raw_rgb = _read_same_size(path, input_path, rgb.shape, "raw input")
                        measures = restoration_measures(to_float(raw_rgb), to_float(rgb))
                        row["input"] = str(input_path)
                        row.update(measures)
                        row["flags"] = join_flags(flags(measures))
                row["warnings"] = sorted({str(w.message) for w in caught})
                for msg in row["warnings"]:
                    console.print(f"[yellow]note:[/] {name}: {msg}")
                out.images.append(row)
            except (ValueError, OSError) as exc:
                out.errors.append({"file": str(path), "error": _problem(exc)})
            progress.advance(task)


def _score_depth(pred: Path, gt: Path, depth_scale: float, recursive: bool, out: _Outcome, console: Any) -> None:
    from murk.errors import InputFileError
    from murk.io import read_depth
    from murk.metrics import depth_errors

    if pred.is_file() != gt.is_file():
        raise ValueError("--depth and --depth-ref: give two files or two folders")
    preds = _depth_files(pred, recursive)
    gts = _depth_files(gt, recursive)
    pairs = [(stem, ps) for stem, ps in preds.items()] if pred.is_dir() else [(next(iter(gts)), [pred])]
    for stem, ps in pairs:
        p = ps[0]
        try:
            p = _one(stem, ps)
            if stem not in gts:
                raise InputFileError(p, f"no ground-truth depth with stem {stem!r} in --depth-ref")
            g = _one(stem, gts[stem])
            errs = depth_errors(read_depth(p, depth_scale=depth_scale), read_depth(g, depth_scale=depth_scale))
            out.depth.append({"file": str(p), "ref": str(g), **errs.as_dict()})
        except (ValueError, OSError) as exc:
            out.errors.append({"file": str(p), "error": _problem(exc)})


def _problem(exc: Exception) -> str:
    """The error message without the file path (which the error record holds separately)."""
    from murk.errors import InputFileError

    return exc.problem if isinstance(exc, InputFileError) else str(exc)


# ----------------------------------------------------------------------------------------------------------
# output


def _columns(rows: list[dict[str, Any]]) -> list[str]:
    from murk.metrics import DEPTH_ERROR_NAMES, MEASURE_KEYS

    order = (*_NOREF_COLUMNS, *_REF_COLUMNS, *MEASURE_KEYS, *DEPTH_ERROR_NAMES)
    present = {k for r in rows for k in r}
    return [c for c in order if c in present]


def summarize(rows: list[dict[str, Any]]) -> dict[str, dict[str, float | int]]:
    """Mean, population std and count of each metric column over ``rows``.

    Infinite values (PSNR of an exact copy) are left out of mean/std and counted in ``n_inf``. With --input,
    ``flags`` holds the flag counts of :func:`murk.metrics.count_flags`.
    """
    import numpy as np

    from murk.metrics import count_flags

    summary: dict[str, dict[str, float | int]] = {}
    for col in _columns(rows):
        vals = np.array([r[col] for r in rows if col in r], dtype=np.float64)
        finite = vals[np.isfinite(vals)]
        entry: dict[str, float | int] = {"n": int(vals.size)}
        if finite.size:
            entry["mean"] = float(finite.mean())
            entry["std"] = float(finite.std())
        n_inf = int(vals.size - finite.size)
        if n_inf:
            entry["n_inf"] = n_inf
        summary[col] = entry
    if any("flags" in r for r in rows):
        summary["flags"] = dict(count_flags(r["flags"] for r in rows if "flags" in r))
    return summary


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return "inf" if math.isinf(v) else f"{v:.4f}"
    return str(v)


def _print_tables(out: _Outcome, quiet: bool) -> None:
    from rich.console import Console
    from rich.table import Table

    stdout = Console(highlight=False, soft_wrap=False, width=10_000)
    for title, rows in (("images", out.images), ("depth", out.depth)):
        if not rows:
            continue
        cols = _columns(rows)
        summary = summarize(rows)
        counts = summary.get("flags")  # only with --input
        table = Table(title=f"{title} ({len(rows)})", title_justify="left", box=None, pad_edge=False)
        table.add_column("file", overflow="fold")
        for c in cols:
            table.add_column(c, justify="right")
        if counts is not None:
            table.add_column("flags")
        if not quiet:
            for r in rows:
                flag_cell = [r.get("flags", "")] if counts is not None else []
                table.add_row(r["file"], *(_fmt(r[c]) if c in r else "" for c in cols), *flag_cell)
            table.add_section()
        flag_total = [f"{counts['flagged']}/{counts['n']} flagged"] if counts is not None else []
        table.add_row("mean", *(_fmt(summary[c].get("mean", math.nan)) for c in cols), *flag_total)
        table.add_row("std", *(_fmt(summary[c].get("std", math.nan)) for c in cols), *([""] * len(flag_total)))
        stdout.print(table)


def _jsonable(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return "inf" if v > 0 else ("-inf" if v < 0 else "nan")
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_jsonable(x) for x in v]
    return v


def _write_json(path: Path, out: _Outcome, meta: dict[str, Any]) -> None:
    import json

    from murk import __version__
    from murk.io import write_text_atomic

    doc = {
        "murk_version": __version__,
        **meta,
        "images": out.images,
        "depth": out.depth,
        "summary": {"images": summarize(out.images), "depth": summarize(out.depth)},
        "errors": out.errors,
    }
    write_text_atomic(path, json.dumps(_jsonable(doc), indent=1, allow_nan=False) + "\n")


def _write_csv(path: Path, out: _Outcome) -> None:
    import csv
    import io

    from murk.io import write_text_atomic

    rows = out.images + out.depth
    paired = any("input" in r for r in rows)  # --input adds the raw input's path and the flags
    cols = ["file", "ref", *(["input"] if paired else []), *_columns(rows), *(["flags"] if paired else []), "warnings"]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({**r, "warnings": "; ".join(r.get("warnings", []))})
    write_text_atomic(path, buf.getvalue())
