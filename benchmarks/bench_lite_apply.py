"""``lite`` on the CPU against its speed before the colour balance (issue 27: "the CPU speeds of BENCHMARKS.md
within 10 %"): the restorer's full-resolution step as it was until 2026-12-04 and as it is now, with the weights
that take no balance and with the shipped ones, side by side in one process.

Until 2026-12-04 :func:`murk.enhance.lite_restorer._forward_cpu` upsampled the 12 coefficient maps with one
12-channel ``cv2.resize``, computed the guide's luma with torch ops per strip and copied each strip's result into
the output, and the restorer then clamped the whole frame. Now it resizes four 3-channel groups (OpenCV's
12-channel path is about 2x slower), takes the luma from one ``cv2.transform`` per strip, writes the result in
place and clamps each strip there (since the later 2026-12-04 run; the restorer no longer clamps the frame on
the CPU). The old step is reproduced below, with its clamp of the whole frame (it is no longer in murk), and
swapped in for alternate calls; outputs agree within 2e-7.

Four arms per frame size, in alternating rounds, torch and OpenCV at 2 threads, the allocator tuned as the
``murk`` command does: previous weights with the old step (the speed BENCHMARKS.md recorded before the balance),
previous weights with the new step, shipped weights with the old step, shipped weights with the new step. Printed:
median ms per frame and the median over rounds of each arm's time over the first arm's in the same round.

Run: PYTHONPATH=src python benchmarks/bench_lite_apply.py --previous-lite OLD_LITE.pt [--rounds 201]
(the previous weights: ``git show 2705626:src/murk/data/models/lite.pt > /tmp/lite-v1.pt``)
"""

from __future__ import annotations

import argparse
import statistics
import time

import cv2
import numpy as np
import torch

import murk.enhance.lite_restorer as lite_restorer
from murk._perf import tune_allocator
from murk.enhance.restorer import create
from murk.models.lite.network import apply_maps_hwc


def old_forward_cpu(model, x, work, ema=None):  # type: ignore[no-untyped-def]
    """The CPU step of ``lite`` until 2026-12-04 (one 12-channel resize, torch luma, a copy per strip)."""
    maps = model.maps(work)
    if ema is not None:
        maps = ema(maps)
    h, w = x.shape[-2:]
    out = torch.empty((x.shape[0], h, w, 3), dtype=x.dtype)
    for i in range(x.shape[0]):
        lo = maps[i].permute(1, 2, 0).contiguous().numpy()
        up = torch.from_numpy(cv2.resize(lo, (w, h), interpolation=cv2.INTER_LINEAR))
        frame = x[i].permute(1, 2, 0)
        for r0 in range(0, h, lite_restorer.STRIP_ROWS):
            rows = slice(r0, r0 + lite_restorer.STRIP_ROWS)
            m = up[rows]
            out[i, rows] = apply_maps_hwc(m[..., 0:3], m[..., 3:6], m[..., 6:9], m[..., 9:12], frame[rows])
    return out.clamp_(0.0, 1.0).permute(0, 3, 1, 2)  # the restorer clamped the whole frame after it


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--previous-lite", required=True, help="lite weights without input balance")
    ap.add_argument("--rounds", type=int, default=201)
    args = ap.parse_args()
    tune_allocator()
    torch.set_num_threads(2)
    cv2.setNumThreads(2)
    new_forward = lite_restorer._forward_cpu
    previous, shipped = create("lite", checkpoint=args.previous_lite), create("lite")
    arms = {
        "previous weights, old step": (previous, old_forward_cpu),
        "previous weights, new step": (previous, new_forward),
        "shipped weights, old step": (shipped, old_forward_cpu),
        "shipped weights, new step": (shipped, new_forward),
    }
    print(f"# bench_lite_apply  {time.strftime('%Y-%m-%d %H:%M')}  2 threads, {args.rounds} rounds")
    for size in ((480, 640), (720, 1280)):
        frame = np.random.default_rng(0).random((1, *size, 3), dtype=np.float32)
        outs = {}
        for name, (restorer, step) in arms.items():
            lite_restorer._forward_cpu = step  # type: ignore[assignment]
            for _ in range(3):
                outs[name] = restorer.restore(frame).images
        diff = np.abs(outs["shipped weights, old step"] - outs["shipped weights, new step"]).max()
        times: dict[str, list[float]] = {name: [] for name in arms}
        for _ in range(args.rounds):
            for name, (restorer, step) in arms.items():
                lite_restorer._forward_cpu = step  # type: ignore[assignment]
                t0 = time.perf_counter()
                restorer.restore(frame)
                times[name].append(time.perf_counter() - t0)
        lite_restorer._forward_cpu = new_forward
        first = times["previous weights, old step"]
        print(f"{size[1]}x{size[0]} (old and new step differ by at most {diff:.1e}):")
        for name, ts in times.items():
            ratio = statistics.median(t / f for t, f in zip(ts, first, strict=True))
            print(f"  {name:28s} {statistics.median(ts) * 1e3:6.2f} ms   {ratio:.3f}x")


if __name__ == "__main__":
    main()
