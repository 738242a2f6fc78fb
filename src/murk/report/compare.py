"""``murk compare``: every method on every real image, scored with UIQM (Eq. 10, with its parts) and UCIQE,
and compared with its input by the restoration measures that noise cannot fool (:mod:`murk.metrics.fidelity`).

Writes into the report folder: ``metrics.csv`` and ``metrics.json`` (per image and method, plus the per-method
mean +- std: the paper's Fig. 8, and per-method flag counts), ``grids/<stem>.jpg`` (methods side by side with
zoomed boxes: Figs. 7 and 9), ``report.html`` (self-contained; flagged methods marked), optionally
``restored/<label>/<stem>.png``, and ``errors.jsonl`` when images failed.

Each row holds the input-vs-output measures (:data:`murk.metrics.MEASURE_KEYS`; input = the raw image read,
output = the method's result, so the ``raw`` method gets the identity values) and ``flags``, the names
:func:`murk.metrics.flags` raised, joined with ``"; "`` (empty when none).
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
from typing import Any

import cv2
import numpy as np

from murk._version import __version__
from murk.io.atomic import write_text_atomic
from murk.io.images import read_image, to_float, to_uint, write_rgb, write_uint
from murk.io.jobs import ErrorRecord, JobSummary
from murk.io.jsonl import json_safe
from murk.io.paths import output_names as unique_names
from murk.metrics import fidelity
from murk.metrics.fidelity import MEASURE_KEYS, count_flags, flags, join_flags, restoration_measures
from murk.metrics.stats import column_stats
from murk.report.figures import Box, auto_boxes, comparison_grid
from murk.report.html import SUMMARY_METRICS, render_report
from murk.report.methods import MethodSpec, build_restorer

SCORE_KEYS = ("uiqm", "uicm", "uism", "uiconm", "uciqe", "sigma_c", "con_l", "mu_s")
"""No-reference scores of the output alone (:func:`score`)."""
METRIC_KEYS = (*SCORE_KEYS, *MEASURE_KEYS)
"""Every numeric column of a row (besides ``ms``), summarised per method."""


@dataclass
class CompareResult(JobSummary):
    """The job summary (:class:`murk.io.jobs.JobSummary`; ``processed`` counts images scored), the rows (one
    per image and method) and the per-method summary."""

    command: str = "compare"
    rows: list[dict[str, Any]] = field(default_factory=list)
    summary: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)

    @property
    def out_dir(self) -> Path:
        return Path(self.out or ".")

    @property
    def errors(self) -> list[dict[str, Any]]:
        """The failures as ``errors.jsonl`` lines."""
        return [r.to_json() for r in self.failures]


def score(image: np.ndarray, *, uiqm_preset: str = "panetta2016", uciqe_preset: str = "uciqe_m") -> dict[str, float]:
    """UIQM and UCIQE with their parts for a float RGB image in [0, 1]."""
    from murk.metrics import uciqe, uiqm

    q = uiqm(image, data_range=1.0, preset=uiqm_preset)  # type: ignore[arg-type]
    c = uciqe(image, data_range=1.0, preset=uciqe_preset)  # type: ignore[arg-type]
    return {
        "uiqm": q.uiqm,
        "uicm": q.uicm,
        "uism": q.uism,
        "uiconm": q.uiconm,
        "uciqe": c.uciqe,
        "sigma_c": c.sigma_c,
        "con_l": c.con_l,
        "mu_s": c.mu_s,
    }


def summarise(rows: Sequence[dict[str, Any]], labels: Sequence[str]) -> dict[str, dict[str, dict[str, float]]]:
    """Per method and metric: mean and population std over images (finite values), and n; under ``"flags"``
    the flag counts of :func:`murk.metrics.count_flags` (rows flagged, rows, and rows per flag name)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for lab in labels:
        mine = [r for r in rows if r["method"] == lab]
        out[lab] = {}
        for k in (*METRIC_KEYS, "ms"):
            st = column_stats(r[k] for r in mine if isinstance(r.get(k), (int, float)))
            out[lab][k] = {"mean": st.mean, "std": st.std, "n": st.n_finite}
        out[lab]["flags"] = dict(count_flags(r["flags"] for r in mine if isinstance(r.get("flags"), str)))
    return out


def real_images(real_dir: Path, out: Path, *, recursive: bool = False) -> list[Path]:
    """The images to compare: ``real_dir`` itself when it is a file, else its images (``recursive``), leaving
    out any inside the report folder ``out``.

    Raises:
        ValueError: ``out`` is the input folder (or would mix with it); no image found.
    """
    from murk.io.images import list_images
    from murk.io.paths import check_output_location
    from murk.io.rosbag import is_bag

    if real_dir.is_file() or is_bag(real_dir):  # a bag's frames are read by run_compare (topic, every)
        return [real_dir]
    check_output_location(out, [real_dir], inside="allow")  # an --out inside REAL_DIR is left out below
    images = [p for p in list_images(real_dir, recursive=recursive) if out.resolve() not in p.resolve().parents]
    if not images:
        raise ValueError(f"{real_dir}: no images found")
    return images


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
) -> CompareResult:
    """Run, score and report every method on every image (see the module docstring for the outputs). A ROS bag
    among ``images`` contributes every ``every``-th frame of ``topic``; frames that fail to decode are
    recorded in ``errors.jsonl``."""
    from murk.io.rosbag import bag_frames_as_files

    with bag_frames_as_files(images, topic, every=every) as frames:
        from murk.io.images import list_images

        files = [f for p in frames.paths for f in (list_images(p) if p.is_dir() else [p])]
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
        )
    return result


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
) -> CompareResult:
    if not methods:
        raise ValueError("--method: give at least one method (e.g. --method raw --method post)")
    labels = [m.label for m in methods]
    if len(set(labels)) != len(labels):
        raise ValueError(f"--method: labels must be unique, got {labels}; name them with LABEL=METHOD")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
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
            img = to_float(raw)
        except (ValueError, OSError) as exc:  # unreadable, corrupt, a bomb: recorded, the others go on
            result.add_failure(ErrorRecord(str(path), "read", str(exc)))
            continue
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
                metrics.update(restoration_measures(resize_to(img, restored.shape[:2]), restored))
            row = {"image": path.name, "path": str(path), "method": spec.label, "spec": spec.text, "ms": ms, **metrics}
            row["flags"] = join_flags(flags(metrics))
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
    result.summary = summarise(result.rows, labels)
    from murk.enhance.restorer import weights_of

    weights = {m.label: weights_of(r) for m, r in zip(methods, restorers, strict=True)}
    _write_tables(out, result, methods, uiqm_preset, uciqe_preset, weights)
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
    notes += [f"Weights of {lab}: {w}" for lab, w in weights.items() if w]
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
    weights: dict[str, str | None],
) -> None:
    cols = ["image", "method", "spec", *METRIC_KEYS, "ms", "flags", "warnings"]
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
                "weights": weights.get(m.label),
            }
            for m in methods
        ],
        "summary": result.summary,
        "rows": result.rows,
        "errors": result.errors,
        "summary_columns": [k for k, _ in SUMMARY_METRICS],
    }
    write_text_atomic(out / "metrics.json", json.dumps(json_safe(doc), indent=2, allow_nan=False) + "\n")
