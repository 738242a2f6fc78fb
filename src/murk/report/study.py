"""``murk study``: train the arms (:mod:`murk.train.study`), then evaluate them and write the report.

Outputs in the study folder (besides ``models/`` and ``configs/``):

- ``real/``: ``murk compare`` on the real images with the methods ``raw``, ``post`` (Eq. 9 only), every arm,
  the last arm (the proposed data) + ``post``, and the ``eval.baselines`` specs (UDAformer, URSCT-SESR):
  ``metrics.csv``/``metrics.json`` (per image and method, UIQM/UCIQE and the restoration measures of
  :mod:`murk.metrics.fidelity`, with flags), ``grids/`` (Fig. 9: the methods side by side with zoomed boxes)
  and ``report.html``;
- ``heldout.json``: PSNR/SSIM and depth errors of every arm on held-out degraded procedural scenes;
- ``study.json`` (everything) and ``study.md`` (the Fig. 8 table as mean +- std per method over the real
  images, the held-out table, and the training record of every arm).

Evaluation is rerun on every invocation (it takes a minute or two); training is not.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from murk._config import merge
from murk._version import __version__
from murk.io.atomic import write_text_atomic
from murk.io.jobs import ErrorRecord, FolderSummary
from murk.io.jsonl import json_safe
from murk.metrics import table
from murk.train.config import TrainConfig
from murk.train.study import WALL_FILE, ArmRun, StudyConfig, arm_config, load_study, train_arms


@dataclass
class StudyResult(FolderSummary):
    """What a ``murk study`` invocation did: the job summary (:class:`murk.io.jobs.JobSummary`; ``processed``
    counts arms trained now, ``skipped`` arms already trained; failures are failed arms (stage ``train``) and
    real images that failed in the comparison (its stages), also in ``<study>/errors.jsonl``)."""

    command: str = "study"
    arms: list[ArmRun] = field(default_factory=list)
    report: dict[str, Any] = field(default_factory=dict)
    message: str = ""

    @property
    def ok(self) -> bool:
        return self.exit_code == 0


def run_study(
    config_file: str | Path,
    out_dir: str | Path,
    *,
    train_only: bool = False,
    on_event: Callable[[str], None] | None = None,
    real_pairs: str | Path | None = None,
    snow_pairs: str | Path | None = None,
) -> StudyResult:
    """Train every unfinished arm, then (unless ``train_only``) evaluate all arms and write the report.
    ``real_pairs`` and ``snow_pairs`` override the config's ``eval.real_pairs`` and ``eval.snow_pairs``."""
    study, base = load_study(config_file)
    if real_pairs is not None:
        study = merge(study, {"eval": {"real_pairs": str(real_pairs)}})
    if snow_pairs is not None:
        study = merge(study, {"eval": {"snow_pairs": str(snow_pairs)}})
    out = Path(out_dir)
    if not train_only:  # a typo in an evaluation folder is found now, not after hours of training
        check_eval_inputs(study)
    result = StudyResult(out=out)
    result.arms = train_arms(study, base, out, on_event=on_event)
    result.processed = sum(a.status == "trained" for a in result.arms)
    result.skipped = sum(a.status == "done" for a in result.arms)
    for i, arm in enumerate(result.arms):
        if arm.status == "failed":
            where = str(Path(arm_config(base, study.arms[i], out).out))
            result.add_failure(ErrorRecord(where, "train", f"arm {arm.name}: {arm.error}", index=i))
    failed = [a.name for a in result.arms if a.status == "failed"]
    if failed:
        result.write_errors(out)
        result.finish()
        result.message = f"study: arm(s) {', '.join(failed)} failed; rerun the same command to retry"
        return result
    if train_only:
        result.message = f"study: {len(result.arms)} arm(s) trained -> {out / 'models'}"
        result.write_errors(out)
        return result.finish()
    result.report = evaluate_study(study, base, out, on_event=on_event)
    for rec in result.report["real"]["errors"]:
        result.add_failure(ErrorRecord.from_json(rec))
    for rec in result.report.get("snow_pairs", {}).get("errors", []):
        result.add_failure(ErrorRecord.from_json(rec))
    for pair_set in result.report.get("real_pairs", {}).get("sets", {}).values():
        for rec in pair_set["errors"]:
            result.add_failure(ErrorRecord.from_json(rec))
    result.write_errors(out)
    result.message = f"study: report -> {out / 'study.md'} and {out / 'real' / 'report.html'}"
    return result.finish()


