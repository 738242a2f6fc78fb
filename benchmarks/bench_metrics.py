"""Speed of murk's UIQM/UCIQE on a 640x480 image against the plainly written block-loop formulation.

Run:  PYTHONPATH=src /work/venv/bin/python benchmarks/bench_metrics.py [--repeats N] [--batch B]

Everything runs on ONE core (OMP/MKL/OPENBLAS threads = 1, ``cv2.setNumThreads(1)``,
``torch.set_num_threads(1)``). The baseline is written here the plain way: a Python loop over the blocks
(``np.max``/``np.min`` per block, as the published codes do) and straightforward whole-array numpy for the
rest; it computes the same definitions, and the script prints the largest difference between the two so the
comparison is like for like. Figures are medians over ``--repeats`` runs, in ms per image. With CUDA, the
batched torch twins are also timed on the GPU (ms per image at ``--batch``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cv2  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
from _common import Figure, Recorder, device_sync, median_s  # noqa: E402

from murk.data import sample_underwater_dir  # noqa: E402
from murk.io import read_image  # noqa: E402
from murk.metrics import uciqe, uciqe_torch, uiqm, uiqm_torch  # noqa: E402

cv2.setNumThreads(1)
torch.set_num_threads(1)

IMAGE = sample_underwater_dir() / "suim" / "n_l_52_.jpg"  # a real 640x480 photo


# ----------------------------------------------------------------------------------------------------------
# the plain block-loop formulation (baseline)


def _plain_eme(edge: np.ndarray, block: int) -> float:
    h, w = edge.shape
    k2, k1 = h // block, w // block
    total = 0.0
    for i in range(k2):
        for j in range(k1):
            b = edge[i * block : (i + 1) * block, j * block : (j + 1) * block]
            mx, mn = float(np.max(b)), float(np.min(b))
            if mn > 0:
                total += math.log(mx / mn)
    return 2.0 / (k1 * k2) * total


def _plain_log_amee(intensity: np.ndarray, block: int) -> float:
    h, w = intensity.shape
    k2, k1 = h // block, w // block
    gamma = 1026.0
    plip_sum = 0.0
    for i in range(k2):
        for j in range(k1):
            b = intensity[i * block : (i + 1) * block, j * block : (j + 1) * block]
            mx, mn = float(np.max(b)), float(np.min(b))
            num = gamma * (mx - mn) / (gamma - mn)
            den = mx + mn - mx * mn / gamma
            c = num / den if den > 0 else 0.0
            t = c * math.log(c) if c > 0 else 0.0
            plip_sum = plip_sum + t - plip_sum * t / gamma  # PLIP addition
    c = 1.0 / (k1 * k2)
    return gamma - gamma * (1.0 - plip_sum / gamma) ** c  # PLIP scalar multiplication


def plain_uiqm(rgb_u8: np.ndarray) -> float:
    """UIQM, panetta2016 definitions, written plainly."""
    x = rgb_u8.astype(np.float64)
    r, g, b = x[..., 0], x[..., 1], x[..., 2]
    uicm_parts = []
    for v in ((r - g).ravel(), (0.5 * (r + g) - b).ravel()):
        k = v.size
        t_l, t_r = math.ceil(k / 10), k // 10
        mu = float(np.mean(np.sort(v)[t_l : k - t_r]))
        uicm_parts.append((mu, float(np.mean((v - mu) ** 2))))
    (mu_rg, s_rg), (mu_yb, s_yb) = uicm_parts
    uicm = -0.0268 * math.sqrt(mu_rg**2 + mu_yb**2) + 0.1586 * math.sqrt(s_rg + s_yb)
    uism = 0.0
    for ch, lam in zip((r, g, b), (0.299, 0.587, 0.114), strict=True):
        gx = cv2.Sobel(ch, cv2.CV_64F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT)
        gy = cv2.Sobel(ch, cv2.CV_64F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT)
        uism += lam * _plain_eme(np.sqrt(gx**2 + gy**2) * ch, 8)
    uiconm = -_plain_log_amee((r + g + b) / 3.0, 8)
    return 0.0282 * uicm + 0.2953 * uism + 3.5753 * uiconm


def plain_uciqe(rgb_u8: np.ndarray) -> float:
    """UCIQE, uciqe_m definitions, written plainly (per-pixel arrays, full sort for stretchlim)."""
    lab = cv2.cvtColor(rgb_u8, cv2.COLOR_RGB2LAB).astype(np.float64) / 255.0
    lum, a, b = lab[..., 0].ravel(), lab[..., 1].ravel(), lab[..., 2].ravel()
    chroma = np.sqrt(a**2 + b**2)
    sat = chroma / np.sqrt(chroma**2 + lum**2)
    sigma_c = math.sqrt(float(np.mean(np.abs(1.0 - (np.mean(chroma) / chroma) ** 2))))
    s = np.sort(lum)
    n = s.size
    lo, hi = s[math.floor(0.01 * n)], s[math.ceil(0.99 * n) - 1]
    con_l = 1.0 if lo == hi else float(hi - lo)
    return 0.4680 * sigma_c + 0.2745 * con_l + 0.2576 * float(np.mean(sat))


# ----------------------------------------------------------------------------------------------------------


def median_ms(fn: Callable[[], object], repeats: int) -> float:
    fn()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def gpu_figures(
    rec: Recorder,
    device: str | torch.device,
    rgb: np.ndarray,
    *,
    batch: int = 64,
    repeats: int = 15,
    targets: bool = True,
) -> None:
    """ms per image of the batched torch UIQM/UCIQE on ``device`` (batch ``batch``), against murk's numpy
    ``uiqm``/``uciqe`` on one core in the same run (``rgb``: uint8 (H, W, 3))."""
    dev = torch.device(device)
    sync = device_sync(dev)
    h, w = rgb.shape[:2]
    x = torch.from_numpy(rgb).permute(2, 0, 1)[None].repeat(batch, 1, 1, 1).contiguous().to(dev)
    uciqe_torch(x[:1], data_range=255)  # builds the Lab lookup table once
    for key, name, numpy_fn, torch_fn, target in (
        ("uiqm", "UIQM panetta2016", uiqm, uiqm_torch, "<= 0.3 ms/image"),
        ("uciqe", "UCIQE uciqe_m", uciqe, uciqe_torch, None),
    ):
        cpu_ms = 1e3 * median_s(lambda f=numpy_fn: f(rgb, data_range=255), repeats=max(5, repeats // 3))
        base = f"{name} numpy, 1 core, {w}x{h}"
        rec.add(Figure(f"{key}_cpu_ms", base, cpu_ms, "ms/image"))
        t = rec.attempt(
            f"{name} torch batch {batch}",
            lambda f=torch_fn: median_s(lambda: f(x, data_range=255), repeats=repeats, warmup=3, sync=sync),
        )
        if t is not None:
            label = f"{name} torch {dev.type}, {w}x{h}, batch {batch}"
            tgt = target if targets else None
            rec.add(Figure(f"{key}_torch_ms", label, 1e3 * t / batch, "ms/image", base, cpu_ms, tgt))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--batch", type=int, default=64)
    args = ap.parse_args()

    rgb, _ = read_image(IMAGE)
    assert rgb.shape == (480, 640, 3)
    print(
        f"machine: {platform.processor() or platform.machine()}, python {platform.python_version()}, "
        f"numpy {np.__version__}, opencv {cv2.__version__}, torch {torch.__version__}; 1 thread"
    )
    print(f"image: {IMAGE.name} 640x480, median of {args.repeats} runs\n")

    d_uiqm = abs(plain_uiqm(rgb) - uiqm(rgb, data_range=255).uiqm)
    d_uciqe = abs(plain_uciqe(rgb) - uciqe(rgb, data_range=255).uciqe)
    print(f"agreement plain vs murk: |dUIQM| = {d_uiqm:.1e}, |dUCIQE| = {d_uciqe:.1e}")

    rows = [
        ("UIQM panetta2016", lambda: plain_uiqm(rgb), lambda: uiqm(rgb, data_range=255), 50.0),
        ("UCIQE uciqe_m", lambda: plain_uciqe(rgb), lambda: uciqe(rgb, data_range=255), 15.0),
    ]
    print(f"\n{'metric':<20}{'plain ms':>10}{'murk ms':>10}{'speed-up':>10}{'target ms':>11}")
    for name, base_fn, murk_fn, target in rows:
        base = median_ms(base_fn, max(3, args.repeats // 3))
        ours = median_ms(murk_fn, args.repeats)
        status = "ok" if ours <= target else "MISSED"
        print(f"{name:<20}{base:>10.1f}{ours:>10.1f}{base / ours:>9.1f}x{target:>8.0f} {status}")

    print("\nother presets (murk numpy, 1 core):")
    for preset in ("funie", "jointid"):
        t = median_ms(lambda p=preset: uiqm(rgb, data_range=255, preset=p), args.repeats)
        print(f"  UIQM {preset:<12}{t:7.1f} ms")
    t = median_ms(lambda: uciqe(rgb, data_range=255, preset="cielab_raw"), args.repeats)
    print(f"  UCIQE cielab_raw  {t:7.1f} ms")

    batch_cpu = torch.from_numpy(rgb).permute(2, 0, 1)[None].repeat(4, 1, 1, 1).contiguous()
    uciqe_torch(batch_cpu[:1], data_range=255)  # builds the Lab lookup table once
    t_uiqm_cpu = median_ms(lambda: uiqm_torch(batch_cpu, data_range=255), max(3, args.repeats // 3)) / 4
    t_uciqe_cpu = median_ms(lambda: uciqe_torch(batch_cpu, data_range=255), max(3, args.repeats // 3)) / 4
    print(f"\ntorch CPU (1 thread, batch 4): UIQM {t_uiqm_cpu:.1f} ms/image, UCIQE {t_uciqe_cpu:.1f} ms/image")

    if torch.cuda.is_available():
        print(f"\nGPU {torch.cuda.get_device_name()}, batch {args.batch}:")
        gpu_figures(Recorder(echo=True), "cuda", rgb, batch=args.batch, repeats=args.repeats)
    else:
        print("\nGPU: CUDA not available, GPU figures not measured")


if __name__ == "__main__":
    main()
