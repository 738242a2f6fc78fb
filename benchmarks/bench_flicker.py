"""Temporal stability: how much a method's output changes from frame to frame when only the camera moves.

Run: PYTHONPATH=src python benchmarks/bench_flicker.py [--methods lite post jointid] [--frames 20]

A slow pan is simulated on three of the shipped real images: frame t is the 400x560 window at (3 t, 2 t) px, so
consecutive frames show the same scene shifted by (3, 2) px. Each method restores the frames as one video, as
``murk enhance`` does (inside ``restorer.sequence()``: ``lite`` and ``post`` with a ``temporal`` weight average
their per-frame estimates over the frames; every other method restores each frame on its own). The overlap of
consecutive outputs, aligned by the known shift, would be identical for a method that depends only on the
scene; what differs is flicker the method adds (the inputs' aligned difference is exactly 0). Reported per
image and method: mean and 99th percentile of the absolute aligned difference, in 1/255 units, averaged over
the consecutive pairs. A method with a ``temporal`` weight lags behind real changes by about 1 / (1 - weight)
frames: column ``dev`` is the mean absolute difference from the same method restoring each frame on its own
(0 for the others); ``--speed K`` pans K times faster.
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


def pan(img: np.ndarray, frames: int, speed: int = 1) -> list[np.ndarray]:
    """Windows of ``img`` at (speed * STEP_XY * t) for t < ``frames``."""
    h, w = WINDOW_HW
    sx, sy = STEP_XY[0] * speed, STEP_XY[1] * speed
    if img.shape[0] < h + sy * frames or img.shape[1] < w + sx * frames:
        raise ValueError(f"image {img.shape[:2]} too small for {frames} frames of {WINDOW_HW}")
    return [np.ascontiguousarray(img[sy * t : sy * t + h, sx * t : sx * t + w]) for t in range(frames)]


def flicker(outputs: np.ndarray, speed: int = 1) -> tuple[float, float]:
    """Mean and 99th percentile (1/255 units) of |out[t] - out[t+1]| over the aligned overlap, mean over t."""
    h, w = WINDOW_HW
    sx, sy = STEP_XY[0] * speed, STEP_XY[1] * speed
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
        default=[
            "post",
            "post?temporal=0.8",
            "lite",
            "lite?temporal=0.8",
            "lite+post",
            "lite+post?temporal=0.8",
            "jointid",
        ],
    )
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--speed", type=int, default=1, help="pan this many times faster than (3, 2) px per frame")
    args = ap.parse_args()
    torch.set_num_threads(2)
    paths = [p for p in sample_underwater_images() if p.name.startswith(IMAGES)]
    restorers = {m: create(m) for m in args.methods}
    print(
        f"{'image':<16} {'method':<24} {'mean':>6} {'p99':>6} {'dev':>6}   "
        "(|aligned frame-to-frame difference|; dev: |video - each frame on its own|; 1/255)"
    )
    for path in paths:
        frames = np.stack(pan(read_rgb(path), args.frames, args.speed))
        for name, restorer in restorers.items():
            with restorer.sequence():
                video = np.clip(restorer.restore(frames).images, 0.0, 1.0)
            own = np.clip(restorer.restore(frames).images, 0.0, 1.0)  # outside a sequence: frame by frame
            mean, p99 = flicker(video, args.speed)
            dev = float(np.abs(video - own).mean()) * 255.0
            print(f"{path.name:<16} {name:<24} {mean:6.2f} {p99:6.2f} {dev:6.2f}")


if __name__ == "__main__":
    main()