ARM_OPTIONS: dict[str, tuple[str, ...]] = {"jointid": ("refine=0", "lite_blend=0", "depth_area=0")}
"""Options every arm's restorer gets, per network kind. The arms are compared as trained: ``jointid``'s affine
transfer onto the input (``refine``, on by default in ``murk enhance``) would drop the deblurring that the
forward-scattering arm is about; nor is the shipped ``lite``'s restoration blended in (``lite_blend``), nor does
the depth come from a second pass at another size (``depth_area``)."""


def arm_spec(kind: str, body: str, *options: str) -> str:
    """The method spec of an arm: ``body`` (``[LABEL=]METHOD[:CHECKPOINT]``) with ``options`` and the arm options
    of the network ``kind`` (:data:`ARM_OPTIONS`)."""
    opts = ",".join([*options, *ARM_OPTIONS.get(kind, ())])
    return f"{body}?{opts}" if opts else body


def evaluate_study(
    study: StudyConfig, base: TrainConfig, out: Path, *, on_event: Callable[[str], None] | None = None
) -> dict[str, Any]:
    """Evaluate the trained arms (their final weights, ``latest.pt``) and write the study report."""
    from murk.data import resolve_builtin
    from murk.enhance.restorer import create
    from murk.io.images import list_images
    from murk.report.compare import run_compare
    from murk.report.heldout import make_heldout, score_heldout
    from murk.report.methods import parse_method

    say = on_event or (lambda _m: None)
    ev = study.eval
    method = base.model.kind  # the restorer of the arms' network kind: jointid or lite
    ckpts = {a.name: Path(arm_config(base, a, out).out) / "latest.pt" for a in study.arms}
    for name, path in ckpts.items():
        if not path.is_file():
            raise ValueError(f"study arm {name}: {path} not found (train the arms first)")
    report: dict[str, Any] = {"murk_version": __version__, "arms": _training_record(study, base, out)}
    arm_names = [a.name for a in study.arms]

    heldout: dict[str, Any] = {}
    if ev.synthetic_scenes > 0:
        say(f"held-out: rendering {ev.synthetic_scenes} scenes at {ev.synthetic_hw[1]}x{ev.synthetic_hw[0]}")
        synthesis = merge(base.data.synthesis, {"stages": ["basic", "forward_scatter", "marine_snow"]})
        data = make_heldout(
            ev.synthetic_scenes,
            seed=ev.synthetic_seed,
            size_hw=ev.synthetic_hw,
            synthesis=synthesis,
            balance_pct=ev.synthetic_balance_pct,
        )
        restorers = {name: create(arm_spec(method, method), checkpoint=str(p)) for name, p in ckpts.items()}
        if ev.synthetic_balance_pct is not None:  # photographic targets: the classical balance is the bar
            restorers = {"colorbalance": create("colorbalance"), **restorers}
        per_scene: dict[str, dict[str, list[float]]] = {}
        heldout = {
            "scenes": ev.synthetic_scenes,
            "seed": ev.synthetic_seed,
            "size_hw": list(ev.synthetic_hw),
            "balance_pct": ev.synthetic_balance_pct,
            "stages": list(synthesis.stages),
            "scores": score_heldout(
                data, restorers, on_method=lambda m: say(f"held-out: scoring {m}"), per_scene=per_scene
            ),
        }
        scene_rows = [
            {"set": "heldout", "image": i, "method": label, **{k: v[i] for k, v in values.items()}}
            for label, values in per_scene.items()
            for i in range(ev.synthetic_scenes)
        ]
        heldout["contrasts"] = paired_contrasts(scene_rows, arm_contrasts(arm_names), HELDOUT_CONTRAST_KEYS)
        write_text_atomic(out / "heldout.json", json.dumps(json_safe(heldout), indent=2) + "\n")
    report["heldout"] = heldout

    check_eval_inputs(study)
    real_dir = Path(resolve_builtin(ev.real))
    images = list_images(real_dir, recursive=True, unusable=True)
    last = study.arms[-1].name
    specs = ["raw", f"post=post?preset=paper,lam={ev.post_lambda}"]
    specs += [arm_spec(method, f"{name}={method}:{p}") for name, p in ckpts.items()]
    specs.append(arm_spec(method, f"{last}+post={method}+post:{ckpts[last]}", "preset=paper", f"lam={ev.post_lambda}"))
    specs += list(ev.baselines)  # e.g. udaformer:PATH, ursct:PATH (docs/baselines.md)
    methods = [parse_method(s) for s in specs]
    say(f"real: {len(images)} images x {len(methods)} methods")
    res = run_compare(images, methods, out / "real", title="murk study: the paper's ablation")
    report["real"] = {
        "folder": ev.real,
        "images": len(images),
        "methods": [m.label for m in methods],
        "summary": res.summary,
        "errors": res.errors,
    }
    if ev.real_pairs:
        pair_specs = [
            "raw",
            "greyworld+clahe",
            "colorbalance",
            "udcp",
            *specs[2:],
            arm_spec(method, f"{last}+post_murk={method}+post:{ckpts[last]}"),
        ]
        report["real_pairs"] = evaluate_real_pairs(
            Path(resolve_builtin(ev.real_pairs)),
            [parse_method(s) for s in pair_specs],
            out / "real_pairs",
            max_side=ev.real_pairs_max_side,
            contrasts=arm_contrasts([a.name for a in study.arms]),
            on_event=say,
        )
    if ev.snow_pairs:
        snow_dir = Path(resolve_builtin(ev.snow_pairs))
        snowy = list_images(snow_dir / "snowy")
        snow_specs = ["raw", *specs[1:]]
        say(f"snow pairs: {len(snowy)} images x {len(snow_specs)} methods")
        snow_res = run_compare(
            snowy,
            [parse_method(s) for s in snow_specs],
            out / "snow_pairs",
            snow_clean=snow_dir / "clean",
            title="murk study: marine snow on real pairs",
        )
        report["snow_pairs"] = {
            "folder": ev.snow_pairs,
            "images": len(snowy),
            "methods": [parse_method(s).label for s in snow_specs],
            "summary": snow_res.summary,
            "errors": snow_res.errors,
            "contrasts": paired_contrasts(
                [{**r, "set": "snow"} for r in snow_res.rows], arm_contrasts(arm_names), SNOW_CONTRAST_KEYS
            ),
        }
    write_text_atomic(out / "study.json", json.dumps(json_safe(report), indent=2) + "\n")
    write_text_atomic(out / "study.md", study_markdown(report))
    return report


