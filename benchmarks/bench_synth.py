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
from _common import Figure, Recorder, cycler, device_sync, interleaved, machine, median_s, pin_one_core

pin_one_core()

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from murk._config import merge  # noqa: E402
from murk.data import sample_rgbd_dir  # noqa: E402
from murk.io import DepthOptions, discover, load_pair  # noqa: E402
from murk.synth.config import SynthConfig  # noqa: E402
from murk.synth.params import sample_variant  # noqa: E402
from murk.synth.render import render, render_batch_torch  # noqa: E402


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


def redwood_pair(hw: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray, str]:
    """The shipped 640x480 Redwood pair (float32 RGB, metres, hole-filled) and its RGB path; resized to ``hw``."""
    sources, _ = discover(sample_rgbd_dir())
    src = next(s for s in sources if s.stem.startswith("redwood"))  # 640x480
    clean, depth, _ = load_pair(src, DepthOptions())
    if hw is not None:
        clean = cv2.resize(clean, (hw[1], hw[0]), interpolation=cv2.INTER_AREA)
        depth = cv2.resize(depth, (hw[1], hw[0]), interpolation=cv2.INTER_NEAREST)
    return np.ascontiguousarray(clean), np.ascontiguousarray(depth), src.rgb_path


def gpu_figures(
    rec: Recorder,
    device: str | torch.device,
    *,
    batches: tuple[int, ...] = (64, 256),
    hw: tuple[int, int] | None = None,
    repeats: int = 10,
    targets: bool = True,
) -> None:
    """Variants/s of the batched torch path (``basic,forward_scatter``) on ``device``, against murk's numpy
    ``render`` on one core in the same run (the caller pins one core), on the Redwood pair (640x480 or ``hw``)."""
    dev = torch.device(device)
    sync = device_sync(dev)
    clean, depth, _ = redwood_pair(hw)
    size = f"{clean.shape[1]}x{clean.shape[0]}"
    cfg = SynthConfig()
    params = [sample_variant(s, cfg) for s in range(max(batches))]
    nxt = cycler(params[:8])
    cpu_s = median_s(lambda: render(clean, depth, nxt()), repeats=max(8, repeats), warmup=2)
    base = f"murk numpy render, 1 core, {size}"
    rec.add(Figure("cpu_variants_s", base, 1 / cpu_s, "variants/s"))
    for bsz in batches:
        c = torch.from_numpy(clean).permute(2, 0, 1)[None].repeat(bsz, 1, 1, 1).to(dev)
        d = torch.from_numpy(depth)[None, None].repeat(bsz, 1, 1, 1).to(dev)
        ps = params[:bsz]
        t = rec.attempt(
            f"render_batch_torch batch {bsz}",
            lambda c=c, d=d, ps=ps: median_s(
                lambda: render_batch_torch(c, d, ps), repeats=repeats, warmup=2, sync=sync
            ),
        )
        if t is not None:
            target = ">= 5,000 variants/s (640x480)" if targets else None
            label = f"render_batch_torch {dev.type}, {size}, batch {bsz}"
            rec.add(Figure(f"torch_b{bsz}_variants_s", label, bsz / t, "variants/s", base, 1 / cpu_s, target))


def main() -> None:
    clean, depth, rgb_path = redwood_pair()
    clean_u8 = cv2.imread(rgb_path)[:, :, ::-1].copy()
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
        gpu_figures(Recorder(echo=True), "cuda")
    else:
        print("torch GPU path: not measured (no CUDA device)")


if __name__ == "__main__":
    main()
