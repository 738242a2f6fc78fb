"""Seconds per frame of the ``detail`` stage after a restorer, beside the restorer alone (docs/models/detail.md).

Run: PYTHONPATH=src python benchmarks/bench_detail.py [--sizes 640x480,1920x1080] [--methods lite,lite+detail]
     [--rounds 5] [--threads 2]

One of murk's sample underwater images resized to each size; every method restores it once to warm up, then the
methods take turns for ``--rounds`` rounds (``_common.interleaved``: a change of load falls on all of them); the
median per method and size is printed, and each chained method's ratio to the method before its ``+``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import interleaved

from murk.data import sample_underwater_images
from murk.enhance.restorer import create
from murk.io import read_rgb


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="640x480,1920x1080")
    ap.add_argument("--methods", default="lite,lite+detail,jointid,jointid+detail")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    image = read_rgb(sample_underwater_images()[0])
    methods = {m: create(m) for m in args.methods.split(",")}
    for size in args.sizes.split(","):
        w, h = (int(v) for v in size.split("x"))
        frame = cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA)[None].astype(np.float32)
        calls = {m: lambda r=r, f=frame: r.restore(f) for m, r in methods.items()}
        med = interleaved(calls, rounds=args.rounds, inner=1)
        for m, ms in med.items():
            base = m.rsplit("+", 1)[0]
            ratio = f", {ms / med[base]:.1f}x {base}" if "+" in m and base in med else ""
            print(f"{size} {m}: {ms:.0f} ms per frame{ratio}")


if __name__ == "__main__":
    main()
