"""Two or more restorers (trained arms, shipped methods) side by side on the measures of issue 46, paired.

Run: PYTHONPATH=src python benchmarks/bench_arms.py NAME=SPEC [NAME=SPEC ...] --ref NAME
     [--real-pairs DIR] [--snow-pairs DIR] [--heldout-scenes 64] [--heldout-photos DIR]
     [--config configs/train-lite-mild-scratch-cpu.yaml] [--threads 2]

SPEC is a method spec (``lite``, ``jointid``, ``water?strength=0.5``) or a ``.pt`` checkpoint of ``lite`` (a training
run's ``latest.pt``). Every measure is paired over images against the ``--ref`` arm: mean difference, Student's 95 %
interval and the images where the arm is higher.
- ``--real-pairs``: real paired photographs (``murk study --real-pairs`` layout: ``<set>/input`` and
  ``<set>/reference``), long side 256; PSNR, SSIM and CIEDE2000 as the mean over sets (each set counted once),
  ``colorbalance`` beside.
- ``--snow-pairs``: real snowy images and their snow-free twins (``SNOWY`` with ``CLEAN`` beside it, or a folder
  with ``snowy/`` and ``clean/``); the snow residue of ``murk compare --snow-clean`` (lower is better).
- ``--heldout-scenes N``: N held-out procedural scenes at 320x240, photographic targets (balanced at 0.5 %),
  degraded with ``--config``'s synthesis (basic, forward scatter, marine snow); PSNR against the TRUE clean scene
  and the affine-fit PSNR's gain over the input's (murk.metrics.affine_fit_psnr).
- ``--heldout-photos DIR``: clean photographs the arms never trained on, each at 320x240 with the layout prior's
  distance (murk.io.distance_prior), balanced at 0.5 % and degraded the same way; the same two measures.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import torch

from murk._config import load_yaml, merge
from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.io.images import list_images
from murk.io.pairs import DepthOptions, discover, load_pair
from murk.metrics import affine_fit_psnr, psnr
from murk.metrics.reference import ciede2000, ssim
from murk.report.compare import downscale_to
from murk.report.heldout import make_heldout
from murk.report.study import ci95_half_width, pair_sets
from murk.restore_ops.balance import color_balance
from murk.synth.common import fit_size
from murk.train.config import TrainConfig
from murk.train.data import OnlineDegrader

HELDOUT_SEED = 20261201


def paired(a: np.ndarray, b: np.ndarray) -> str:
    d = np.asarray(a, float) - np.asarray(b, float)
    h = ci95_half_width(float(d.std(ddof=1)), len(d))
    return f"{d.mean():+.3f} ({d.mean() - h:+.3f} to {d.mean() + h:+.3f}), higher on {int((d > 0).sum())} of {len(d)}"


def restorer(spec: str) -> Any:
    return create("lite", checkpoint=spec) if spec.endswith(".pt") else create(spec)


def real_pairs(arms: dict[str, Any], folder: Path, ref: str) -> None:
    rows: dict[str, list[tuple[float, float, float]]] = {k: [] for k in arms}
    sets = []
    for name, sub in pair_sets(folder).items():
        refs = {p.stem: p for p in list_images(sub / "reference")}
        for path in list_images(sub / "input"):
            if path.stem not in refs:
                sys.exit(f"{path}: no reference image with stem '{path.stem}' in {sub / 'reference'}")
            image, target = downscale_to(read_rgb(path), 256), downscale_to(read_rgb(refs[path.stem]), 256)
            sets.append(name)
            for k, r in arms.items():
                out = np.clip(r.restore(image[None]).images[0], 0.0, 1.0)
                rows[k].append(
                    (
                        psnr(out, target, data_range=1.0),
                        ssim(out, target, data_range=1.0),
                        ciede2000(out, target, data_range=1.0),
                    )
                )
    s = np.array(sets)
    print("\n| real pairs, mean over sets | PSNR | SSIM | CIEDE2000 | PSNR per set |\n|---|---|---|---|---|")
    for k, v in rows.items():
        x = np.array(v)
        per = [[x[s == n, j].mean() for n in np.unique(s)] for j in range(3)]
        print(
            f"| {k} | {np.mean(per[0]):.2f} | {np.mean(per[1]):.3f} | {np.mean(per[2]):.2f} | "
            + " / ".join(f"{q:.2f}" for q in per[0])
            + " |"
        )
    r0 = np.array(rows[ref])
    for k in arms:
        if k != ref:
            x = np.array(rows[k])
            print(f"real pairs {k} - {ref}: PSNR {paired(x[:, 0], r0[:, 0])}; CIEDE2000 {paired(x[:, 2], r0[:, 2])}")


def snow_pairs(specs: dict[str, str], folder: Path, ref: str) -> None:
    snowy, clean = (
        (folder / "snowy", folder / "clean") if (folder / "snowy").is_dir() else (folder, folder.parent / "clean")
    )
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "murk", "compare", str(snowy), "--snow-clean", str(clean), "--out", tmp, "-q"]
        for k, v in specs.items():
            cmd += ["--method", f"{k}=lite:{v}" if v.endswith(".pt") else f"{k}={v}"]
        done = subprocess.run(cmd, check=False, capture_output=True, text=True)
        if done.returncode not in (0, 1):  # 1: some image failed, recorded in its errors.jsonl
            sys.exit(f"murk compare failed (exit {done.returncode}):\n{done.stderr or done.stdout}")
        rows = list(csv.DictReader(open(Path(tmp) / "metrics.csv", encoding="utf-8")))
    res = {m: {r["image"]: float(r["snow_residue"]) for r in rows if r["method"] == m} for m in specs}
    images = sorted(res[ref])
    print("\nsnow residue, mean: " + "; ".join(f"{m} {np.mean([res[m][i] for i in images]):.3f}" for m in specs))
    for m in specs:
        if m != ref:
            print(f"snow residue {m} - {ref}: " + paired([res[m][i] for i in images], [res[ref][i] for i in images]))


def heldout(arms: dict[str, Any], name: str, degraded: np.ndarray, clean: np.ndarray, ref: str) -> None:
    fit_in = np.array([affine_fit_psnr(x, c, data_range=1.0) for x, c in zip(degraded, clean, strict=True)])
    plain_in = np.array([psnr(x, c, data_range=1.0) for x, c in zip(degraded, clean, strict=True)])
    fit, plain = {}, {}
    for k, r in arms.items():
        out = np.concatenate([np.clip(r.restore(degraded[i : i + 8]).images, 0, 1) for i in range(0, len(degraded), 8)])
        fit[k] = np.array([affine_fit_psnr(x, c, data_range=1.0) for x, c in zip(out, clean, strict=True)])
        plain[k] = np.array([psnr(x, c, data_range=1.0) for x, c in zip(out, clean, strict=True)])
    print(f"\n{name}: input PSNR {plain_in.mean():.2f}, after the affine fit {fit_in.mean():.2f}")
    for k in arms:
        print(f"  {k}: PSNR {plain[k].mean():.2f}, affine-fit gain over the input {np.mean(fit[k] - fit_in):+.2f}")
    for k in arms:
        if k != ref:
            print(f"  {k} - {ref}: affine-fit {paired(fit[k], fit[ref])}; PSNR {paired(plain[k], plain[ref])}")


def heldout_photos(folder: Path, synthesis: Any) -> tuple[np.ndarray, np.ndarray]:
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
    return out.clamp(0, 1).permute(0, 2, 3, 1).numpy().astype(np.float32), clean


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("arms", nargs="+", help="NAME=SPEC")
    ap.add_argument("--ref", required=True)
    ap.add_argument("--real-pairs", type=Path)
    ap.add_argument("--snow-pairs", type=Path)
    ap.add_argument("--heldout-scenes", type=int, default=64)
    ap.add_argument("--heldout-photos", type=Path)
    ap.add_argument("--config", type=Path, default=Path("configs/train-lite-mild-scratch-cpu.yaml"))
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    specs = dict(a.split("=", 1) for a in args.arms)
    if args.ref not in specs:
        ap.error(f"--ref {args.ref}: not one of the arms ({', '.join(specs)})")
    arms = {k: restorer(v) for k, v in specs.items()}
    if args.real_pairs:
        real_pairs({**arms, "colorbalance": create("colorbalance")}, args.real_pairs, args.ref)
    if args.snow_pairs:
        snow_pairs(specs, args.snow_pairs, args.ref)
    synthesis = merge(
        load_yaml(TrainConfig, args.config).data.synthesis, {"stages": ["basic", "forward_scatter", "marine_snow"]}
    )
    if args.heldout_scenes:
        data = make_heldout(
            args.heldout_scenes, seed=HELDOUT_SEED, size_hw=(240, 320), synthesis=synthesis, balance_pct=0.5
        )
        heldout(arms, f"held-out scenes ({args.heldout_scenes})", data.degraded, data.clean, args.ref)
    if args.heldout_photos:
        degraded, clean = heldout_photos(args.heldout_photos, synthesis)
        heldout(arms, f"held-out photographs ({len(clean)})", degraded, clean, args.ref)


if __name__ == "__main__":
    main()
