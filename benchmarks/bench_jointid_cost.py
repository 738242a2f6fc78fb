"""What ``jointid`` costs per frame on the CPU against its cost before the real-water work (issue 27: "the CPU
speeds of BENCHMARKS.md within 10 %"), side by side in one process.

Run: PYTHONPATH=src python benchmarks/bench_jointid_cost.py --previous-jointid STAGE2.pt [--rounds 31]
     [--size 640x480] [--threads 2]
(the weights shipped before the real-water work: ``git show 1c935ef:src/murk/data/models/jointid-small.pt >
/tmp/jointid-stage2.pt``)

Four arms, called in turn on one random frame for ``--rounds`` rounds after 3 warm-up calls each, torch and
OpenCV at ``--threads``:
- before the real-water work: the stage-2 weights (no input balance, no colour head), the network alone
  (``refine=0``, ``lite_blend=0``), the shuffle smoothing by torch's pooling;
- until 2026-12-04: the shipped weights with the balance, the colour head and ``refine``, no ``lite`` blend, the
  smoothing by torch's pooling;
- the shipped weights with OpenCV's smoothing (:func:`murk.models.jointid.decoder.smooth_shuffled`'s twin), no
  blend;
- ``jointid`` as it is now: the same plus the shipped ``lite``'s restoration blended in (``lite_blend`` 0.5).
The torch smoothing is restored for an arm by switching the OpenCV twin off
(``murk.models.jointid.decoder._plain_cpu_inference``). Printed: median ms per frame and the median over rounds
of each arm's time over the first arm's in the same round.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from typing import Any

import cv2
import numpy as np
import torch

import murk.models.jointid.decoder as decoder
from murk._perf import tune_allocator
from murk.enhance.restorer import create


def parse_size(text: str) -> tuple[int, int]:
    """``WxH`` -> (H, W)."""
    w, h = (int(v) for v in text.lower().split("x"))
    return h, w


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--previous-jointid", required=True, help="Joint-ID weights of before the real-water work")
    ap.add_argument("--rounds", type=int, default=31)
    ap.add_argument("--size", default="640x480", help="frame WxH")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    tune_allocator()
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    opencv_twin = decoder._plain_cpu_inference
    torch_only: Callable[[torch.Tensor], bool] = lambda x: False  # noqa: E731
    arms: dict[str, tuple[Any, Callable[[torch.Tensor], bool]]] = {
        "before the real-water work (stage 2, network alone, torch smoothing)": (
            create("jointid", checkpoint=args.previous_jointid, refine=0.0, lite_blend=0.0),
            torch_only,
        ),
        "until 2026-12-04 (shipped, refine, torch smoothing, no blend)": (
            create("jointid", lite_blend=0.0),
            torch_only,
        ),
        "OpenCV smoothing, no blend": (create("jointid", lite_blend=0.0), opencv_twin),
        "`jointid` now (OpenCV smoothing, lite blended in)": (create("jointid"), opencv_twin),
    }
    h, w = parse_size(args.size)
    frame = np.random.default_rng(0).random((1, h, w, 3), dtype=np.float32)
    stamp = time.strftime("%Y-%m-%d %H:%M")
    print(f"# bench_jointid_cost  {stamp}  {w}x{h}, {args.threads} threads, {args.rounds} rounds")
    for restorer, twin in arms.values():
        decoder._plain_cpu_inference = twin
        for _ in range(3):
            restorer.restore(frame)
    times: dict[str, list[float]] = {name: [] for name in arms}
    for _ in range(args.rounds):
        for name, (restorer, twin) in arms.items():
            decoder._plain_cpu_inference = twin
            t0 = time.perf_counter()
            restorer.restore(frame)
            times[name].append(time.perf_counter() - t0)
    decoder._plain_cpu_inference = opencv_twin
    first = next(iter(arms))
    print("\n| arm | ms per frame | ratio |")
    print("|---|---|---|")
    for name, ts in times.items():
        ratio = statistics.median(t / t0 for t, t0 in zip(ts, times[first], strict=True))
        print(f"| {name} | {statistics.median(ts) * 1e3:.1f} | {ratio:.3f}x |")


if __name__ == "__main__":
    main()
