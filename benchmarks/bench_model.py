"""The shipped murk-trained Joint-ID (or any checkpoint): quality on held-out data and CPU speed.

Run: PYTHONPATH=src python benchmarks/bench_model.py [--method jointid|lite] [--options KEY=VALUE,...]
     [--checkpoint FILE] [--scenes 64] [--heldout-balance-pct 0.5] [--json OUT.json]

1. Held-out procedural scenes (never seen in training: their own seed): 64 scenes, 320x240, degraded with all
   three stages and the synthesis settings of configs/train-small-cpu.yaml. PSNR/SSIM of the degraded input and
   of the restored image against the clean render; depth AbsRel/RMSE against the exact distance (surfaces only).
2. The 13 shipped REAL underwater images: the restoration measures of murk.metrics.fidelity, output vs input
   (artefact energy ratios, structure GMS, luminance contrast ratio, colour cast, luminance ratio, bright and
   dark particle residue), averaged over the images, and the targets of the "working model" issue checked.
3. CPU speed at 640x480 with 2 threads: the restorer end to end (numpy frame in, enhanced + depth out) in fp32
   and bf16 autocast, median of interleaved rounds; the ratio bf16/fp32 is the speed claim (Joint-ID only:
   ``lite`` runs in fp32; its speed is benchmarks/bench_lite.py's).

``--method lite`` measures the shipped ``lite`` network (or ``--checkpoint``) on the same data. ``--options``: method
options, as after ``?`` in a method spec (e.g. ``refine=0.125`` for ``lite``, ``refine=0`` for ``jointid``'s network
alone).
``--heldout-balance-pct P``: the held-out scenes with photographic targets (each clean scene colour-balanced, as
the training scenes of stage 4 are; docs/train.md), with the classical ``colorbalance`` scored beside.
Every held-out row carries the PSNR after the best per-image, per-channel affine map of each output onto the TRUE
clean scene (:func:`murk.metrics.affine_fit_psnr`: least squares, then clipped to [0, 1]) and its paired gain over
the input's: what is left when a global colour and level error is forgiven, i.e. how much of a method's gain is
global colour and how much is local (haze that grows with distance, blur, particles, texture); and depth AbsRel in
m/m beside the median-scaled AbsRel (the map's shape once its scale is forgiven). ``--affine-fit`` is accepted
for old command lines (the figure is always computed).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np
import torch

from murk._config import load_yaml, merge
from murk.data import sample_underwater_images, shipped_jointid_weights, shipped_lite_weights
from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.metrics import restoration_measures
from murk.report.heldout import HeldoutSet, heldout_table, make_heldout, score_heldout
from murk.train.config import TrainConfig

ROOT = Path(__file__).resolve().parent.parent
HELDOUT_SEED = 20261201
"""Seed of the held-out scenes (training uses seed 0: scenes derive_seed(0, i))."""


def heldout_scenes(scenes: int, balance_pct: float | None, size_hw: tuple[int, int] = (240, 320)) -> HeldoutSet:
    """The held-out set: ``scenes`` procedural scenes at ``size_hw`` (320x240 by default; seed
    :data:`HELDOUT_SEED`) degraded by the three stages of the training recipe; ``balance_pct``: photographic
    (colour-balanced) clean targets."""
    train_cfg = load_yaml(TrainConfig, ROOT / "configs" / "train-small-cpu.yaml")
    synthesis = merge(train_cfg.data.synthesis, {"stages": ["basic", "forward_scatter", "marine_snow"]})
    return make_heldout(scenes, seed=HELDOUT_SEED, size_hw=size_hw, synthesis=synthesis, balance_pct=balance_pct)


def real_measures(restorer: object) -> dict[str, float]:
    """Mean restoration measures over the shipped real images, output vs input."""
    rows = []
    for path in sample_underwater_images():
        img = read_rgb(path)
        out = np.clip(restorer.restore(img[None]).images[0], 0.0, 1.0)  # type: ignore[attr-defined]
        rows.append(restoration_measures(img, out))
    keys = rows[0].keys()
    mean = {k: float(np.mean([r[k] for r in rows])) for k in keys}
    mean["images"] = float(len(rows))
    mean["worst_artefact_ratio"] = float(
        max(max(r["artefact_periodic_ratio"], r["artefact_isolated_ratio"]) for r in rows)
    )
    return mean


def speed(checkpoint: str, repeats: int, spec: str = "jointid") -> dict[str, float]:
    torch.set_num_threads(2)
    frame = np.random.default_rng(0).random((1, 480, 640, 3), dtype=np.float32)
    fns = {p: create(spec, checkpoint=checkpoint, precision=p) for p in ("fp32", "bf16")}
    for r in fns.values():
        r.restore(frame)  # warm-up
    samples: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(repeats):
        for k, r in fns.items():
            t0 = time.perf_counter()
            r.restore(frame)
            samples[k].append(time.perf_counter() - t0)
    ms = {k: statistics.median(v) * 1e3 for k, v in samples.items()}
    return {
        "fp32_ms": ms["fp32"],
        "bf16_ms": ms["bf16"],
        "fp32_fps": 1e3 / ms["fp32"],
        "bf16_fps": 1e3 / ms["bf16"],
        "bf16_speedup": ms["fp32"] / ms["bf16"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", choices=["jointid", "lite", "water"], default="jointid")
    ap.add_argument("--options", default="", help="method options KEY=VALUE,... (e.g. refine=0.125)")
    ap.add_argument("--checkpoint", default=None, help="default: the shipped weights of --method")
    ap.add_argument("--scenes", type=int, default=64)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--heldout-balance-pct", type=float, default=None, help="photographic held-out targets")
    ap.add_argument("--affine-fit", action="store_true", help="accepted for old command lines (always computed)")
    ap.add_argument("--json", default=None, help="also write the figures to this JSON file")
    args = ap.parse_args()
    if args.checkpoint is None:
        args.checkpoint = str(shipped_lite_weights() if args.method == "lite" else shipped_jointid_weights())
    torch.set_num_threads(2)
    spec = f"{args.method}?{args.options}" if args.options else args.method
    figures: dict[str, object] = {"method": spec, "checkpoint": args.checkpoint}

    data = heldout_scenes(args.scenes, args.heldout_balance_pct)
    # water reads Joint-ID's weights through its base method (the shipped ones); --checkpoint is for the networks
    restorer = create(spec) if args.method == "water" else create(spec, checkpoint=args.checkpoint)
    restorers = {"model": restorer}
    if args.heldout_balance_pct is not None:
        restorers["colorbalance"] = create("colorbalance")
    scores = score_heldout(data, restorers)
    figures["heldout"] = scores
    print(f"== held-out: {args.scenes} procedural scenes, 320x240, three stages, seed {HELDOUT_SEED}")
    print(heldout_table(scores))
    figures["heldout_affine_fit_psnr"] = {k: v["affine_psnr"] for k, v in scores.items()}
    model = scores["model"]
    gain, half = model["psnr_gain"], model["psnr_gain_ci95"]
    fit, fit_half = model["affine_psnr_gain"], model["affine_psnr_gain_ci95"]
    print(
        f"PSNR gain {gain:+.2f} dB, 95 % CI {gain - half:+.2f} to {gain + half:+.2f} (paired over the scenes); "
        f"after the affine fit {fit:+.2f} dB, 95 % CI {fit - fit_half:+.2f} to {fit + fit_half:+.2f} "
        f"(input {scores['input']['affine_psnr']:.2f} dB; learn-the-water target: jointid >= +3.0, lite >= +2.5); "
        f"SSIM {scores['input']['ssim']:.3f} -> {model['ssim']:.3f}; "
        f"depth AbsRel {model.get('abs_rel', float('nan')):.3f} m/m (target <= 0.45), "
        f"median-scaled {model.get('abs_rel_median', float('nan')):.3f} (target <= 0.25)"
    )

    real = real_measures(restorer)
    figures["real"] = real
    print(f"\n== {int(real['images'])} shipped real images, output vs input (means)")
    checks = [
        ("artefact periodic ratio", real["artefact_periodic_ratio"], "<= 1.3"),
        ("artefact isolated ratio", real["artefact_isolated_ratio"], "<= 1.3"),
        ("worst single-image artefact ratio", real["worst_artefact_ratio"], "(info)"),
        ("structure GMS", real["structure_gms"], "(info; flag below 0.7)"),
        ("luminance contrast ratio", real["contrast_ratio"], ">= 0.5 (no grey collapse)"),
        ("colour cast in -> out", real["cast_out"] - real["cast_in"], "< 0 (smaller cast)"),
        ("mean luminance ratio", real["luminance_ratio"], ">= 0.9 (not darkened)"),
        ("particle residue ratio (bright+dark)", real["particle_residue_ratio"], "< 1 (fewer particles)"),
    ]
    for name, value, target in checks:
        print(f"  {name:<38} {value:8.3f}   target {target}")
    print(
        f"  (cast {real['cast_in']:.2f} -> {real['cast_out']:.2f}; particles/MP bright "
        f"{real['particles_bright_in']:.0f} -> {real['particles_bright_out']:.0f}, "
        f"dark {real['particles_dark_in']:.0f} -> {real['particles_dark_out']:.0f})"
    )

    if args.method != "jointid":
        if args.json:
            Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")
        return
    sp = speed(args.checkpoint, args.repeats, spec)
    figures["speed_640x480_2threads"] = sp
    print(
        f"\n== CPU speed, 640x480, 2 threads: fp32 {sp['fp32_ms']:.0f} ms ({sp['fp32_fps']:.1f} frames/s), "
        f"bf16 {sp['bf16_ms']:.0f} ms ({sp['bf16_fps']:.1f} frames/s), bf16/fp32 speed-up x{sp['bf16_speedup']:.2f}"
    )
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
