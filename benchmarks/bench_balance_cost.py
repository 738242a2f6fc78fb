"""What the input colour balance of the stage-4 weights costs (issue 27): the restorers with weights that take no
balance against the shipped ones, in the same tree, side by side.

Run: PYTHONPATH=src python benchmarks/bench_balance_cost.py --previous-lite OLD_LITE.pt --previous-jointid OLD.pt
     [--rounds 31]
(the previous weights, e.g. ``git show 2705626:src/murk/data/models/lite.pt > /tmp/lite-v1.pt``)

One random frame per size, restored alternately by the two restorers of each method (``lite``, ``lite+post`` at
640x480 and 1280x720, ``jointid`` at 640x480), torch at 2 threads, after 3 warm-up calls; median ms per frame
and the ratio shipped / previous. The network's own cost does not depend on its weights' values, so the
difference is the balance (levels + one affine map with clamping per frame).

Then the levels step inside the shipped ``lite`` restorer on the CPU: its torch twin (``topk``, what the restorer
uses) against the numpy twin (a sort of the sample), swapped in for alternate calls of the same restorer.
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
        "jointid": (  # without the lite blend, which takes its own balance
            create("jointid", checkpoint=args.previous_jointid, lite_blend=0.0),
            create("jointid", lite_blend=0.0),
        ),
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
    levels_ab(pairs["lite"][1], args.rounds)


def levels_ab(restorer: object, rounds: int) -> None:
    """The shipped lite restorer with its levels from the torch twin (``topk``, what it uses) and from the numpy twin
    (a sort of the sample, per frame), alternately: the same levels, bit for bit."""
    from murk.enhance import lite_restorer
    from murk.restore_ops.balance import balance_levels

    torch_levels = lite_restorer.balance_levels_torch

    def numpy_levels(x: torch.Tensor, low: float, high: float) -> torch.Tensor:
        return torch.from_numpy(np.stack([balance_levels(f.permute(1, 2, 0).numpy(), low, high) for f in x]))

    variants = {"torch": torch_levels, "numpy": numpy_levels}
    try:
        for h, w in [(480, 640), (720, 1280)]:
            img = np.random.default_rng(0).random((1, h, w, 3), dtype=np.float32)
            times: dict[str, list[float]] = {k: [] for k in variants}
            for _ in range(rounds + 3):
                for key, fn in variants.items():
                    lite_restorer.balance_levels_torch = fn  # type: ignore[assignment]
                    t0 = time.perf_counter()
                    restorer.restore(img)  # type: ignore[attr-defined]
                    times[key].append(time.perf_counter() - t0)
            a, b = (statistics.median(times[k][3:]) * 1e3 for k in ("torch", "numpy"))
            print(f"lite levels {w}x{h}: torch twin {a:7.2f} ms, numpy twin {b:7.2f} ms, ratio {b / a:.3f}")
    finally:
        lite_restorer.balance_levels_torch = torch_levels


if __name__ == "__main__":
    main()