def check_eval_inputs(study: StudyConfig) -> None:
    """The folders the evaluation reads (``eval.real``, ``eval.real_pairs``, ``eval.snow_pairs``), checked before
    any arm trains.

    Raises:
        ValueError: ``eval.real`` holds no images; ``eval.real_pairs`` holds no set (:func:`pair_sets`);
            ``eval.snow_pairs`` lacks ``snowy/`` or ``clean/``.
    """
    from murk.data import resolve_builtin
    from murk.io.images import list_images

    ev = study.eval
    real_dir = Path(resolve_builtin(ev.real))
    if not real_dir.is_dir() or not list_images(real_dir, recursive=True, unusable=True):
        raise ValueError(f"eval.real: {real_dir} holds no images")
    if ev.real_pairs:
        pair_sets(Path(resolve_builtin(ev.real_pairs)))
    if ev.snow_pairs:
        snow_dir = Path(resolve_builtin(ev.snow_pairs))
        if not (snow_dir / "snowy").is_dir() or not (snow_dir / "clean").is_dir():
            raise ValueError(f"eval.snow_pairs: {snow_dir} must hold snowy/ and clean/ folders (matched by file stem)")


def pair_sets(folder: Path) -> dict[str, Path]:
    """The real paired sets of ``folder``: itself when it holds ``input/`` and ``reference/``, else each
    subfolder that does (by name).

    Raises:
        ValueError: no set found.
    """

    def is_set(p: Path) -> bool:
        return (p / "input").is_dir() and (p / "reference").is_dir()

    if is_set(folder):
        return {folder.name: folder}
    sets = {p.name: p for p in sorted(folder.iterdir()) if p.is_dir() and is_set(p)} if folder.is_dir() else {}
    if not sets:
        raise ValueError(
            f"eval.real_pairs: {folder} holds neither input/ and reference/ folders nor subfolders that do"
        )
    return sets


CONTRAST_KEYS = ("psnr", "ciede2000")
"""The metrics the arms are contrasted by on real pairs, image by image (:func:`paired_contrasts`)."""

HELDOUT_CONTRAST_KEYS = ("affine_psnr", "psnr")
"""The metrics the arms are contrasted by on the held-out scenes, scene by scene (against the true clean scene)."""

SNOW_CONTRAST_KEYS = ("snow_residue", "snow_colour_residue")
"""The metrics the arms are contrasted by on the real snow pairs, image by image."""


