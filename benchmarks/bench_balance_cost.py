"""What the input colour balance of the stage-4 weights costs (issue 27): the restorers with weights that take no
balance against the shipped ones, in the same tree, side by side.

Run: PYTHONPATH=src python benchmarks/bench_balance_cost.py --previous-lite OLD_LITE.pt --previous-jointid OLD.pt
     [--rounds 31]
(the previous weights, e.g. ``git show 2705626:src/murk/data/models/lite.pt > /tmp/lite-v1.pt``)

One random frame per size, restored alternately by the two restorers of each method (``lite``, ``lite+post`` at
640x480 and 1280x720, ``jointid`` at 640x480), torch at 2 threads, after 3 warm-up calls; median ms per frame
and the ratio shipped / previous. The network's own cost does not depend on its weights' values, so the
difference is the balance (levels + one affine map with clamping per frame).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import torch

from murk.enhance.restorer import create


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--previous-lite", required=True, help="lite weights without input balance")
    ap.add_argument("--previous-jointid", required=True, help="Joint-ID weights without input balance")
    ap.add_argument("--rounds", type=int, default=31)
    args = ap.parse_args()
    torch.set_num_threads(2)
    pairs = {
        "lite": (create("lite", checkpoint=args.previous_lite), create("lite")),
        "lite+post": (create("lite+post", checkpoint=args.previous_lite), create("lite+post")),
        "jointid": (create("jointid", checkpoint=args.previous_jointid), create("jointid")),
    }
    for name, (old, new) in pairs.items():
        sizes = [(480, 640)] if name == "jointid" else [(480, 640), (720, 1280)]
        rounds = max(5, args.rounds // 3) if name == "jointid" else args.rounds
        for h, w in sizes:
            img = np.random.default_rng(0).random((1, h, w, 3), dtype=np.float32)
            times: dict[str, list[float]] = {"old": [], "new": []}
            for _ in range(3):
                old.restore(img)
                new.restore(img)
            for _ in range(rounds):
                for key, r in (("old", old), ("new", new)):
                    t0 = time.perf_counter()
                    r.restore(img)
                    times[key].append(time.perf_counter() - t0)
            a, b = (statistics.median(times[k]) * 1e3 for k in ("old", "new"))
            print(f"{name:<10} {w}x{h}: previous weights {a:7.2f} ms, shipped {b:7.2f} ms, ratio {b / a:.3f}")


if __name__ == "__main__":
    main()
