"""CPU milliseconds per frame of the paper's comparison baselines (UDAformer, URSCT-SESR) beside Joint-ID base
and the small Joint-ID, each through its murk restorer (numpy frame in, enhanced frame out), 2 threads.

Run: PYTHONPATH=src python benchmarks/bench_baselines.py [--sizes 256x256,640x480] [--repeats 3] [--threads 2]

Baseline of every ratio: Joint-ID base at the same size, measured in the same run (these machines are noisy).
Restorers in their default (``native``) policy: UDAformer on the whole frame (reflect-padded to a multiple of
8), URSCT-SESR in 256x256 tiles with 64 px overlap (640x480 -> 6 tiles), Joint-ID reflect-padded to a multiple
of 32. Random weights (timing does not depend on them; murk ships none of the baselines' weights).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np
import torch
from _common import Figure, Recorder, machine, median_s

from murk.enhance.baseline import BaselineRestorer
from murk.enhance.jointid_restorer import JointIDRestorer
from murk.enhance.udaformer_restorer import UDAFORMER
from murk.enhance.ursct_restorer import URSCT_SESR
from murk.models.jointid import build_jointid
from murk.models.udaformer import build_udaformer
from murk.models.ursct_sesr import build_ursct


def restorers() -> dict[str, Callable[[], object]]:
    """Builders of the four restorers (built one at a time to keep memory low)."""
    return {
        "jointid-base": lambda: JointIDRestorer(build_jointid("base", init=False).eval()),
        "jointid-small": lambda: JointIDRestorer(build_jointid("small").eval()),
        "udaformer": lambda: BaselineRestorer(UDAFORMER, build_udaformer()),
        "ursct": lambda: BaselineRestorer(URSCT_SESR, build_ursct()),
    }


def parse_sizes(text: str) -> list[tuple[int, int]]:
    out = []
    for item in text.split(","):
        w, h = (int(v) for v in item.lower().split("x"))
        out.append((h, w))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="256x256,640x480", help="WxH list, comma separated")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    print(f"{machine()}; torch threads {args.threads}; load average {os.getloadavg()[0]:.1f}", flush=True)
    rec = Recorder(echo=True)
    sizes = parse_sizes(args.sizes)
    frames = {hw: np.random.default_rng(0).random((1, *hw, 3), dtype=np.float32) for hw in sizes}
    times: dict[tuple[str, tuple[int, int]], float] = {}
    for name, build in restorers().items():
        restorer = build()
        for hw in sizes:
            frame = frames[hw]
            times[name, hw] = median_s(lambda r=restorer, f=frame: r.restore(f), repeats=args.repeats) * 1e3
        del restorer
    for hw in sizes:
        h, w = hw
        base = times["jointid-base", hw]
        for name in restorers():
            rec.add(
                Figure(
                    key=f"baselines.cpu{args.threads}.{name}.{w}x{h}",
                    label=f"{name} {w}x{h}, CPU {args.threads} threads",
                    value=times[name, hw],
                    unit="ms/image",
                    baseline=f"jointid-base {w}x{h}",
                    baseline_value=base,
                )
            )
    print(f"load average after: {os.getloadavg()[0]:.1f}", flush=True)


if __name__ == "__main__":
    main()
