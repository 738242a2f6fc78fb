"""Synthesis speed, Eqs. (1)-(6): ms per 640x480 variant on one core, murk vs a plainly written baseline.

The baseline is the same equations written the obvious way inside this script: float64 numpy, everything
(conversions, distance map, transmission) recomputed per variant, cv2.GaussianBlur for the blur. murk renders
from the float32 clean image and depth loaded once per image, as ``murk synth`` does for its 8 variants.
With CUDA present, also variants/s of the batched torch path.

Run: PYTHONPATH=src python benchmarks/bench_synth.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import cycler, interleaved, machine, pin_one_core

pin_one_core()

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from murk._config import merge  # noqa: E402
from murk.data import sample_rgbd_dir  # noqa: E402
from murk.io import DepthOptions, discover, load_pair  # noqa: E402
from murk.synth.config import SynthConfig  # noqa: E402
from murk.synth.params import sample_variant  # noqa: E402
from murk.synth.pipeline import render, render_batch_torch  # noqa: E402


def baseline(clean_u8: np.ndarray, depth_mm: np.ndarray, p, forward_scatter: bool) -> np.ndarray:
    """Eqs. (1), (5), (6) written plainly (float64, recomputed per variant)."""
    m = p.medium
    j = clean_u8.astype(np.float64) / 255.0
    d = depth_mm.astype(np.float64) / 1000.0
    dist = m.near_m + d / d.max() * (m.far_m - m.near_m)
    t = np.exp(-np.asarray(m.beta_per_m)[None, None, :] * dist[:, :, None])
    b = np.asarray(m.b_inf)[None, None, :]
    img = j * t + b * (1.0 - t)
    if forward_scatter:
        fs = p.forward_scatter
        sigma = fs.sigma0_px + fs.k_px_per_m * dist.max()
        blurred = cv2.GaussianBlur(img, (0, 0), sigma)
        a = (1.0 - np.exp(-fs.gamma_per_m * dist))[:, :, None]
        img = (1.0 - a) * img + a * blurred
    return np.clip(img, 0.0, 1.0)


def main() -> None:
    sources, _ = discover(sample_rgbd_dir())
    src = next(s for s in sources if s.stem.startswith("redwood"))  # 640x480
    clean, depth, _ = load_pair(src, DepthOptions())
    clean_u8 = cv2.imread(src.rgb_path)[:, :, ::-1].copy()
    # the baseline reads the same hole-filled depth (as millimetres) so both compute the same image
    depth_mm = np.rint(depth.astype(np.float64) * 1000.0).astype(np.uint16)
    print(f"# bench_synth  {time.strftime('%Y-%m-%d')}  {machine()}  image {clean.shape[1]}x{clean.shape[0]}, 1 thread")
    results = {}
    for stages in (("basic",), ("basic", "forward_scatter")):
        cfg = merge(SynthConfig(), {"stages": list(stages)})
        params = [sample_variant(s, cfg) for s in range(8)]
        nxt = cycler(params)

        fs = "forward_scatter" in stages
        ms = interleaved(
            {
                "baseline": lambda fs=fs, nxt=nxt: baseline(clean_u8, depth_mm, nxt(), fs),
                "murk": lambda nxt=nxt: render(clean, depth, nxt()),
            },
            rounds=9,
            inner=4,
        )
        name = ",".join(stages)
        results[name] = ms
        print(
            f"{name:24s} baseline {ms['baseline']:7.2f} ms/variant   murk {ms['murk']:6.2f} ms/variant   "
            f"speed-up x{ms['baseline'] / ms['murk']:.1f}"
        )
    cfg = SynthConfig()
    params = [sample_variant(s, cfg) for s in range(8)]
    for p in params:
        ref = baseline(clean_u8, depth_mm, p, True)
        diff = np.abs(render(clean, depth, p).degraded - ref).max()
        assert diff < 1 / 255, diff
    print("check: murk equals the baseline within 1/255 on all 8 variants")
    if torch.cuda.is_available():
        dev = torch.device("cuda")
        for bsz in (64, 256):
            c = torch.from_numpy(clean).permute(2, 0, 1)[None].repeat(bsz, 1, 1, 1).to(dev)
            d = torch.from_numpy(depth)[None, None].repeat(bsz, 1, 1, 1).to(dev)
            ps = [sample_variant(s, cfg) for s in range(bsz)]
            render_batch_torch(c, d, ps)
            torch.cuda.synchronize()
            t0 = time.perf_counter()
            n = 10
            for _ in range(n):
                render_batch_torch(c, d, ps)
            torch.cuda.synchronize()
            dt = (time.perf_counter() - t0) / n
            print(
                f"torch {torch.cuda.get_device_name()} batch {bsz}: {bsz / dt:,.0f} variants/s (basic,forward_scatter)"
            )
    else:
        print("torch GPU path: not measured (no CUDA device)")


if __name__ == "__main__":
    main()
