"""Marine-snow removal on image pairs: the same scene without and with marine snow (e.g. MSRB's ``*_orig.png`` and
``*_task1/2.png``, PHISMID's ``7water.png`` / ``snowtest7.png``; murk does not ship such pairs).

Run: PYTHONPATH=src python benchmarks/bench_snow_pairs.py --pairs CLEAN SNOWY [CLEAN SNOWY ...]
     [--methods jointid lite post "jointid?checkpoint=FILE" ...]

A method that removes the snow restores the snowy image to what it restores the clean one to. Per pair and method:
PSNR(restore(snowy), restore(clean)) next to the inputs' own PSNR(snowy, clean); a positive difference means the
method brought the two closer (removed snow), a negative one that it made them differ more (kept or amplified the
snow; any contrast gain also amplifies the difference). Images are cropped to a common size, a multiple of 32.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.metrics import psnr


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", nargs="+", required=True, type=Path, help="CLEAN SNOWY [CLEAN SNOWY ...]")
    ap.add_argument("--methods", nargs="+", default=["jointid", "lite", "post"], help="method specs")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    if len(args.pairs) % 2:
        ap.error("--pairs: give CLEAN SNOWY pairs (an even number of files)")
    torch.set_num_threads(args.threads)
    methods = {m: create(m) for m in args.methods}
    gains: dict[str, list[float]] = {m: [] for m in methods}
    print(f"{'snowy image':<28} {'input':>7} " + " ".join(f"{m[:22]:>22}" for m in methods) + "   (PSNR dB)")
    for clean_path, snowy_path in zip(args.pairs[::2], args.pairs[1::2], strict=True):
        clean, snowy = read_rgb(clean_path), read_rgb(snowy_path)
        h = min(clean.shape[0], snowy.shape[0]) // 32 * 32
        w = min(clean.shape[1], snowy.shape[1]) // 32 * 32
        clean, snowy = clean[:h, :w], snowy[:h, :w]
        base = psnr(snowy, clean, data_range=1.0)
        cells = []
        for name, restorer in methods.items():
            a = np.clip(restorer.restore(clean[None]).images[0], 0.0, 1.0)
            b = np.clip(restorer.restore(snowy[None]).images[0], 0.0, 1.0)
            value = psnr(b, a, data_range=1.0)
            gains[name].append(value - base)
            cells.append(f"{value:22.2f}")
        print(f"{snowy_path.parent.name + '/' + snowy_path.name:<28} {base:7.2f} " + " ".join(cells))
    print("mean change against the input: " + ", ".join(f"{m} {np.mean(g):+.2f} dB" for m, g in gains.items()))


if __name__ == "__main__":
    main()
