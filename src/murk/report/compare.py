"""``murk compare``: every method on every real image, scored with UIQM (Eq. 10, with its parts) and UCIQE,
and compared with its input by the restoration measures that noise cannot fool (:mod:`murk.metrics.fidelity`).

Writes into the report folder: ``metrics.csv`` and ``metrics.json`` (per image and method, plus the per-method
mean +- std: the paper's Fig. 8, and per-method flag counts), ``grids/<stem>.jpg`` (methods side by side with
zoomed boxes: Figs. 7 and 9), ``report.html`` (self-contained; flagged methods marked), optionally
``restored/<label>/<stem>.png``, and ``errors.jsonl`` when images failed.

Each row holds the input-vs-output measures (:data:`murk.metrics.MEASURE_KEYS`; input = the raw image read,
output = the method's result, so the ``raw`` method gets the identity values) and ``flags``, the names
:func:`murk.metrics.flags` raised, joined with ``"; "`` (empty when none).

The scores, their order, headings and directions are the default rows of the metric table
(:mod:`murk.metrics.table`), read when a comparison runs: a row registered there is scored here.
"""

from __future__ import annotations

import csv
import io
import json
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from murk._version import __version__
from murk.io.atomic import make_output_folder, write_text_atomic
from murk.io.images import read_image, to_float, to_uint, write_rgb, write_uint
from murk.io.jobs import ErrorRecord, FolderSummary
from murk.io.jsonl import json_safe
from murk.io.paths import output_names as unique_names
from murk.metrics import fidelity, table
from murk.metrics.fidelity import count_flags, flags, join_flags
from murk.metrics.stats import column_stats
from murk.report.figures import Box, auto_boxes, comparison_grid
from murk.report.html import SUMMARY_METRICS, html_heading, render_report
from murk.report.methods import MethodSpec, build_restorer, check_method

if TYPE_CHECKING:
    from murk.enhance.restorer import WeightsUsed

SNOW_HTML_ORDER = ("snow_residue", "snow_sites_left", "snow_colour_residue", "snow_free_gms")
"""The snow-pair columns of the report page, in its order."""
_MEASURES = "murk.metrics.fidelity:restoration_measures"


def metric_keys() -> tuple[str, ...]:
    """Every numeric column of a row (besides ``ms``) that is always scored, summarised per method: the no-reference
    scores of the output alone (:func:`score`) and the input-vs-output restoration measures."""
    return (*table.names("none", default=True), *table.names("input", default=True))


def ref_keys() -> tuple[str, ...]:
    """Full-reference scores of the output against the reference image (``--ref``)."""
    return table.names("reference", default=True)


def paired_keys() -> tuple[str, ...]:
    """Paired differences to the raw input on the same image (``d_psnr = psnr(output) - psnr(input)``; better is
    the metric's direction: for CIEDE2000 negative)."""
    return tuple(f"d_{k}" for k in ref_keys())


def snow_keys() -> tuple[str, ...]:
    """Marine-snow removal on a pair of the same scene without and with snow (``snow_clean``;
    :mod:`murk.metrics.snow_pairs`): contrast-normalised particle excess left, share of particle sites left,
    structure away from the sites, and the particles' RGB difference left (a recoloured particle counts as left)."""
    return table.names("snow_pair", default=True)


def ref_html_columns() -> tuple[tuple[str, str], ...]:
    """(key, HTML heading) of each full-reference score and its paired difference to the raw input."""
    return tuple(
        col
        for m in table.metrics("reference", default=True)
        for col in ((m.name, html_heading(m.heading)), (f"d_{m.name}", html_heading(f"Δ{m.label} vs raw")))
    )


def snow_html_columns() -> tuple[tuple[str, str], ...]:
    """(key, HTML heading) of the snow-pair scores, in the report's order."""
    return tuple((k, html_heading(table.get(k).heading)) for k in SNOW_HTML_ORDER)


@dataclass
class CompareResult(FolderSummary):
    """The job summary (:class:`murk.io.jobs.JobSummary`; ``processed`` counts images scored), the rows (one
    per image and method) and the per-method summary."""

    command: str = "compare"
    rows: list[dict[str, Any]] = field(default_factory=list)
    summary: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)

    @property
    def errors(self) -> list[dict[str, Any]]:
        """The failures as ``errors.jsonl`` lines."""
        return [r.to_json() for r in self.failures]