def ci95_half_width(sd: float, n: int) -> float:
    """Half-width of the 95 % confidence interval of a mean of ``n`` paired differences with sample standard
    deviation ``sd``: Student's t quantile with ``n - 1`` degrees of freedom times ``sd / sqrt(n)`` (NaN under two
    values)."""
    if n < 2 or not math.isfinite(sd):
        return float("nan")
    from scipy.stats import t as student_t

    return float(student_t.ppf(0.975, n - 1)) * sd / math.sqrt(n)


def paired_contrasts(
    rows: list[dict[str, Any]], contrasts: list[tuple[str, str]], keys: tuple[str, ...] = CONTRAST_KEYS
) -> list[dict[str, Any]]:
    """Method ``a`` against method ``b`` for each ``(a, b)`` of ``contrasts``, paired over the images both scored:
    per key the mean and standard deviation of ``a - b`` over the images, how many images have ``a > b``, the
    paired t statistic (mean / (sd / sqrt(n)); NaN under two images or with no spread) and the half-width of the
    mean's 95 % confidence interval (:func:`ci95_half_width`). ``rows``: dicts with
    ``set``, ``image``, ``method`` and the keys (``murk compare`` rows, tagged with their set)."""
    table = {(r["set"], r["image"], r["method"]): r for r in rows}
    out = []
    for a, b in contrasts:
        images = sorted({(st, im) for st, im, m in table if m == a and (st, im, b) in table})
        entry: dict[str, Any] = {"a": a, "b": b, "n": len(images)}
        for k in keys:
            pairs = [(table[(st, im, a)].get(k), table[(st, im, b)].get(k)) for st, im in images]
            vals = [float(va) - float(vb) for va, vb in pairs if va is not None and vb is not None]
            d = [v for v in vals if math.isfinite(v)]  # an image a metric could not score is left out
            n = len(d)
            mean = sum(d) / n if n else float("nan")
            sd = math.sqrt(sum((v - mean) ** 2 for v in d) / (n - 1)) if n > 1 else float("nan")
            t = mean / (sd / math.sqrt(n)) if n > 1 and sd > 0 else float("nan")
            entry[k] = {
                "mean": mean,
                "std": sd,
                "n": n,
                "higher": sum(v > 0 for v in d),
                "t": t,
                "ci95": ci95_half_width(sd, n),
            }
        out.append(entry)
    return out


def evaluate_real_pairs(
    folder: Path,
    methods: list[Any],
    out: Path,
    *,
    max_side: int,
    contrasts: list[tuple[str, str]] | None = None,
    on_event: Callable[[str], None] | None = None,
) -> dict[str, Any]:
    """Score ``methods`` on every real paired set of ``folder`` (:func:`pair_sets`) with ``murk compare --ref``
    into ``out/<set>/``; the result holds each set's summary and, per method, the mean over sets of each set's
    mean PSNR / SSIM / CIEDE2000 and paired differences (each set counted once), and the ``contrasts`` between
    methods paired over all images of all sets (:func:`paired_contrasts`)."""
    from murk.io.images import list_images
    from murk.report.compare import paired_keys, ref_keys, run_compare

    say = on_event or (lambda _m: None)
    sets: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    for name, path in pair_sets(folder).items():
        images = list_images(path / "input", unusable=True)
        say(f"real pairs {name}: {len(images)} images x {len(methods)} methods")
        res = run_compare(
            images,
            methods,
            out / name,
            ref_dir=path / "reference",
            max_side=max_side,
            title=f"murk study: real pairs ({name})",
        )
        sets[name] = {"folder": str(path), "images": len(images), "summary": res.summary, "errors": res.errors}
        rows += [{**r, "set": name} for r in res.rows]
    labels = [m.label for m in methods]
    over_sets: dict[str, dict[str, float]] = {}
    for lab in labels:
        over_sets[lab] = {}
        for k in (*ref_keys(), *paired_keys()):
            means = [s["summary"][lab][k]["mean"] for s in sets.values() if s["summary"][lab][k]["n"]]
            over_sets[lab][k] = sum(means) / len(means) if means else float("nan")
    return {
        "folder": str(folder),
        "max_side": max_side,
        "methods": labels,
        "sets": sets,
        "mean_over_sets": over_sets,
        "contrasts": paired_contrasts(rows, contrasts or []),
    }


def arm_contrasts(arms: list[str]) -> list[tuple[str, str]]:
    """The arm comparisons a study reports: each arm against the one before (what its added stage does), and
    the last against the first when there are more than two arms."""
    pairs = [(arms[i], arms[i - 1]) for i in range(1, len(arms))]
    return [*pairs, (arms[-1], arms[0])] if len(arms) > 2 else pairs


