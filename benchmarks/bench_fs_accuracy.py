"""How far is the paper's forward-scattering approximation (Eqs. 5-6) from the spatially varying blur of
Eq. (4)? Mean and 99th-percentile absolute difference (0-1 scale and 8-bit levels) on the shipped RGB-D
pairs, 8 variants each, same parameters; plus the cost of each mode.

Run: PYTHONPATH=src python benchmarks/bench_fs_accuracy.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import interleaved, machine, pin_one_core

pin_one_core()

import numpy as np  # noqa: E402

from murk._config import merge  # noqa: E402
from murk.data import sample_rgbd_dir  # noqa: E402
from murk.io import DepthOptions, discover, load_pair  # noqa: E402
from murk.synth.config import SynthConfig  # noqa: E402
from murk.synth.params import sample_variant  # noqa: E402
from murk.synth.render import render  # noqa: E402


def main() -> None:
    print(f"# bench_fs_accuracy  {time.strftime('%Y-%m-%d')}  {machine()}")
    approx_cfg = SynthConfig()
    exact_cfg = merge(approx_cfg, {"forward_scatter": {"mode": "exact"}})
    diffs, p99 = [], []
    sources, _ = discover(sample_rgbd_dir())
    for src in sources:
        clean, depth, _ = load_pair(src, DepthOptions())
        for k in range(8):
            pa = sample_variant(k, approx_cfg)
            pe = sample_variant(k, exact_cfg)
            a = render(clean, depth, pa).degraded
            e = render(clean, depth, pe).degraded
            d = np.abs(a - e)
            diffs.append(float(d.mean()))
            p99.append(float(np.percentile(d, 99)))
        print(
            f"{src.stem:16s} mean |approx - exact| = {np.mean(diffs[-8:]):.5f} ({255 * np.mean(diffs[-8:]):.2f} levels)"
        )
    print(
        f"all {len(diffs)} variants: mean {np.mean(diffs):.5f} ({255 * np.mean(diffs):.2f} of 255 levels), "
        f"99th percentile {np.mean(p99):.4f} ({255 * np.mean(p99):.1f} levels)"
    )
    clean, depth, _ = load_pair(sources[0], DepthOptions())
    ms = interleaved(
        {
            "approx": lambda: render(clean, depth, sample_variant(1, approx_cfg)),
            "exact": lambda: render(clean, depth, sample_variant(1, exact_cfg)),
        },
        rounds=5,
        inner=2,
    )
    print(
        f"cost at {clean.shape[1]}x{clean.shape[0]}, 1 thread: approx {ms['approx']:.1f} ms, exact {ms['exact']:.1f} ms"
    )


if __name__ == "__main__":
    main()
