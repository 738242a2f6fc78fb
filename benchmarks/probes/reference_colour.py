"""Probe (issue 46, 2026-12-07): where each method's colour sits against the references of each real paired set.

For every set of a real-pairs folder (``<set>/input``, ``<set>/reference``; long side 256, as ``murk compare --ref``
scores them), each method's output and the reference in CIELAB (D65): the mean over the set's images of the
output's mean L*, a*, b* minus the reference's, with the spread (standard deviation over images) of the a* and b*
offsets. A method whose colour is off the same way in every set could be corrected once; offsets of opposite sign
in two sets cannot be.

Run: PYTHONPATH=src python benchmarks/probes/reference_colour.py <realpairs_dev> --methods lite,jointid,colorbalance
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
from murk.report.study import pair_sets


def mean_lab(image: np.ndarray) -> np.ndarray:
    """The mean L*, a*, b* of an RGB image (H, W, 3) in [0, 1]."""
    lab = cv2.cvtColor(np.ascontiguousarray(np.clip(image, 0, 1), np.float32), cv2.COLOR_RGB2Lab)
    return lab.reshape(-1, 3).mean(0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pairs", type=Path)
    ap.add_argument("--methods", default="lite,jointid,colorbalance")
    ap.add_argument("--max-side", type=int, default=256)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    methods = {m: create(m) for m in args.methods.split(",")}
    print("| set | method | L* - reference | a* - reference (sd) | b* - reference (sd) |\n|---|---|---|---|---|")
    for name, folder in pair_sets(args.pairs).items():
        offsets: dict[str, list[np.ndarray]] = {m: [] for m in methods}
        for path in list_images(folder / "input"):
            x = downscale_to(read_rgb(path), args.max_side).astype(np.float32)
            ref = downscale_to(read_rgb(folder / "reference" / path.name), args.max_side)
            for m, restorer in methods.items():
                offsets[m].append(mean_lab(restorer.restore(x[None]).images[0]) - mean_lab(ref))
        for m, rows in offsets.items():
            d = np.array(rows)
            mean, sd = d.mean(0), d.std(0, ddof=1)
            cells = f"{mean[0]:+.1f} | {mean[1]:+.1f} ({sd[1]:.1f}) | {mean[2]:+.1f} ({sd[2]:.1f})"
            print(f"| {name} ({len(d)}) | `{m}` | {cells} |")


if __name__ == "__main__":
    main()
