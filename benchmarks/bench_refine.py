"""What the ``refine`` step costs (docs/enhance.md, "`jointid?refine`"): restorers with and without it, side by side.

Pairs, each restored alternately on one 640x480 frame (a shipped real image, resized) after 2 warm-up calls, torch
and OpenCV at ``--threads``, median of ``--rounds``:
- ``jointid?lite_blend=0`` (refine 0.125 with the particle guard, the default) against
  ``jointid?refine=0,lite_blend=0`` (the network alone): without the ``lite`` blend, which runs after the step;
- ``lite?refine=0.125`` against ``lite``.
Then the step itself on the same frame: the transfer with the fast guided filter (``transfer_step``), the exact
filter it replaces, and the particle guard, each median of ``--rounds`` calls. The ratios are the speed claims.

Run: OMP_WAIT_POLICY=PASSIVE PYTHONPATH=src python benchmarks/bench_refine.py [--rounds 31] [--threads 2]
     [--size 640x480]
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import cv2
import numpy as np
import torch

from murk.data import sample_underwater_images
from murk.enhance.restorer import create
from murk.io.images import read_image, to_float
from murk.restore_ops import affine_transfer as at

PAIRS = (("jointid?lite_blend=0", "jointid?refine=0,lite_blend=0"), ("lite?refine=0.125", "lite"))


def median_ms(fn: Callable[[], object], rounds: int) -> float:
    fn()
    times = []
    for _ in range(rounds):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times) * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=31)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--size", default="640x480", help="WIDTHxHEIGHT of the frame")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    w, h = (int(v) for v in args.size.lower().split("x"))
    rgb = to_float(read_image(sample_underwater_images()[0])[0]).astype(np.float32)
    frame = np.ascontiguousarray(cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA)[None])
    print(f"# bench_refine  {time.strftime('%Y-%m-%d %H:%M')}  {w}x{h}, {args.threads} threads, {args.rounds} rounds")
    print("| with refine | without | ms with | ms without | ratio |")
    print("|---|---|---|---|---|")
    for spec_on, spec_off in PAIRS:
        rest = {s: create(s) for s in (spec_on, spec_off)}
        for r in rest.values():
            r.restore(frame)
            r.restore(frame)
        samples: dict[str, list[float]] = {s: [] for s in rest}
        for _ in range(args.rounds):
            for s, r in rest.items():
                t0 = time.perf_counter()
                r.restore(frame)
                samples[s].append(time.perf_counter() - t0)
        on, off = (statistics.median(samples[s]) * 1e3 for s in (spec_on, spec_off))
        print(f"| `{spec_on}` | `{spec_off}` | {on:.1f} | {off:.1f} | {on / off:.3f}x |")
    image = frame[0]
    restored = create("jointid?refine=0,lite_blend=0").restore(frame).images[0]
    radius = at.transfer_radius_px(h, w, 0.125)
    step = at.transfer_step(radius)
    fast = at.affine_transfer(image, restored, radius, 1e-4, step)
    steps = {
        f"transfer, fast guided filter (step {step})": lambda: at.affine_transfer(image, restored, radius, 1e-4, step),
        "transfer, exact guided filter": lambda: at.affine_transfer(image, restored, radius, 1e-4),
        "particle guard": lambda: at.guard_particle_removal(image, fast, restored, 0.04, at.guard_size_px(h, w)),
    }
    for name, fn in steps.items():
        print(f"{name}: {median_ms(fn, args.rounds):.2f} ms")


if __name__ == "__main__":
    main()