def score(image: np.ndarray, *, uiqm_preset: str = "panetta2016", uciqe_preset: str = "uciqe_m") -> dict[str, float]:
    """The no-reference scores (the metric table's default rows: UIQM and UCIQE with their parts) of a float RGB
    image in [0, 1]."""
    settings = {"uiqm": {"preset": uiqm_preset}, "uciqe": {"preset": uciqe_preset}}
    return table.compute(table.metrics("none", default=True), image, data_range=1.0, settings=settings)


def measures(input: np.ndarray, output: np.ndarray) -> tuple[dict[str, float], list[str]]:
    """The input-vs-output restoration measures (the metric table's default rows) and the flags they raise."""
    results: dict[str, Any] = {}
    values = table.compute(table.metrics("input", default=True), input, output, results=results)
    return values, flags(results[_MEASURES]) if _MEASURES in results else []


def summarise(
    rows: Sequence[dict[str, Any]], labels: Sequence[str], *, reference: bool = False
) -> dict[str, dict[str, dict[str, float]]]:
    """Per method and metric: mean and population std over images (finite values), and n; under ``"flags"``
    the flag counts of :func:`murk.metrics.count_flags` (rows flagged, rows, and rows per flag name).

    With ``reference``, also the full-reference scores (:func:`ref_keys`) and their paired differences to the raw
    input on the same images (:func:`paired_keys`), each with ``better``: on how many images the method beat
    the raw input (by the metric's direction: higher PSNR/SSIM, lower CIEDE2000)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    metric_cols, paired = metric_keys(), paired_keys()
    keys = (*metric_cols, *ref_keys(), *paired, "ms") if reference else (*metric_cols, "ms")
    snow = snow_keys()
    if any(k in r for r in rows for k in snow):
        keys = (*keys, *snow)
    for lab in labels:
        mine = [r for r in rows if r["method"] == lab]
        out[lab] = {}
        for k in keys:
            st = column_stats(r[k] for r in mine if isinstance(r.get(k), (int, float)))
            out[lab][k] = {"mean": st.mean, "std": st.std, "n": st.n_finite}
            if k in paired:
                sign = table.get(k[2:]).sign
                out[lab][k]["better"] = sum(1 for r in mine if isinstance(r.get(k), float) and sign * r[k] > 0)
        out[lab]["flags"] = dict(count_flags(r["flags"] for r in mine if isinstance(r.get("flags"), str)))
    return out


def real_images(real_dir: Path, out: Path, *, recursive: bool = False) -> list[Path]:
    """The images to compare: ``real_dir`` itself when it is a file, else its images (``recursive``), leaving
    out any inside the report folder ``out``.

    Raises:
        ValueError: ``out`` is the input folder (or would mix with it); no image found.
    """
    from murk.io.images import list_images
    from murk.io.listing import real_path
    from murk.io.paths import check_output_location
    from murk.io.rosbag import is_bag

    if real_dir.is_file() or is_bag(real_dir):  # a bag's frames are read by run_compare (topic, every)
        return [real_dir]
    check_output_location(out, [real_dir], inside="allow")  # an --out inside REAL_DIR is left out below
    listed = list_images(real_dir, recursive=recursive, unusable=True)
    out_real = real_path(out)
    images = [p for p in listed if out_real not in real_path(p).parents]
    if not images:
        raise ValueError(f"{real_dir}: no images found{'' if recursive else ' (use --recursive for subfolders)'}")
    return images


def _listable(path: Path) -> bool:
    """A folder whose images are listed (a folder that cannot be entered, or a link that loops back to its own
    folder, stays one input its reader refuses)."""
    from murk.io.listing import can_list, is_folder_loop

    return path.is_dir() and can_list(path) and not is_folder_loop(path)


def run_compare(
    images: Sequence[Path],
    methods: Sequence[MethodSpec],
    out_dir: str | Path,
    *,
    boxes: Sequence[Box] = (),
    uiqm_preset: str = "panetta2016",
    uciqe_preset: str = "uciqe_m",
    restorer_options: dict[str, Any] | None = None,
    save_outputs: bool = False,
    title: str = "murk compare",
    topic: str | None = None,
    every: int = 1,
    on_image: Callable[[int, int, str], None] | None = None,
    ref_dir: str | Path | None = None,
    max_side: int | None = None,
    snow_clean: str | Path | None = None,
) -> CompareResult:
    """Run, score and report every method on every image (see the module docstring for the outputs). A ROS bag
    among ``images`` contributes every ``every``-th frame of ``topic``; frames that fail to decode are
    recorded in ``errors.jsonl``.

    ``ref_dir``: a folder of reference images matched by file stem (the field's full-reference protocol on
    real paired photographs): every row gets PSNR, SSIM and CIEDE2000 against the reference and their paired
    differences to the raw input (:func:`ref_keys`, :func:`paired_keys`); an image without a reference of its
    size is one error record. ``max_side``: images (and references) whose long side exceeds it are first
    downscaled to it (area resampling), e.g. 256 as in the published real-pair tables.

    ``snow_clean``: a folder of snow-free images of the same scenes as ``images`` (matched by file stem): every
    method also restores the snow-free image, and each row gets the snow-pair measures of
    :mod:`murk.metrics.snow_pairs` (:func:`snow_keys`: particle residue on the known particle sites)."""
    from murk.io.rosbag import bag_frames_as_files
    from murk.metrics import UCIQE_PRESETS, UIQM_PRESETS

    presets = (("--uiqm-preset", uiqm_preset, UIQM_PRESETS), ("--uciqe-preset", uciqe_preset, UCIQE_PRESETS))
    for flag, preset, known in presets:
        if preset not in known:
            raise ValueError(f"{flag}: expected one of {', '.join(known)}, got {preset!r}")
    for m in methods:  # every method's names and options before any footage is read or network loaded
        check_method(m, **(restorer_options or {}))
    with bag_frames_as_files(images, topic, every=every) as frames:
        from murk.io.images import list_images

        files = [f for p in frames.paths for f in (list_images(p) if _listable(p) else [p])]
        result = _run_compare(
            files,
            methods,
            out_dir,
            boxes=boxes,
            uiqm_preset=uiqm_preset,
            uciqe_preset=uciqe_preset,
            restorer_options=restorer_options,
            save_outputs=save_outputs,
            title=title,
            on_image=on_image,
            failures=frames.errors,
            refs=_reference_index(Path(ref_dir)) if ref_dir is not None else None,
            max_side=max_side,
            snow=_reference_index(Path(snow_clean), "--snow-clean") if snow_clean is not None else None,
        )
    return result


def _reference_index(ref_dir: Path, flag: str = "--ref") -> dict[str, list[Path]]:
    from murk.io.images import list_images

    if not ref_dir.is_dir():
        raise ValueError(f"{flag} {ref_dir}: not a folder of images")
    index: dict[str, list[Path]] = {}
    for p in list_images(ref_dir):
        index.setdefault(p.stem, []).append(p)
    if not index:
        raise ValueError(f"{flag} {ref_dir}: no images found")
    return index


def _read_reference(
    path: Path, refs: dict[str, list[Path]], size_hw: tuple[int, ...], max_side: int | None, flag: str = "--ref"
) -> Any:
    """The reference of ``path`` (same stem), as float RGB at the input's size after ``max_side``."""
    found = refs.get(path.stem, [])
    if len(found) != 1:
        what = "no image" if not found else f"{len(found)} images ({', '.join(map(str, found))})"
        raise ValueError(f"{what} with stem {path.stem!r} in {flag}")
    raw, _ = read_image(found[0])
    ref = downscale_to(to_float(raw), max_side)
    if ref.shape[:2] != tuple(size_hw[:2]):
        raise ValueError(
            f"reference {found[0]} is {ref.shape[1]}x{ref.shape[0]}, the input {size_hw[1]}x{size_hw[0]} (after "
            "--max-side): a full-reference score needs the same size"
        )
    return ref


