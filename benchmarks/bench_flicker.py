"""Temporal stability: how much a method's output changes from frame to frame when only the camera moves.

Run: PYTHONPATH=src python benchmarks/bench_flicker.py [--methods lite post jointid] [--frames 20]

A slow pan is simulated on three of the shipped real images: frame t is the 400x560 window at (3 t, 2 t) px, so
consecutive frames show the same scene shifted by (3, 2) px. Each method restores the frames as one video, as
``murk enhance`` does (inside ``restorer.sequence()``: only ``post?he_smoothing=S`` carries state from frame to
frame; every other method restores each frame on its own). The overlap of consecutive outputs, aligned by the
known shift, would be identical for a method that depends only on the scene; what differs is flicker the method
adds (the inputs' aligned difference is exactly 0). Reported per image and method: mean and 99th percentile of
the absolute aligned difference, in 1/255 units, averaged over the consecutive pairs.
"""

from __future__ import annotations

import argparse
import itertools

import numpy as np
import torch

from murk.data import sample_underwater_images
from murk.enhance.restorer import create
from murk.io import read_rgb

IMAGES = ("d_r_598_", "f_r_329_", "n_l_100_")
WINDOW_HW = (400, 560)
STEP_XY = (3, 2)


def pan(img: np.ndarray, frames: int) -> list[np.ndarray]:
    """Windows of ``img`` at (STEP_XY * t) for t < ``frames``."""
    h, w = WINDOW_HW
    sx, sy = STEP_XY
    if img.shape[0] < h + sy * frames or img.shape[1] < w + sx * frames:
        raise ValueError(f"image {img.shape[:2]} too small for {frames} frames of {WINDOW_HW}")
    return [np.ascontiguousarray(img[sy * t : sy * t + h, sx * t : sx * t + w]) for t in range(frames)]


def flicker(outputs: np.ndarray) -> tuple[float, float]:
    """Mean and 99th percentile (1/255 units) of |out[t] - out[t+1]| over the aligned overlap, mean over t."""
    h, w = WINDOW_HW
    sx, sy = STEP_XY
    means, p99s = [], []
    for a, b in itertools.pairwise(outputs):
        d = np.abs(a[sy:, sx:] - b[: h - sy, : w - sx]) * 255.0
        means.append(float(d.mean()))
        p99s.append(float(np.percentile(d, 99)))
    return float(np.mean(means)), float(np.mean(p99s))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--methods",
        nargs="+",
        default=["post", "post?he_smoothing=0.8", "lite", "lite+post", "lite+post?he_smoothing=0.8", "jointid"],
    )
    ap.add_argument("--frames", type=int, default=20)
    args = ap.parse_args()
    torch.set_num_threads(2)
    paths = [p for p in sample_underwater_images() if p.name.startswith(IMAGES)]
    restorers = {m: create(m) for m in args.methods}
    print(f"{'image':<16} {'method':<28} {'mean':>6} {'p99':>6}   (|aligned frame-to-frame difference|, 1/255)")
    for path in paths:
        frames = np.stack(pan(read_rgb(path), args.frames))
        for name, restorer in restorers.items():
            with restorer.sequence():
                mean, p99 = flicker(np.clip(restorer.restore(frames).images, 0.0, 1.0))
            print(f"{path.name:<16} {name:<28} {mean:6.2f} {p99:6.2f}")


if __name__ == "__main__":
    main()