def _training_record(study: StudyConfig, base: TrainConfig, out: Path) -> dict[str, Any]:
    record = {}
    for arm in study.arms:
        cfg = arm_config(base, arm, out)
        d = Path(cfg.out)
        summary = json.loads((d / "summary.json").read_text(encoding="utf-8")) if (d / "summary.json").is_file() else {}
        wall = json.loads((d / WALL_FILE).read_text(encoding="utf-8"))["wall_s"] if (d / WALL_FILE).is_file() else None
        record[arm.name] = {
            "stages": list(arm.stages),
            "steps": summary.get("steps_done"),
            "wall_s": wall,
            "last_eval": summary.get("last_eval", {}),
            "checkpoint": str(d / "latest.pt"),
        }
    return record


def summary_keys() -> list[tuple[str, str]]:
    """(key, heading) of the real-image table: the headline no-reference scores and restoration measures of the
    metric table."""
    kinds: tuple[table.Needs, ...] = ("none", "input")
    return [(m.name, m.heading) for kind in kinds for m in table.metrics(kind) if m.headline]


def real_pairs_markdown(pairs: dict[str, Any]) -> list[str]:
    """Markdown lines of the real-pair tables: per set mean +- std and the paired difference to raw, then the
    mean over sets."""

    def cell(v: dict[str, Any]) -> str:
        ok = v.get("n") and isinstance(v.get("mean"), (int, float)) and math.isfinite(v["mean"])
        return f"{v['mean']:.2f} +- {v['std']:.2f}" if ok else "-"

    from murk.report.compare import ref_keys

    refs = [table.get(k) for k in ref_keys()]
    first = refs[0].name  # its paired difference also counts the images where the method beat raw
    head = [col for m in refs for col in (m.heading, f"d {m.label}", *(["better than raw"] if m.name == first else []))]
    lines = [f"## Real paired photographs (long side <= {pairs['max_side']} px; {pairs['folder']})", ""]
    for name, s in pairs["sets"].items():
        lines += [
            f"### {name} ({s['images']} pairs): mean +- std over images; d = paired difference to raw",
            "",
            "| method | " + " | ".join(head) + " |",
            "|---|" + "---|" * len(head),
        ]
        for m in pairs["methods"]:
            r = s["summary"][m]
            better = f"{r[f'd_{first}'].get('better', 0)}/{r[f'd_{first}']['n']}"
            cells = [
                c
                for k in refs
                for c in (cell(r[k.name]), cell(r[f"d_{k.name}"]), *([better] if k.name == first else []))
            ]
            lines.append(f"| {m} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["### Mean over sets (each set's mean counted once)", ""]
    lines += ["| method | " + " | ".join(m.heading for m in refs) + " |", "|---|" + "---|" * len(refs)]
    for m in pairs["methods"]:
        o = pairs["mean_over_sets"][m]
        lines.append(f"| {m} | " + " | ".join(f"{o[k.name]:.{k.digits}f}" for k in refs) + " |")
    lines += contrasts_markdown(
        pairs.get("contrasts", []), CONTRAST_KEYS, "### Arms against each other: paired over all images of all sets"
    )
    return [*lines, ""]


def contrasts_markdown(contrasts: list[dict[str, Any]], keys: tuple[str, ...], title: str) -> list[str]:
    """Markdown lines of :func:`paired_contrasts`' result (none when no contrast has images)."""
    contrasts = [c for c in contrasts if c["n"]]
    if not contrasts:
        return []
    rows = [table.get(k) for k in keys]
    digits = max(2, *(r.digits for r in rows))
    directions = ", ".join(f"higher {k.label} is {'better' if k.better == 'higher' else 'worse'}" for k in rows)
    lines = [
        "",
        title,
        "",
        "a - b per image: mean +- sd, the mean's 95 % confidence interval (Student's t, n - 1 degrees of "
        "freedom), images where a's value is higher, paired t. "
        f"{directions[0].upper()}{directions[1:]}.",
        "",
        "| a - b | images | " + " | ".join(f"{k.heading} | {k.label} higher on | t" for k in rows) + " |",
        "|---|---|" + "---|---|---|" * len(rows),
    ]
    for c in contrasts:
        cells = []
        for k in rows:
            e = c[k.name]
            half = ci95_half_width(e["std"], e["n"])  # from the figures, so older study.json files render too
            f = f".{digits}f"
            cells.append(
                f"{e['mean']:+{f}} +- {e['std']:{f}} ({e['mean'] - half:+{f}} to {e['mean'] + half:+{f}}) | "
                f"{e['higher']} | {e['t']:.2f}"
            )
        lines.append(f"| {c['a']} - {c['b']} | {c['n']} | " + " | ".join(cells) + " |")
    return lines


def study_markdown(report: dict[str, Any]) -> str:
    """The study report as Markdown (tables of the real-image and held-out evaluations, training record)."""
    from murk.report.heldout import heldout_table

    lines = [f"# murk study (murk {report['murk_version']})", ""]
    real = report["real"]
    lines += [f"## Real images: mean +- std over {real['images']} images of {real['folder']} (Fig. 8)", ""]
    keys = [(k, name) for k, name in summary_keys() if any(k in real["summary"][m] for m in real["methods"])]
    lines.append("| method | " + " | ".join(name for _, name in keys) + " | images flagged |")
    lines.append("|---|" + "---|" * (len(keys) + 1))
    for m in real["methods"]:
        s = real["summary"][m]
        cells = []
        for k, _ in keys:
            v = s.get(k, {})
            mean, std = v.get("mean"), v.get("std")
            ok = isinstance(mean, (int, float)) and math.isfinite(mean)
            cells.append(f"{mean:.3f} +- {std:.3f}" if ok else "-")
        fl = s.get("flags", {})
        flagged = f"{fl.get('flagged', 0)}/{fl.get('n', 0)}" if fl else "-"
        lines.append(f"| {m} | " + " | ".join(cells) + f" | {flagged} |")
    lines += ["", "Grids (Fig. 9): `real/grids/`; per-image numbers: `real/metrics.csv`; `real/report.html`.", ""]
    if report.get("real_pairs"):
        lines += real_pairs_markdown(report["real_pairs"])
    if report.get("snow_pairs"):
        sp = report["snow_pairs"]
        lines += [
            f"## Marine snow on real pairs ({sp['images']} scenes with and without snow, {sp['folder']})",
            "",
            "snow residue: the particles' contrast left on the known particle sites (1 = kept, 0 = removed); sites "
            "left: share of particle sites still at half their contrast; GMS away from snow: structure fidelity of the "
            "output to the snowy input 3 px or more from every site (1 = nothing blurred); colour residue: the "
            "particles' RGB difference left (a particle turned into a darker or coloured dot still counts). "
            "Mean +- std over images.",
            "",
            "| method | snow residue | sites left | GMS away from snow | colour residue "
            "| particles out/in (no-reference) |",
            "|---|---|---|---|---|---|",
        ]
        for m in sp["methods"]:
            r = sp["summary"][m]

            def ms(v: dict[str, Any]) -> str:
                ok = v.get("n") and isinstance(v.get("mean"), (int, float)) and math.isfinite(v["mean"])
                return f"{v['mean']:.3f} +- {v['std']:.3f}" if ok else "-"

            lines.append(
                f"| {m} | {ms(r['snow_residue'])} | {ms(r['snow_sites_left'])} | "
                f"{ms(r.get('snow_free_gms', {}))} | {ms(r.get('snow_colour_residue', {}))} | "
                f"{ms(r['particle_residue_ratio'])} |"
            )
        lines += contrasts_markdown(
            sp.get("contrasts", []), SNOW_CONTRAST_KEYS, "### Arms against each other on the snow pairs"
        )
        lines.append("")
    if report.get("heldout"):
        h = report["heldout"]
        hh, ww = h["size_hw"]
        lines += [
            f"## Held-out procedural scenes ({h['scenes']} scenes, {ww}x{hh}, seed {h['seed']}, stages "
            f"{', '.join(h['stages'])})",
            "",
            heldout_table(h["scores"]),
            *contrasts_markdown(
                h.get("contrasts", []),
                HELDOUT_CONTRAST_KEYS,
                "### Arms against each other: paired over the scenes (against the true clean scene)",
            ),
            "",
        ]
    lines += ["## Training", "", "| arm | stages | steps | wall min | last val PSNR |", "|---|---|---|---|---|"]
    for name, a in report["arms"].items():
        wall = f"{a['wall_s'] / 60:.1f}" if a.get("wall_s") else "-"
        vp = a.get("last_eval", {}).get("val_psnr")
        lines.append(
            f"| {name} | {', '.join(a['stages'])} | {a['steps']} | {wall} | {f'{vp:.2f}' if vp is not None else '-'} |"
        )
    return "\n".join(lines) + "\n"