def _reference_scores(image: np.ndarray, ref: np.ndarray) -> dict[str, float]:
    """The full-reference scores (the metric table's default rows) of ``image`` against ``ref``."""
    ref = resize_to(ref, image.shape[:2])
    return table.compute(table.metrics("reference", default=True), image, ref, data_range=1.0)


def downscale_to(image: np.ndarray, max_side: int | None) -> np.ndarray:
    """``image`` shrunk (area resampling) so that its long side is at most ``max_side``; unchanged when it
    already fits or ``max_side`` is None."""
    h, w = image.shape[:2]
    if max_side is None or max(h, w) <= max_side:
        return image
    f = max_side / max(h, w)
    return resize_to(image, (max(1, round(h * f)), max(1, round(w * f))))


def _run_compare(
    images: Sequence[Path],
    methods: Sequence[MethodSpec],
    out_dir: str | Path,
    *,
    boxes: Sequence[Box],
    uiqm_preset: str,
    uciqe_preset: str,
    restorer_options: dict[str, Any] | None,
    save_outputs: bool,
    title: str,
    on_image: Callable[[int, int, str], None] | None,
    failures: Sequence[ErrorRecord],
    refs: dict[str, list[Path]] | None = None,
    max_side: int | None = None,
    snow: dict[str, list[Path]] | None = None,
) -> CompareResult:
    if not methods:
        raise ValueError("--method: give at least one method (e.g. --method raw --method post)")
    labels = [m.label for m in methods]
    if len(set(labels)) != len(labels):
        raise ValueError(f"--method: labels must be unique, got {labels}; name them with LABEL=METHOD")
    out = Path(out_dir)
    make_output_folder(out, "report folder")
    restorers = [build_restorer(m, **(restorer_options or {})) for m in methods]
    result = CompareResult(out=out)
    for failure in failures:
        result.add_failure(failure)
    out_names = output_names(images)
    sections = []
    resized: set[str] = set()
    for i, path in enumerate(images):
        if on_image:
            on_image(i, len(images), path.name)
        try:
            raw, info = read_image(path)
            img = downscale_to(to_float(raw), max_side)
            # the input as the outputs are scored (at its bit depth): what the restoration measures and the snow
            # sites compare with, so that `raw` (the identity) gets the identity values after a --max-side resize
            img_q = to_float(to_uint(img, info.bit_depth))
        except (ValueError, OSError) as exc:  # unreadable, corrupt, a bomb: recorded, the others go on
            result.add_failure(ErrorRecord(str(path), "read", str(exc)))
            continue
        ref = None
        if refs is not None:
            try:
                ref = _read_reference(path, refs, img.shape, max_side)
            except (ValueError, OSError) as exc:
                result.add_failure(ErrorRecord(str(path), "reference", str(exc)))
                continue
            input_scores = _reference_scores(img_q, ref)
        snow_free, sites = None, None
        if snow is not None:
            from murk.metrics.snow_pairs import snow_sites

            try:
                snow_free = _read_reference(path, snow, img.shape, max_side, "--snow-clean")
            except (ValueError, OSError) as exc:
                result.add_failure(ErrorRecord(str(path), "snow-clean", str(exc)))
                continue
            snow_free_q = to_float(to_uint(snow_free, info.bit_depth))
            sites = snow_sites(img_q, snow_free_q)
        outputs, rows = [], []
        for spec, rest in zip(methods, restorers, strict=True):
            t0 = time.perf_counter()
            try:
                restored = img if rest is None else rest.restore(img[None]).images[0]
            except (ValueError, RuntimeError) as exc:
                result.add_failure(ErrorRecord(str(path), "restore", f"method {spec.label}: {exc}"))
                restored = None
            ms = (time.perf_counter() - t0) * 1e3
            if restored is None:
                continue
            # Scored as delivered: at the input's bit depth, as `murk enhance` writes it and --save-outputs saves it
            # (scoring the unrounded float output gave UIQM 1-2 % off `murk eval` of the same written file).
            restored = to_float(to_uint(np.clip(restored, 0.0, 1.0), info.bit_depth))
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                metrics = score(restored, uiqm_preset=uiqm_preset, uciqe_preset=uciqe_preset)
                measured, raised = measures(resize_to(img_q, restored.shape[:2]), restored)
                metrics.update(measured)
                if snow_free is not None and sites is not None:
                    from murk.metrics.fidelity import structure_fidelity
                    from murk.metrics.snow_pairs import snow_free_mask, snow_residue

                    out_free = snow_free if rest is None else rest.restore(snow_free[None]).images[0]
                    out_free = to_float(to_uint(np.clip(out_free, 0.0, 1.0), info.bit_depth))
                    r = snow_residue(sites, snow_free_q, restored, out_free)
                    metrics.update(
                        {
                            "snow_residue": r.residue,
                            "snow_sites_left": r.sites_left,
                            "snow_colour_residue": r.colour_residue,
                        }
                    )
                    if restored.shape == img.shape:  # the structure away from the particles, "not blurred"
                        clear = structure_fidelity(img_q, restored, where=snow_free_mask(sites))
                        metrics["snow_free_gms"] = clear.gms_mean
                if ref is not None:
                    full = _reference_scores(restored, ref)
                    metrics.update(full)
                    metrics.update({f"d_{k}": v - input_scores[k] for k, v in full.items()})
            row = {"image": path.name, "path": str(path), "method": spec.label, "spec": spec.text, "ms": ms, **metrics}
            row["flags"] = join_flags(raised)
            if caught:
                row["warnings"] = "; ".join(sorted({str(w.message) for w in caught}))
            rows.append(row)
            outputs.append((spec.label, resize_to(restored, img.shape[:2])))
            if restored.shape != img.shape:
                resized.add(f"{spec.label} ({restored.shape[1]}x{restored.shape[0]})")
            if save_outputs:
                write_rgb(
                    out / "restored" / _safe(spec.label) / f"{out_names[path]}.png", restored, bits=info.bit_depth
                )
        if not outputs:
            continue
        result.rows.extend(rows)
        result.processed += 1
        chosen = list(boxes) if boxes else auto_boxes(img)
        panels = [("input", img)] if "raw" not in [m.method for m in methods] else []
        panels += [(lab, o) for lab, o in outputs]
        by_label = {r["method"]: r for r in rows}
        names = [lab if lab not in by_label else f"{lab}  UIQM {by_label[lab]['uiqm']:.2f}" for lab, _ in panels]
        grid = comparison_grid([p for _, p in panels], names, chosen)
        write_uint(out / "grids" / f"{out_names[path]}.jpg", grid, jpeg_quality=90)
        sections.append(
            {"name": path.name, "grid_u8": _shrink(grid), "rows": rows, "boxes": [b.__dict__ for b in chosen]}
        )
    result.summary = summarise(result.rows, labels, reference=refs is not None)
    from murk.enhance.restorer import weights_used

    used = {m.label: weights_used(r) for m, r in zip(methods, restorers, strict=True)}
    _write_tables(
        out,
        result,
        methods,
        uiqm_preset,
        uciqe_preset,
        used,
        reference=refs is not None,
        snow=snow is not None,
    )
    notes = [
        f"UIQM preset '{uiqm_preset}', UCIQE preset '{uciqe_preset}' (docs/metrics.md says which published code "
        "each preset reproduces); metrics are computed on the full-resolution outputs.",
        "Boxes: "
        + (
            "given with --box."
            if boxes
            else "chosen automatically: most structure (gradient energy), then most marine snow (top-hat response)."
        ),
        "Restoration measures compare each output with its input (docs/metrics.md): artefact ratios (periodic: "
        "checkerboard/tiling peaks; isolated: pixel noise), structure GMS (do the edges follow the input), "
        f"particle residue, colour cast, luminance and contrast. Flags: artefacts (a ratio > "
        f"{fidelity.ARTEFACT_RATIO_MAX:g}), structure loss (GMS < {fidelity.STRUCTURE_GMS_MIN:g}), grey collapse "
        f"(contrast ratio < {fidelity.CONTRAST_RATIO_MIN:g}), darkened (luminance ratio < "
        f"{fidelity.LUMINANCE_RATIO_MIN:g}), particles not removed (particle ratio > {fidelity.PARTICLE_RATIO_MAX:g})."
        " UIQM and UCIQE reward noise and artefacts: read them with the flags.",
    ]
    if snow is not None:
        notes.append(
            "Snow pairs (--snow-clean): each image has a snow-free image of the same scene; particle sites are the "
            "small blobs where the snowy image is brighter; snow residue = the particles' luma excess left in "
            "R(snowy) - R(clean), normalised by the method's contrast gain (1 = kept, 0 = removed); sites left = "
            "share of sites still at half their contrast or more (docs/metrics.md)."
        )
    if refs is not None:
        notes.append(
            "Full-reference scores against the --ref images matched by stem: PSNR (dB), SSIM (11x11 Gaussian window) "
            "and mean CIEDE2000 (scikit-image; lower is better); the Delta columns are paired differences to the raw "
            "input on the same image (mean +- std over images)."
            + (f" Images and references were downscaled to a long side of {max_side} px first." if max_side else "")
        )
    notes += [
        f"Weights of {lab}: {u.weights}"
        + (f" (built on: {u.base_weights})" if u.base_weights else "")
        + (f" (with lite's restoration blended in: {u.blended_weights})" if u.blended_weights else "")
        + (f" (then: {u.later_weights})" if u.later_weights else "")
        for lab, u in used.items()
        if u.weights
    ]
    if resized:
        notes.append(
            f"Outputs at another size than their input: {', '.join(sorted(resized))} (e.g. a baseline's official "
            "policy, 256x256 as its published test script). Their scores are computed at that size, their "
            "restoration measures against the input resized to it, and the grids show them resized to the input."
        )
    html_text = render_report(
        title=title,
        methods=[{"label": m.label, "spec": m.text} for m in methods],
        summary=result.summary,
        images=sections,
        notes=notes,
        columns=(
            *(ref_html_columns() if refs is not None else ()),
            *(snow_html_columns() if snow is not None else ()),
            *SUMMARY_METRICS,
        ),
        meta=f"murk {__version__} · {len(sections)} images · {time.strftime('%Y-%m-%d %H:%M')}",
    )
    write_text_atomic(out / "report.html", html_text)
    result.write_errors(out)
    return result.finish()


