"""Joint-ID's depth at several frame sizes, with and without ``depth_area`` (docs/enhance.md,
"jointid?depth_area"), and what the second pass costs.

Run: PYTHONPATH=src python benchmarks/bench_depth_sizes.py [--sizes 320x240,640x480,1280x720,1920x1080]
     [--scenes 16,16,8,4] [--areas 0,76800] [--method jointid] [--threads 2] [--rounds 3]

For each size: that many held-out procedural scenes (bench_model.py's held-out set: seed 20261201, the synthesis of
configs/train-small-cpu.yaml with its three stages, photographic targets) rendered at that size, restored by
``METHOD?depth_area=A`` for each area; depth AbsRel in m/m against the exact distance, the AbsRel after scaling
each map by its median ratio to the truth, and the median over scenes of median(predicted) / median(true). Then
the time per frame of each area on one scene of that size, the areas interleaved (median of ``--rounds`` rounds),
and its ratio to the first area's: the cost of the depth pass measured side by side.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_model import heldout_scenes

from murk.enhance.restorer import create
from murk.metrics import depth_errors


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="320x240,640x480,1280x720,1920x1080", help="WxH,...")
    ap.add_argument("--scenes", default="16,16,8,4", help="scenes per size")
    ap.add_argument("--areas", default="0,76800", help="depth_area values; 0 = the frame's own pass")
    ap.add_argument("--method", default="jointid")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]
    counts = [int(v) for v in args.scenes.split(",")]
    if len(counts) != len(sizes):
        ap.error("--scenes: give one count per size")
    areas = [int(v) for v in args.areas.split(",")]
    restorers = {a: create(f"{args.method}?depth_area={a}") for a in areas}
    print(f"{'size':>10} {'depth_area':>10} {'AbsRel':>7} {'scaled':>7} {'ratio':>6} {'s/frame':>8} {'x':>6}")
    for (w, h), n in zip(sizes, counts, strict=True):
        data = heldout_scenes(n, 0.5, size_hw=(h, w))
        rows = {}
        for a, r in restorers.items():
            errs, ratios = [], []
            for i in range(n):
                depth = np.asarray(r.restore(data.degraded[i : i + 1]).depth_m[0], np.float32).reshape(h, w)
                e = depth_errors(depth, data.dist_m[i])
                errs.append((e.abs_rel, e.abs_rel_median))
                valid = np.isfinite(data.dist_m[i]) & (data.dist_m[i] > 0)
                ratios.append(float(np.median(depth[valid]) / np.median(data.dist_m[i][valid])))
            rows[a] = (*np.mean(errs, axis=0), float(np.median(ratios)))
        times: dict[int, list[float]] = {a: [] for a in areas}
        frame = data.degraded[:1]
        for a in areas:
            restorers[a].restore(frame)  # warm-up
        for _ in range(args.rounds):
            for a, r in restorers.items():
                t0 = time.perf_counter()
                r.restore(frame)
                times[a].append(time.perf_counter() - t0)
        first = float(np.median(times[areas[0]]))
        for a in areas:
            t = float(np.median(times[a]))
            absrel, scaled, ratio = rows[a]
            print(f"{w}x{h:<6} {a:>10} {absrel:7.3f} {scaled:7.3f} {ratio:6.2f} {t:8.3f} {t / first:6.2f}", flush=True)


if __name__ == "__main__":
    main()
