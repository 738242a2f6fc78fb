"""Two or more restorers (trained arms, shipped methods) side by side on the measures of issue 46, paired.

Run: PYTHONPATH=src python benchmarks/bench_arms.py NAME=SPEC [NAME=SPEC ...] --ref NAME[,NAME...]
     [--real-pairs DIR] [--snow-pairs DIR] [--heldout-scenes 64] [--heldout-photos DIR]
     [--config configs/train-lite-mild-scratch-cpu.yaml] [--stages basic,forward_scatter,marine_snow] [--threads 2]
     [--upside-down] [--artefacts] [--out DIR] [--probe benchmarks/probes/FILE.py ...]

SPEC is a method spec as ``murk compare --method`` takes it (``lite``, ``jointid``, ``water?strength=0.5``,
``lite:runs/x/latest.pt``), or a ``.pt`` file (a ``lite`` checkpoint, a training run's ``latest.pt``). Every measure
is paired over images against each ``--ref`` arm (comma-separated: every other arm against each of them): mean
difference, its 95 % interval and the images where the arm is higher. The measures are ``murk study``'s, computed by
the same functions:
- ``--real-pairs``: real paired photographs (``<set>/input``, ``<set>/reference``), long side 256, scored with
  ``murk compare --ref`` (:func:`murk.report.study.evaluate_real_pairs`): PSNR, SSIM and CIEDE2000 as the mean over
  sets (each set counted once), ``colorbalance`` beside.
- ``--snow-pairs``: a folder with ``snowy/`` and ``clean/`` (real snowy images and their snow-free twins); the snow
  residue of ``murk compare --snow-clean`` (lower is better).
- ``--heldout-scenes N``: N held-out procedural scenes at 320x240, photographic targets (balanced at 0.5 %),
  degraded with ``--config``'s synthesis (``--stages``: basic, forward scatter, marine snow by default); PSNR against
  the TRUE clean scene, the affine-fit PSNR's gain over the input's, and the depth errors of methods that give depth
  (:func:`murk.report.heldout.score_heldout`).
- ``--heldout-photos DIR``: clean photographs the arms never trained on, each at 320x240 with the layout prior's
  distance (murk.io.distance_prior), balanced at 0.5 % and degraded the same way; the same measures (no depth: the
  prior is no truth).
- ``--upside-down``: the held-out scenes (and photographs) scored a second time turned upside down (input, truth
  and distance alike): murk's scenes put the far water at the top of the frame, in training and in the held-out set,
  so the difference measures how much of an arm's gain is that layout rather than the water (docs/train.md, "How much
  of the synthetic gain is the frame's layout").
- ``--artefacts``: the shipped real images (:func:`murk.data.sample_underwater_images`), output against input
  (:func:`murk.metrics.restoration_measures`): periodic artefact ratio (issue 46's limit: 1.3x on every image),
  mean and worst image (periodic or isolated, as ``bench_model``'s ``worst_artefact_ratio``), and the contrast ratio;
  the periodic ratio paired against each ``--ref`` arm.
- ``--probe FILE``: a Python file that registers methods of its own (``murk.enhance.restorer.register``), run before
  the arms are read, so that a SPEC may name them (``a16=detail_area?area=16``, ``lite+detail_area``). The probes of
  issue 46 that were measured and not kept live in ``benchmarks/probes/`` (their README lists them with the
  command each was measured with).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

from murk._config import load_yaml, merge
from murk.data import sample_underwater_images
from murk.io import read_rgb
from murk.io.images import list_images
from murk.io.pairs import DepthOptions, discover, load_pair
from murk.metrics import restoration_measures
from murk.report.compare import run_compare
from murk.report.heldout import HeldoutSet, make_heldout, score_heldout
from murk.report.methods import build_restorer, parse_method
from murk.report.study import (
    SNOW_CONTRAST_KEYS,
    ci95_half_width,
    evaluate_real_pairs,
    paired_contrasts,
)
from murk.restore_ops.balance import color_balance
from murk.synth.common import fit_size
from murk.train.config import TrainConfig
from murk.train.data import OnlineDegrader

HELDOUT_SEED = 20261201


def method_text(name: str, spec: str) -> str:
    """``NAME=SPEC`` as ``murk compare --method`` reads it (a bare ``.pt`` is a ``lite`` checkpoint)."""
    return f"{name}=lite:{spec}" if spec.endswith(".pt") and ":" not in spec else f"{name}={spec}"


def interval(c: dict[str, Any]) -> str:
    m, h = c["mean"], c["ci95"]
    return f"{m:+.3f} ({m - h:+.3f} to {m + h:+.3f}), higher on {c['higher']} of {c['n']}"


def contrasts_text(contrasts: list[dict[str, Any]], keys: tuple[str, ...], what: str) -> None:
    for c in contrasts:
        print(f"{what} {c['a']} - {c['b']}: " + "; ".join(f"{k} {interval(c[k])}" for k in keys))


def against(names: list[str], refs: list[str]) -> list[tuple[str, str]]:
    """Every arm of ``names`` against each of ``refs`` (itself left out), ref by ref; two refs are paired once."""
    pairs: list[tuple[str, str]] = []
    for r in refs:
        pairs += [(n, r) for n in names if n != r and (r, n) not in pairs]
    return pairs


def real_pairs(texts: list[str], names: list[str], folder: Path, refs: list[str], out: Path) -> None:
    labels = [*names, "colorbalance"]
    res = evaluate_real_pairs(
        folder,
        [parse_method(t) for t in [*texts, "colorbalance"]],
        out / "real_pairs",
        max_side=256,
        contrasts=against(labels, refs),
    )
    print("\n| real pairs, mean over sets | PSNR | SSIM | CIEDE2000 |\n|---|---|---|---|")
    for lab in labels:
        m = res["mean_over_sets"][lab]
        print(f"| {lab} | {m['psnr']:.2f} | {m['ssim']:.3f} | {m['ciede2000']:.2f} |")
    contrasts_text(res["contrasts"], ("psnr", "ciede2000"), "real pairs")


def snow_pairs(texts: list[str], names: list[str], folder: Path, refs: list[str], out: Path) -> None:
    res = run_compare(
        list_images(folder / "snowy"), [parse_method(t) for t in texts], out / "snow", snow_clean=folder / "clean"
    )
    rows = [{**r, "set": "snow"} for r in res.rows]
    print("\nsnow residue, mean: " + "; ".join(f"{n} {res.summary[n]['snow_residue']['mean']:.3f}" for n in names))
    contrasts_text(paired_contrasts(rows, against(names, refs), SNOW_CONTRAST_KEYS), ("snow_residue",), "snow")


def paired(a: list[float], b: list[float]) -> str:
    d = np.asarray(a, float) - np.asarray(b, float)
    h = ci95_half_width(float(d.std(ddof=1)), len(d))
    return f"{d.mean():+.3f} ({d.mean() - h:+.3f} to {d.mean() + h:+.3f}), higher on {int((d > 0).sum())} of {len(d)}"


def heldout(arms: dict[str, Any], name: str, data: HeldoutSet, refs: list[str]) -> None:
    per_scene: dict[str, dict[str, list[float]]] = {}
    scores = score_heldout(data, arms, per_scene=per_scene)
    inp = scores["input"]
    print(f"\n{name}: input PSNR {inp['psnr']:.2f}, after the affine fit {inp['affine_psnr']:.2f}")
    for k in arms:
        row = scores[k]
        depth = (
            f", depth AbsRel {row['abs_rel']:.3f} m/m, median-scaled {row['abs_rel_median']:.3f}"
            if np.isfinite(row.get("abs_rel", np.nan))
            else ""
        )
        print(f"  {k}: PSNR {row['psnr']:.2f}, affine-fit gain over the input {row['affine_psnr_gain']:+.2f}{depth}")
    for k, ref in against(list(arms), refs):
        fit = paired(per_scene[k]["affine_psnr"], per_scene[ref]["affine_psnr"])
        print(f"  {k} - {ref}: affine-fit {fit}; PSNR {paired(per_scene[k]['psnr'], per_scene[ref]['psnr'])}")


def upside_down(data: HeldoutSet) -> HeldoutSet:
    """``data`` with every frame turned upside down: degraded input, clean truth and distance alike."""

    def flip(batch: np.ndarray) -> np.ndarray:  # (N, H, W, ...)
        return np.ascontiguousarray(batch[:, ::-1])

    return dataclasses.replace(data, degraded=flip(data.degraded), clean=flip(data.clean), dist_m=flip(data.dist_m))


def artefacts(arms: dict[str, Any], refs: list[str]) -> None:
    images = [read_rgb(p) for p in sample_underwater_images()]
    rows: dict[str, list[dict[str, float]]] = {}
    for k, restorer in arms.items():
        outs = [np.clip(restorer.restore(img[None]).images[0], 0.0, 1.0) for img in images]
        rows[k] = [restoration_measures(img, out) for img, out in zip(images, outs, strict=True)]
    print(f"\nartefacts on the {len(images)} shipped real images (output / input):")
    for k, r in rows.items():
        periodic = [m["artefact_periodic_ratio"] for m in r]
        worst = max(max(m["artefact_periodic_ratio"], m["artefact_isolated_ratio"]) for m in r)
        contrast = float(np.mean([m["contrast_ratio"] for m in r]))
        print(f"  {k}: periodic {np.mean(periodic):.3f}x, worst image {worst:.2f}x, contrast {contrast:.2f}x")
    for k, ref in against(list(arms), refs):
        per = [[m["artefact_periodic_ratio"] for m in rows[n]] for n in (k, ref)]
        print(f"  {k} - {ref}: periodic {paired(per[0], per[1])}")


def heldout_photos(folder: Path, synthesis: Any) -> HeldoutSet:
    sources, problems = discover(folder, "layout")
    for p in problems:
        print(f"held-out photographs: left out {p.input}: {p.error}")
    cleans, dists = [], []
    for src in sources:
        rgb, dist, valid = load_pair(src, DepthOptions(depth_from="layout", layout_seed=HELDOUT_SEED))
        rgb, dist, _ = fit_size(rgb, dist, valid, (320, 240))
        cleans.append(color_balance(rgb, 0.5, 0.5))
        dists.append(dist)
    clean, dist = np.stack(cleans).astype(np.float32), np.stack(dists).astype(np.float32)
    degrader = OnlineDegrader(synthesis, seed=HELDOUT_SEED)
    out = degrader(
        torch.from_numpy(clean).permute(0, 3, 1, 2), torch.from_numpy(dist)[:, None], 0, list(range(len(clean)))
    )
    degraded = out.clamp(0, 1).permute(0, 2, 3, 1).numpy().astype(np.float32)
    return HeldoutSet(degraded, clean, np.full(dist.shape, np.nan, np.float32), HELDOUT_SEED)


def load_probe(path: Path) -> None:
    """Run the Python file ``path`` as a module (named after its stem) so that the methods it registers exist.

    Raises:
        FileNotFoundError: ``path`` is not a file.
        ImportError: it cannot be loaded as a module, or importing it failed (the message names the file).
    """
    if not path.is_file():
        raise FileNotFoundError(f"--probe {path}: no such file")
    name = f"murk_probe_{path.stem}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"--probe {path}: not a Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except (ImportError, OSError) as e:
        raise ImportError(f"--probe {path}: {e}") from e


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("arms", nargs="+", help="NAME=SPEC")
    ap.add_argument("--ref", required=True, help="the arm(s) every other arm is paired against, comma-separated")
    ap.add_argument("--real-pairs", type=Path)
    ap.add_argument("--snow-pairs", type=Path)
    ap.add_argument("--heldout-scenes", type=int, default=64)
    ap.add_argument("--heldout-photos", type=Path)
    ap.add_argument("--config", type=Path, default=Path("configs/train-lite-mild-scratch-cpu.yaml"))
    ap.add_argument("--stages", default="basic,forward_scatter,marine_snow", help="the held-out water's stages")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--upside-down", action="store_true", help="also score the held-out frames turned upside down")
    ap.add_argument("--artefacts", action="store_true", help="periodic artefacts on the shipped real images")
    ap.add_argument("--out", type=Path, help="where murk compare's reports go (default: a temporary folder)")
    ap.add_argument("--probe", type=Path, action="append", default=[], help="a Python file that registers methods")
    args = ap.parse_args()
    for probe in args.probe:
        try:
            load_probe(probe)
        except (OSError, ImportError) as e:
            ap.error(str(e))
    torch.set_num_threads(args.threads)
    pairs = [a.split("=", 1) for a in args.arms]
    names, texts = [n for n, _ in pairs], [method_text(n, s) for n, s in pairs]
    refs = args.ref.split(",")
    unknown = [r for r in refs if r not in names]
    if unknown:
        ap.error(f"--ref: {', '.join(unknown)} not among the arms ({', '.join(names)})")
    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or Path(tmp)
        if args.real_pairs:
            real_pairs(texts, names, args.real_pairs, refs, out)
        if args.snow_pairs:
            snow_pairs(texts, names, args.snow_pairs, refs, out)
    arms = {n: build_restorer(parse_method(t)) for n, t in zip(names, texts, strict=True)}
    if args.artefacts:
        artefacts(arms, refs)
    synthesis = merge(load_yaml(TrainConfig, args.config).data.synthesis, {"stages": args.stages.split(",")})
    if args.heldout_scenes:
        data = make_heldout(
            args.heldout_scenes, seed=HELDOUT_SEED, size_hw=(240, 320), synthesis=synthesis, balance_pct=0.5
        )
        heldout(arms, f"held-out scenes ({args.heldout_scenes})", data, refs)
        if args.upside_down:
            heldout(arms, f"held-out scenes ({args.heldout_scenes}), upside down", upside_down(data), refs)
    if args.heldout_photos:
        photos = heldout_photos(args.heldout_photos, synthesis)
        heldout(arms, f"held-out photographs ({len(photos.clean)})", photos, refs)
        if args.upside_down:
            heldout(arms, f"held-out photographs ({len(photos.clean)}), upside down", upside_down(photos), refs)


if __name__ == "__main__":
    main()
