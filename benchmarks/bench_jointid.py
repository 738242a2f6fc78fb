"""Joint-ID inference speed (base variant, random weights) on the CPU (2 threads) and, when present, CUDA.

Run: PYTHONPATH=src python benchmarks/bench_jointid.py [--cpu-only] [--gpu-only] [--repeats N]

Every speed is a ratio against a baseline measured in the same run:
- CPU: the baseline is the network in fp32 (NCHW memory) with the RLN statistics computed as separate
  reductions, as the spec writes them; then murk's fused RLN, then the
  ``jointid`` restorer end to end (numpy frame in, enhanced + depth out) in fp32 and bf16 autocast, and the
  ONNX export under ONNX Runtime, all with 2 threads at 288x512.
- GPU: the baseline is the official configuration (fp32 eager, NCHW); then bf16 + channels-last, a CUDA
  graph for batch-1 latency, torch.compile for throughput, and 1088x1920 frames.
bf16 fidelity: PSNR of the bf16 enhanced output against fp32 on a real underwater sample (288x512 crop).
Random weights (the official checkpoint is not shipped), so fidelity figures are indicative.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from murk.data import sample_underwater_images
from murk.enhance.jointid_restorer import JointIDRestorer
from murk.io import read_rgb
from murk.models.jointid import build_jointid, normalize_input

H, W = 288, 512


def timeit(fn: Callable[[], object], repeats: int, warmup: int = 1, sync: Callable[[], None] | None = None) -> float:
    """Median seconds per call."""
    for _ in range(warmup):
        fn()
    if sync:
        sync()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        if sync:
            sync()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1.0 / mse)


def sample_frame() -> np.ndarray:
    """A 288x512 crop of a real underwater sample, resized up if needed (float32 RGB in [0, 1])."""
    import cv2

    path = next(p for p in sample_underwater_images() if p.name == "d_r_47_.jpg")
    img = read_rgb(path)
    if img.shape[0] < H or img.shape[1] < W:
        scale = max(H / img.shape[0], W / img.shape[1])
        img = cv2.resize(img, (math.ceil(img.shape[1] * scale), math.ceil(img.shape[0] * scale)))
    return np.ascontiguousarray(img[:H, :W], dtype=np.float32)


def load() -> str:
    """The 1-minute load average (other processes share the CPUs: read the figures with it)."""
    return f"load average {os.getloadavg()[0]:.2f}" if hasattr(os, "getloadavg") else "load average n/a"


def bench_cpu(repeats: int) -> None:
    torch.set_num_threads(2)
    print(f"== CPU: {platform.machine()}, torch {torch.__version__}, 2 threads, {H}x{W}, {load()}")
    torch.manual_seed(0)
    model = build_jointid("base").eval()
    frame = sample_frame()
    x = normalize_input(torch.from_numpy(frame).permute(2, 0, 1)[None].contiguous())

    def literal() -> object:
        # The RLN statistics written out as separate reductions (the branch the ONNX export traces) instead of
        # murk's single fused layer-norm pass: what a line-by-line implementation of the spec costs.
        real = torch.onnx.is_in_onnx_export
        torch.onnx.is_in_onnx_export = lambda: True
        try:
            with torch.inference_mode():
                return model(x)
        finally:
            torch.onnx.is_in_onnx_export = real

    def direct() -> object:
        with torch.inference_mode():
            return model(x)

    fp32 = JointIDRestorer(model, precision="fp32", channels_last=True)
    bf16 = JointIDRestorer(model, precision="bf16", channels_last=True)
    configs: dict[str, Callable[[], object]] = {
        "baseline: network fp32, NCHW, RLN as separate reductions": literal,
        "network called directly, fp32, NCHW (fused RLN)": direct,
        "restorer fp32 (channels-last)": lambda: fp32.restore(frame[None]),
        "restorer bf16 autocast": lambda: bf16.restore(frame[None]),
    }
    ort_out = None
    tmp = tempfile.TemporaryDirectory()
    try:
        from murk.models.jointid.onnx_export import OnnxJointID, export_onnx

        ort_restorer = JointIDRestorer(OnnxJointID(export_onnx(model, Path(tmp.name) / "base.onnx"), threads=2))
        configs["restorer ONNX Runtime fp32"] = lambda: ort_restorer.restore(frame[None])
        ort_out = ort_restorer.restore(frame[None])
    except ImportError as exc:
        print(f"ONNX Runtime skipped: {exc}")
    # Round-robin: every configuration is timed once per round, so a change in the machine's load hits all.
    times: dict[str, list[float]] = {name: [] for name in configs}
    for fn in configs.values():
        fn()  # warm-up
    for _ in range(repeats):
        for name, fn in configs.items():
            t0 = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t0)
    tmp.cleanup()
    t_base = statistics.median(times[next(iter(configs))])
    for name, ts in times.items():
        t = statistics.median(ts)
        print(f"{name:52s}: {t * 1e3:8.1f} ms  {1 / t:6.2f} frames/s  x{t_base / t:5.2f} vs baseline")
    print(f"(CPU section ended at {load()})")

    ref = fp32.restore(frame[None])
    low = bf16.restore(frame[None])
    print(
        f"bf16 vs fp32 (CPU): enhanced PSNR {psnr(low.images, ref.images):.1f} dB, "
        f"depth max |diff| {np.abs(low.depth_m - ref.depth_m).max():.4f} m"
    )
    if ort_out is not None:
        print(
            f"ONNX vs torch fp32: enhanced max |diff| {np.abs(ort_out.images - ref.images).max():.2e}, "
            f"depth max |diff| {np.abs(ort_out.depth_m - ref.depth_m).max():.2e} m"
        )


def bench_gpu(repeats: int) -> None:
    dev = torch.device("cuda")
    torch.backends.cudnn.benchmark = True
    torch.backends.cuda.matmul.allow_tf32 = False  # the official fp32 figures are without TF32
    torch.backends.cudnn.allow_tf32 = False
    print(f"== GPU: {torch.cuda.get_device_name(dev)}, torch {torch.__version__}, CUDA {torch.version.cuda}")
    sync = torch.cuda.synchronize
    torch.manual_seed(0)
    model = build_jointid("base").eval().to(dev)

    def frames(batch: int, h: int = H, w: int = W) -> torch.Tensor:
        return torch.rand(batch, 3, h, w, device=dev, generator=torch.Generator(dev).manual_seed(batch))

    def run(restorer: JointIDRestorer, x: torch.Tensor) -> Callable[[], object]:
        return lambda: restorer.restore_tensor(x)

    def report(label: str, t: float, batch: int, base: float | None = None) -> None:
        ratio = f"  x{base / t:5.2f} vs official config" if base else ""
        print(f"{label:60s}: {t * 1e3:8.2f} ms/batch  {batch / t:8.1f} img/s{ratio}")

    # Baseline: the official configuration (fp32 eager, NCHW memory).
    official = JointIDRestorer(model, device=dev, precision="fp32", channels_last=False)
    x1, x8 = frames(1), frames(8)
    t1_base = timeit(run(official, x1), repeats, warmup=3, sync=sync)
    report("official config fp32 eager NCHW, 288x512 batch 1", t1_base, 1)
    t8_base = timeit(run(official, x8), repeats, warmup=3, sync=sync)
    report("official config fp32 eager NCHW, 288x512 batch 8", t8_base, 8)
    xl = frames(1, 1088, 1920)
    tl_base = timeit(run(official, xl), max(3, repeats // 3), warmup=2, sync=sync)
    report("official config fp32 eager NCHW, 1088x1920 batch 1", tl_base, 1)

    def attempt(label: str, make: Callable[[], float], batch: int, base: float) -> float | None:
        try:
            t = make()
        except Exception as exc:  # report and go on: one failing configuration must not hide the others
            print(f"{label:60s}: FAILED ({type(exc).__name__}: {str(exc).splitlines()[0][:120]})")
            return None
        report(label, t, batch, base)
        return t

    bf16 = JointIDRestorer(model, device=dev, precision="bf16", channels_last=True)
    attempt("bf16 + channels-last eager, batch 1", lambda: timeit(run(bf16, x1), repeats, 3, sync), 1, t1_base)
    graph = JointIDRestorer(model, device=dev, precision="bf16", channels_last=True, cuda_graph=True)
    attempt("bf16 + channels-last + CUDA graph, batch 1", lambda: timeit(run(graph, x1), repeats, 3, sync), 1, t1_base)
    cgraph = JointIDRestorer(model, device=dev, precision="bf16", channels_last=True, compile=True, cuda_graph=True)
    attempt(
        "bf16 + channels-last + compile + CUDA graph, batch 1",
        lambda: timeit(run(cgraph, x1), repeats, 3, sync),
        1,
        t1_base,
    )
    attempt("bf16 + channels-last eager, batch 8", lambda: timeit(run(bf16, x8), repeats, 3, sync), 8, t8_base)
    comp = JointIDRestorer(model, device=dev, precision="bf16", channels_last=True, compile=True)
    attempt("bf16 + channels-last + compile, batch 8", lambda: timeit(run(comp, x8), repeats, 3, sync), 8, t8_base)
    attempt(
        "bf16 + channels-last + compile + CUDA graph, batch 8",
        lambda: timeit(run(cgraph, x8), repeats, 3, sync),
        8,
        t8_base,
    )
    best = (0.0, 0)
    for batch in (16, 32, 64):
        xb = frames(batch)
        t = attempt(
            f"bf16 + channels-last + compile + CUDA graph, batch {batch}",
            lambda xb=xb: timeit(run(cgraph, xb), repeats, 3, sync),
            batch,
            t8_base / 8 * batch,
        )
        if t is not None and batch / t > best[0]:
            best = (batch / t, batch)
    if best[1]:
        print(f"best throughput: {best[0]:.1f} img/s at batch {best[1]}")
    attempt(
        "1088x1920 bf16 + channels-last eager, batch 1",
        lambda: timeit(run(bf16, xl), max(3, repeats // 3), 2, sync),
        1,
        tl_base,
    )
    attempt(
        "1088x1920 bf16 + channels-last + compile + CUDA graph, batch 1",
        lambda: timeit(run(cgraph, xl), max(3, repeats // 3), 2, sync),
        1,
        tl_base,
    )

    frame = torch.from_numpy(sample_frame()).permute(2, 0, 1)[None].to(dev)
    ref = official.restore_tensor(frame)
    low = bf16.restore_tensor(frame)
    p = psnr(low.images.cpu().numpy(), ref.images.cpu().numpy())
    d = float((low.depth_m - ref.depth_m).abs().max())
    print(f"bf16 vs fp32 (GPU): enhanced PSNR {p:.1f} dB, depth max |diff| {d:.4f} m")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cpu-only", action="store_true")
    parser.add_argument("--gpu-only", action="store_true")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    print(f"python {platform.python_version()}, {os.cpu_count()} CPUs visible")
    if not args.gpu_only:
        bench_cpu(args.repeats)
    if not args.cpu_only:
        if torch.cuda.is_available():
            bench_gpu(max(args.repeats, 20))
        else:
            print("== GPU: not measured (torch.cuda.is_available() is False on this machine)")


if __name__ == "__main__":
    main()
