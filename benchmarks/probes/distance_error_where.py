"""Analysis probe (issue 46, 2026-12-08): where Joint-ID's distance is wrong on murk's held-out scenes, once scaled
by its median ratio to the truth: near the scene's depth edges, or everywhere; and how much of it is a trend from
row to row (the frame's layout: far water at the top).

Per scene: the median-scaled relative error ``|s d - t| / t`` (``s = median(t) / median(d)``); its share on the
pixels within 4 pixels of a depth edge (``|grad log t| > 0.2``, Sobel) beside those pixels' share of the frame; and
the median-scaled AbsRel again after each row is also scaled by its own median ratio (what is left once the
row-to-row trend is taken out). bench_water_distance.py found the distance's shape costs ``water`` 1.1-2.7 dB after
the fit; ``water_guided.py`` (a guided filter, which snaps a map to the frame's edges) gained nothing, and this
says why.

Run: PYTHONPATH=src python benchmarks/probes/distance_error_where.py [--config configs/train-small-cpu.yaml]
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: the distance benchmark's helpers
from bench_water_distance import HELDOUT_SEED, median_scaled

EDGE_GRAD = 0.2
"""A depth edge: the Sobel gradient of log distance above this (per pixel, unnormalised Sobel)."""
EDGE_REACH_PX = 4
"""Pixels within this many of an edge count as near it (a 9x9 dilation)."""


@dataclass(frozen=True)
class ErrorSplit:
    abs_rel_median: float
    """The median-scaled AbsRel."""
    near_edge_error_share: float
    """The share of the summed relative error on pixels near a depth edge."""
    near_edge_pixel_share: float
    """Those pixels' share of the valid pixels."""
    abs_rel_rows: float
    """The median-scaled AbsRel after each row is scaled by its own median ratio too."""


def error_split(pred_m: np.ndarray, true_m: np.ndarray) -> ErrorSplit:
    """The split of one scene's (H, W) distance error (``true_m`` NaN where no surface: left out)."""
    ok = np.isfinite(true_m) & (true_m > 0)
    scaled = median_scaled(pred_m, true_m)
    err = np.where(ok, np.abs(scaled - np.where(ok, true_m, 1.0)) / np.where(ok, true_m, 1.0), 0.0)
    log_t = np.log(np.where(ok, true_m, np.nanmax(true_m[ok]))).astype(np.float32)
    grad = np.hypot(cv2.Sobel(log_t, cv2.CV_32F, 1, 0), cv2.Sobel(log_t, cv2.CV_32F, 0, 1))
    side = 2 * EDGE_REACH_PX + 1
    near = ok & cv2.dilate((grad > EDGE_GRAD).astype(np.uint8), np.ones((side, side), np.uint8)).astype(bool)
    row_ratio = np.ones(true_m.shape[0])
    for r in range(true_m.shape[0]):
        if ok[r].any():
            row_ratio[r] = np.median(true_m[r][ok[r]]) / np.median(scaled[r][ok[r]])
    rows = np.abs(scaled * row_ratio[:, None] - np.where(ok, true_m, 1.0)) / np.where(ok, true_m, 1.0)
    return ErrorSplit(
        float(err[ok].mean()),
        float(err[near].sum() / max(err[ok].sum(), 1e-12)),
        float(near.sum() / ok.sum()),
        float(rows[ok].mean()),
    )


def main() -> None:
    import torch

    from murk._config import load_yaml, merge
    from murk.enhance.restorer import create
    from murk.report.heldout import make_heldout
    from murk.train.config import TrainConfig

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=Path("configs/train-lite-mild-scratch-cpu.yaml"))
    ap.add_argument("--heldout-scenes", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    synthesis = merge(
        load_yaml(TrainConfig, args.config).data.synthesis, {"stages": ["basic", "forward_scatter", "marine_snow"]}
    )
    data = make_heldout(
        args.heldout_scenes, seed=HELDOUT_SEED, size_hw=(240, 320), synthesis=synthesis, balance_pct=0.5
    )
    jointid = create("jointid")
    splits = []
    for i in range(0, len(data.degraded), 8):
        depth = jointid.restore(data.degraded[i : i + 8]).depth_m
        assert depth is not None
        splits += [error_split(p, t) for p, t in zip(depth, data.dist_m[i : i + 8], strict=True)]
    mean = {k: float(np.mean([getattr(s, k) for s in splits])) for k in ErrorSplit.__dataclass_fields__}
    print(f"{args.config}, {len(splits)} held-out scenes, Joint-ID's distance, means over the scenes:")
    print(f"  median-scaled AbsRel {mean['abs_rel_median']:.3f} m/m")
    print(
        f"  share of that error within {EDGE_REACH_PX} px of a depth edge {mean['near_edge_error_share']:.3f}, "
        f"on {mean['near_edge_pixel_share']:.3f} of the pixels"
    )
    print(f"  after each row is scaled by its own median ratio too: {mean['abs_rel_rows']:.3f} m/m")


if __name__ == "__main__":
    main()