def resize_to(image: np.ndarray, size_hw: tuple[int, ...]) -> np.ndarray:
    """``image`` at (height, width) ``size_hw``: unchanged when it has that size, else area-resampled when
    shrinking and bilinear when enlarging (float32, [0, 1] kept)."""
    h, w = int(size_hw[0]), int(size_hw[1])
    if image.shape[:2] == (h, w):
        return image
    shrink = h * w < image.shape[0] * image.shape[1]
    out = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def output_names(images: Sequence[Path]) -> dict[Path, str]:
    """A distinct output name per image: its stem, or where stems collide (``a/x.jpg``, ``b/x.png``) the parent
    folder and the stem (``a_x``, ``b_x``), then the suffix, then a counter: no grid overwrites another
    (:func:`murk.io.paths.output_names`, shared with the other commands)."""
    return unique_names(images, safe=_safe)


def _safe(label: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in label)


def _shrink(grid: np.ndarray, max_width: int = 1600) -> np.ndarray:
    if grid.shape[1] <= max_width:
        return grid
    f = max_width / grid.shape[1]
    return cv2.resize(grid, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)


def _write_tables(
    out: Path,
    result: CompareResult,
    methods: Sequence[MethodSpec],
    uiqm_preset: str,
    uciqe_preset: str,
    used: dict[str, WeightsUsed],
    *,
    reference: bool = False,
    snow: bool = False,
) -> None:
    ref_cols = [*ref_keys(), *paired_keys()] if reference else []
    ref_cols += list(snow_keys()) if snow else []
    cols = ["image", "method", "spec", *ref_cols, *metric_keys(), "ms", "flags", "warnings"]
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in result.rows:
        w.writerow({k: (f"{r[k]:.6f}" if isinstance(r.get(k), float) else r.get(k, "")) for k in cols})
    write_text_atomic(out / "metrics.csv", buf.getvalue())
    doc = {
        "murk_version": __version__,
        "presets": {"uiqm": uiqm_preset, "uciqe": uciqe_preset},
        "methods": [
            {
                "label": m.label,
                "spec": m.text,
                "method": m.method,
                "checkpoint": m.checkpoint,
                "weights": used[m.label].weights,
                "base_weights": used[m.label].base_weights,  # the network the first builds on (water's Joint-ID)
                "blended_weights": used[m.label].blended_weights,  # what a blend of the spec averages in
                "later_weights": used[m.label].later_weights,  # what a chain runs after the first (lite+detail)
            }
            for m in methods
        ],
        "summary": result.summary,
        "rows": result.rows,
        "errors": result.errors,
        "summary_columns": [k for k, _ in SUMMARY_METRICS],
    }
    write_text_atomic(out / "metrics.json", json.dumps(json_safe(doc), indent=2, allow_nan=False) + "\n")
