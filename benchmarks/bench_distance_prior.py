"""How plausible the layout prior's distance is for photographs, against real RGB-D (issue 46, item 2).

Run: PYTHONPATH=src python benchmarks/bench_distance_prior.py [RGBD_DIR ...] [--layouts 100] [--depth-scale 1000]

Each RGBD_DIR holds rgb/ + depth/ matched by stem (default: murk's shipped RGB-D, src/murk/data/rgbd: two Redwood
frames and one TUM frame, depth in mm). For each frame, against its valid true depth:
- the median-scaled AbsRel (each map scaled by median(true) / median(map) first: shape, not scale; lower is
  better) and Spearman's rank correlation (does the order of near and far agree; higher is better);
- of murk's own distance head (``jointid_net``, trained on underwater synthetic water; it sees the clean photo);
- of the layout prior (murk.io.distance_prior): the median and 10th / 90th percentiles over ``--layouts`` sampled
  layouts, and the rank correlation of one mid-range layout (horizon 0.0, no roll, 57.5 degrees, 1.75 m, 4x);
- of a constant map (its AbsRel is the frame's own spread of depth; its rank correlation is undefined).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch
from scipy.stats import spearmanr

from murk.data import sample_rgbd_dir
from murk.enhance.restorer import create
from murk.io.distance_prior import Layout, layout_distance, sample_layout
from murk.io.pairs import DepthOptions, discover, load_pair
from murk.metrics import depth_errors


def ms_abs_rel(pred: np.ndarray, true: np.ndarray, valid: np.ndarray) -> float:
    """murk's median-scaled AbsRel (:func:`murk.metrics.depth_errors`) over the valid true pixels."""
    return depth_errors(pred, np.where(valid, true, 0.0)).abs_rel_median


def spearman(pred: np.ndarray, true: np.ndarray, valid: np.ndarray) -> float:
    return float(spearmanr(pred[valid][::7], true[valid][::7]).statistic)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="*", type=Path)
    ap.add_argument("--layouts", type=int, default=100)
    ap.add_argument("--depth-scale", type=float, default=1000.0)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    folders = args.folders or [sample_rgbd_dir()]
    net = create("jointid_net")
    rng = np.random.default_rng(0)
    layouts = [sample_layout(rng) for _ in range(args.layouts)]
    mid = Layout(horizon=0.0, roll_deg=0.0, fov_deg=57.5, camera_height_m=1.75, far_m=7.0)
    print(
        "| frame | true 95th / 5th pct | jointid_net | layout prior, median (p10-p90) | constant "
        "| rank corr. jointid_net / layout |"
    )
    print("|---|---|---|---|---|---|")
    for folder in folders:
        sources, _ = discover(folder)
        for src in sources:
            rgb, depth, valid = load_pair(src, DepthOptions(depth_scale=args.depth_scale, invalid="far"))
            h, w = depth.shape
            head = net.restore(rgb[None]).depth_m[0]
            prior = [ms_abs_rel(layout_distance(h, w, lay), depth, valid) for lay in layouts]
            spread = np.percentile(depth[valid], 95) / np.percentile(depth[valid], 5)
            print(
                f"| {src.stem} | {spread:.1f} | {ms_abs_rel(head, depth, valid):.3f} | {np.median(prior):.3f} "
                f"({np.percentile(prior, 10):.3f}-{np.percentile(prior, 90):.3f}) | "
                f"{ms_abs_rel(np.ones_like(depth), depth, valid):.3f} | {spearman(head, depth, valid):.2f} / "
                f"{spearman(layout_distance(h, w, mid), depth, valid):.2f} |"
            )


if __name__ == "__main__":
    main()
