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
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Literal

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np
import torch
from _common import Figure, Recorder, device_sync, median_s

from murk.data import sample_underwater_images
from murk.enhance.jointid_restorer import JointIDRestorer
from murk.io import read_rgb
from murk.models.jointid import build_jointid, normalize_input

H, W = 288, 512


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return math.inf if mse == 0 else 10 * math.log10(1.0 / mse)


def sample_frame(hw: tuple[int, int] = (H, W)) -> np.ndarray:
    """A crop (288x512 by default) of a real underwater sample, resized up if needed (float32 RGB in [0, 1])."""
    import cv2

    h, w = hw
    path = next(p for p in sample_underwater_images() if p.name == "d_r_47_.jpg")
    img = read_rgb(path)
    if img.shape[0] < h or img.shape[1] < w:
        scale = max(h / img.shape[0], w / img.shape[1])
        img = cv2.resize(img, (math.ceil(img.shape[1] * scale), math.ceil(img.shape[0] * scale)))
    return np.ascontiguousarray(img[:h, :w], dtype=np.float32)


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


def gpu_figures(
    rec: Recorder,
    model: torch.nn.Module,
    device: str | torch.device,
    *,
    mode: Literal["eager", "compile"] = "eager",
    hw: tuple[int, int] = (H, W),
    large_hw: tuple[int, int] = (1088, 1920),
    batches: tuple[int, ...] = (8, 16, 32, 64),
    compile_batches: tuple[int, ...] | None = None,
    compile_large: bool = True,
    repeats: int = 20,
    warmup: int = 3,
    cuda_graph: bool = True,
    compile_need_s: float = 0.0,
    targets: bool = True,
) -> None:
    """Inference figures of ``model`` on ``device``, each against the official configuration (fp32 eager, NCHW)
    measured first in the same process (``model`` is moved to ``device`` and switched to channels-last in place).

    ``mode="eager"``: bf16 + channels-last at batch 1 (eager, CUDA graph), ``batches[0]`` and the larger batches
    (the best throughput), ``large_hw`` frames, and the bf16-vs-fp32 PSNR on a real frame. ``mode="compile"``:
    ``torch.compile`` (+ CUDA graph when ``cuda_graph``; without it after a failure on the first shape) at
    ``compile_batches`` (default, in this order: ``batches[0]``, ``batches[-1]``, 1) and at ``large_hw``
    (``compile_large``); each new shape compiles again, so each is skipped when less than ``compile_need_s`` of the
    recorder's budget is left.
    ``warmup``: untimed calls before each timing (the first call of a compiled shape compiles).
    ``targets``: attach the issue's targets (meant for the base model at 288x512 on an H200).
    """
    dev = torch.device(device)
    cuda = dev.type == "cuda"
    if cuda:
        torch.backends.cudnn.benchmark = True
        torch.backends.cuda.matmul.allow_tf32 = False  # the official fp32 figures are without TF32
        torch.backends.cudnn.allow_tf32 = False
    elif cuda_graph:
        no_graph = f"CUDA graphs need a CUDA device (this run's device: {dev.type})"
        if mode == "eager":
            rec.skip(f"bf16 + channels-last + CUDA graph, {hw[0]}x{hw[1]} batch 1", no_graph)
            rec.skip(f"bf16 + channels-last + CUDA graph, {large_hw[0]}x{large_hw[1]} batch 1", no_graph)
        else:
            rec.skip("bf16 + channels-last + compile + CUDA graph", f"{no_graph}: compiled without a graph")
        cuda_graph = False
    sync = device_sync(dev)
    model = model.eval()
    (h, w), (lh, lw) = hw, large_hw
    size, large = f"{h}x{w}", f"{lh}x{lw}"
    b8 = batches[0]

    def frames(batch: int, fh: int = h, fw: int = w) -> torch.Tensor:
        return torch.rand(batch, 3, fh, fw, device=dev, generator=torch.Generator(dev).manual_seed(batch))

    def t_of(restorer: JointIDRestorer, x: torch.Tensor, reps: int = repeats) -> float:
        return median_s(lambda: restorer.restore_tensor(x), repeats=reps, warmup=warmup, sync=sync)

    def tgt(text: str) -> str | None:
        return text if targets else None

    # Baselines first: the restorers below switch the model's weights to channels-last in place.
    official = JointIDRestorer(model, device=dev, precision="fp32", channels_last=False)
    base = "official config (fp32 eager NCHW)"
    x1, xb, xl = frames(1), frames(b8), frames(1, lh, lw)
    t1 = rec.attempt(f"{base}, {size} batch 1", lambda: t_of(official, x1))
    t8 = rec.attempt(f"{base}, {size} batch {b8}", lambda: t_of(official, xb))
    tl = rec.attempt(f"{base}, {large} batch 1", lambda: t_of(official, xl, max(3, repeats // 3)))
    if t1 is not None:
        rec.add(Figure("official_b1_ms", f"{base}, {size} batch 1", t1 * 1e3, "ms"))
    if t8 is not None:
        rec.add(Figure(f"official_b{b8}_img_s", f"{base}, {size} batch {b8}", b8 / t8, "img/s"))
    if tl is not None:
        rec.add(Figure("official_large_fps", f"{base}, {large} batch 1", 1 / tl, "frames/s"))

    def latency(key: str, label: str, restorer: JointIDRestorer, target: str | None = None, need: float = 0) -> None:
        t = rec.attempt(label, lambda: t_of(restorer, x1), need_s=need)
        if t is not None:
            ref = None if t1 is None else t1 * 1e3
            rec.add(Figure(key, label, t * 1e3, "ms", f"{base}, {size} batch 1", ref, target))

    def throughput(
        key: str, label: str, restorer: JointIDRestorer, batch: int, target: str | None = None, need: float = 0
    ) -> float | None:
        x = xb if batch == b8 else frames(batch)
        t = rec.attempt(label, lambda: t_of(restorer, x), need_s=need)
        if t is None:
            return None
        ref = None if t8 is None else b8 / t8
        rec.add(Figure(key, label, batch / t, "img/s", f"{base}, {size} batch {b8}", ref, target))
        return batch / t

    def large_fps(key: str, label: str, restorer: JointIDRestorer, target: str | None = None, need: float = 0) -> None:
        t = rec.attempt(label, lambda: t_of(restorer, xl, max(3, repeats // 3)), need_s=need)
        if t is not None:
            ref = None if tl is None else 1 / tl
            rec.add(Figure(key, label, 1 / t, "frames/s", f"{base}, {large} batch 1", ref, target))

    def best_of(key: str, label: str, rates: dict[int, float | None]) -> None:
        got = {b: r for b, r in rates.items() if r is not None}
        if got:
            b = max(got, key=lambda k: got[k])
            ref = None if t8 is None else b8 / t8
            target = tgt(">= 800 img/s")
            rec.add(Figure(key, f"{label} (batch {b})", got[b], "img/s", f"{base}, {size} batch {b8}", ref, target))

    cl = "bf16 + channels-last"
    if mode == "eager":
        bf16 = JointIDRestorer(model, device=dev, precision="bf16", channels_last=True)
        latency("bf16_b1_ms", f"{cl} eager, {size} batch 1", bf16)
        if cuda_graph:
            graph = JointIDRestorer(model, device=dev, precision="bf16", channels_last=True, cuda_graph=True)
            latency("bf16_graph_b1_ms", f"{cl} + CUDA graph, {size} batch 1", graph, tgt("<= 10 ms"))
        rates = {
            b: throughput(
                f"bf16_b{b}_img_s", f"{cl} eager, {size} batch {b}", bf16, b, tgt(">= 500 img/s") if b == b8 else None
            )
            for b in batches
        }
        best_of("bf16_best_img_s", f"{cl} eager, {size}, best batch up to {max(batches)}", rates)
        large_fps("bf16_large_fps", f"{cl} eager, {large} batch 1", bf16, tgt(">= 30 frames/s"))
        if cuda_graph:
            large_fps("bf16_graph_large_fps", f"{cl} + CUDA graph, {large} batch 1", graph, tgt(">= 30 frames/s"))

        def fidelity() -> tuple[float, float]:
            frame = torch.from_numpy(sample_frame(hw)).permute(2, 0, 1)[None].to(dev)
            ref, low = official.restore_tensor(frame), bf16.restore_tensor(frame)
            p = psnr(low.images.cpu().numpy(), ref.images.cpu().numpy())
            return p, float((low.depth_m - ref.depth_m).abs().max())

        fid = rec.attempt("bf16 vs fp32 on a real frame", fidelity)
        if fid is not None:
            psnr_label = f"bf16 vs fp32 enhanced PSNR, real {size} frame"
            rec.add(Figure("bf16_psnr_db", psnr_label, fid[0], "dB", target=tgt(">= 40 dB")))
            rec.add(Figure("bf16_depth_max_diff_m", f"bf16 vs fp32 depth max |diff|, real {size} frame", fid[1], "m"))
        return

    def compiled_restorer(graph: bool) -> tuple[JointIDRestorer, str]:
        r = JointIDRestorer(model, device=dev, precision="bf16", channels_last=True, compile=True, cuda_graph=graph)
        return r, f"{cl} + compile" + (" + CUDA graph" if graph else "")

    comp, label = compiled_restorer(cuda_graph)
    shapes = compile_batches if compile_batches is not None else tuple(dict.fromkeys((b8, batches[-1], 1)))
    compiled: dict[int, float | None] = {}
    for i, b in enumerate(shapes):
        n_failed = sum(p["kind"] == "failed" for p in rec.problems)
        if b == 1:
            latency("compile_b1_ms", f"{label}, {size} batch 1", comp, tgt("<= 10 ms"), compile_need_s)
        else:
            target = tgt(">= 500 img/s") if b == b8 else None
            compiled[b] = throughput(
                f"compile_b{b}_img_s", f"{label}, {size} batch {b}", comp, b, target, compile_need_s
            )
        if i == 0 and cuda_graph and sum(p["kind"] == "failed" for p in rec.problems) > n_failed:
            rec.note("compile + CUDA graph failed on the first shape: the other shapes are compiled without a graph")
            comp, label = compiled_restorer(False)
    if compiled:
        best_of("compile_best_img_s", f"{label}, {size}, best batch up to {max(compiled)}", compiled)
    if compile_large:
        large_fps("compile_large_fps", f"{label}, {large} batch 1", comp, tgt(">= 30 frames/s"), compile_need_s)


def bench_gpu(repeats: int) -> None:
    torch.manual_seed(0)
    print(f"== GPU: {torch.cuda.get_device_name()}, torch {torch.__version__}, CUDA {torch.version.cuda}")
    rec = Recorder(echo=True)
    model = build_jointid("base")
    gpu_figures(rec, model, "cuda", mode="eager", repeats=repeats)
    gpu_figures(rec, model, "cuda", mode="compile", repeats=repeats)


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
