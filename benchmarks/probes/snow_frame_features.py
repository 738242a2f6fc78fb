"""Probe (issue 46, item 4, 2026-12-07; measured, not kept): can a frame be told to hold marine snow from what
``detail`` takes out of it?

If it could, ``detail`` (which costs about 0.25 dB on snow-free photographs) could run only on snowy frames. For each
image of each folder (downscaled so that its long side is at most ``--max-side``), ``lite`` restores it and ``detail``
runs after; printed per image, and as the range over each folder:
- ``dark``: per thousand pixels, where ``detail`` darkens the luma by more than 0.02 / 0.05 / 0.10 (what it takes
  for particles), and the mean absolute change (x 1000);
- ``flat``: the same darkening (0.03, 0.06) counted only on the flatter half of the frame (the local gradient of a
  median-filtered background below its median), per ten thousand flat pixels, and the share of the darkened pixels
  that lie there (snow floats in front of open water and sand as much as in front of texture).

Run: PYTHONPATH=src python benchmarks/probes/snow_frame_features.py <pairs>/uieb18/input <pairs>/uimnet9/input
     --max-side 256 ; the same for <snow pairs>/snowy, <snow pairs>/clean and the unseen pairs at full size
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np
import torch

from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.io.images import list_images
from murk.report.compare import downscale_to


def features(restored: np.ndarray, detailed: np.ndarray) -> list[float]:
    change = (detailed - restored).mean(-1)
    dark = [float((change < -t).mean() * 1000) for t in (0.02, 0.05, 0.10)] + [float(np.abs(change).mean() * 1000)]
    luma = detailed.mean(-1).astype(np.float32)
    k = max(3, round(max(luma.shape) / 64) | 1)
    background = cv2.medianBlur((luma * 255).astype(np.uint8), k).astype(np.float32) / 255
    gradient = np.hypot(cv2.Sobel(background, cv2.CV_32F, 1, 0), cv2.Sobel(background, cv2.CV_32F, 0, 1))
    texture = cv2.GaussianBlur(gradient, (0, 0), 3)
    flat = texture < np.percentile(texture, 50)
    out = []
    for t in (0.03, 0.06):
        m = change < -t
        out += [float(1e4 * (m & flat).sum() / max(1, flat.sum())), float((m & flat).sum() / max(1, m.sum()))]
    return dark + out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path)
    ap.add_argument("--max-side", type=int, default=100_000)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    lite, detail = create("lite"), create("detail")
    names = "dark>0.02 dark>0.05 dark>0.10 |change| flat>0.03 share flat>0.06 share".split()
    for folder in args.folders:
        rows = []
        for path in list_images(folder):
            x = downscale_to(read_rgb(path), args.max_side).astype(np.float32)
            y = lite.restore(x[None]).images[0]
            rows.append(features(y, detail.restore(y[None]).images[0]))
            print(
                f"{folder.name}/{path.name}: " + " ".join(f"{n} {v:.2f}" for n, v in zip(names, rows[-1], strict=True))
            )
        f = np.array(rows)
        print(
            f"{folder} ({len(rows)}): "
            + "; ".join(f"{n} {a:.2f}-{b:.2f}" for n, a, b in zip(names, f.min(0), f.max(0), strict=True))
        )


if __name__ == "__main__":
    main()
