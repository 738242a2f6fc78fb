"""Latency of the one-input ONNX export of ``lite`` under plain ONNX Runtime, beside murk's torch restorer, at
640x480 and 1280x720 on 2 CPU threads, side by side in one run.

Run: PYTHONPATH=src python benchmarks/bench_lite_onnx.py [--checkpoint LITE.pt] [--rounds 15]

Measured per size on a real underwater frame (the first shipped sample image, resized), one frame at a time,
median over interleaved rounds (machine noise hits both alike; each block of timed calls starts after a pause
and an untimed call, so that neither runtime's idle threads still spin on the cores, see :func:`blocks`):
- ``onnxruntime``: what a user of the exported file runs: ``murk export`` of the checkpoint, one
  ``InferenceSession`` (CPU, 2 intra-op threads, otherwise default options), ``session.run(None, {"image": x})``
  with x the (1, 3, H, W) float32 frame in [0, 1] (the working image, padding and clamping are in the graph);
- ``torch restorer``: ``murk.enhance.create("lite").restore(frame)`` on the (1, H, W, 3) frame, what ``murk enhance
  --method lite`` calls per frame (torch and OpenCV on 2 threads): the baseline of the ratio.
Also printed: max |onnxruntime - torch restorer| on that frame (the export's contract: <= 1e-4).
Weights: ``--checkpoint``, else the shipped ``lite.pt``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cv2
import numpy as np
import torch
from _common import Figure, Recorder, machine

from murk.data import sample_underwater_images, shipped_lite_weights
from murk.enhance.restorer import create
from murk.io import read_rgb

SIZES = {"640x480": (480, 640), "1280x720": (720, 1280)}
THREADS = 2


GAP_S = 0.05
"""Untimed pause before each block of calls (see :func:`blocks`)."""


def blocks(fns: dict[str, Callable[[], object]], *, rounds: int, inner: int) -> dict[str, float]:
    """Median milliseconds per call of each function, in alternating rounds. Each block of ``inner`` timed calls
    follows a pause of :data:`GAP_S` and one untimed call: ONNX Runtime's and OpenMP's worker threads busy-wait a
    while after each call, and a method timed right after the other shares the 2 cores with them (measured
    2026-12-03: torch at 640x480 16-200 ms per frame right after ONNX Runtime, 9 ms after a 50 ms pause; 6.6 ms
    alone)."""
    samples: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(rounds):
        for k, f in fns.items():
            time.sleep(GAP_S)
            f()
            t0 = time.perf_counter()
            for _ in range(inner):
                f()
            samples[k].append((time.perf_counter() - t0) / inner * 1e3)
    return {k: statistics.median(v) for k, v in samples.items()}


def main() -> None:
    import onnxruntime as ort

    from murk.models.export import export_checkpoint

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, default=None, help="lite checkpoint (default: the shipped lite.pt)")
    ap.add_argument("--rounds", type=int, default=15, help="timing rounds (each: both sizes, both runtimes)")
    args = ap.parse_args()
    torch.set_num_threads(THREADS)
    cv2.setNumThreads(THREADS)
    ckpt = args.checkpoint or shipped_lite_weights()
    print(f"machine: {machine()}, onnxruntime {ort.__version__}; {THREADS} threads (torch, OpenCV, ONNX Runtime)")
    print(f"weights: {ckpt}")
    with tempfile.TemporaryDirectory(prefix="bench-lite-onnx-") as tmp:
        onnx_path = export_checkpoint(ckpt, Path(tmp) / "lite.onnx").path  # what `murk export` writes
        opts = ort.SessionOptions()
        opts.intra_op_num_threads = THREADS
        opts.inter_op_num_threads = 1
        session = ort.InferenceSession(str(onnx_path), opts, providers=["CPUExecutionProvider"])
    restorer = create("lite", checkpoint=str(ckpt))
    src = read_rgb(sample_underwater_images()[0])
    rec = Recorder(echo=True)
    load_start = os.getloadavg()[0]  # other work on the box slows torch's thread pool more than ONNX Runtime's
    fns: dict[str, Callable[[], object]] = {}
    for label, (h, w) in SIZES.items():
        frame = np.ascontiguousarray(cv2.resize(src, (w, h), interpolation=cv2.INTER_AREA).clip(0, 1), np.float32)
        frame = frame[None]  # (1, H, W, 3), as murk enhance passes it
        x = np.ascontiguousarray(frame.transpose(0, 3, 1, 2))  # (1, 3, H, W), as the graph takes it
        (out,) = session.run(None, {"image": x})
        ref = restorer.restore(frame).images.transpose(0, 3, 1, 2)
        print(f"{label}: max |onnxruntime - torch restorer| = {float(np.abs(out - ref).max()):.2e}")
        fns[f"onnxruntime {label}"] = lambda x=x: session.run(None, {"image": x})
        fns[f"torch {label}"] = lambda f=frame: restorer.restore(f)
    with torch.inference_mode():
        ms = blocks(fns, rounds=args.rounds, inner=3)  # both sizes in every round: noise hits all four alike
    for label in SIZES:
        torch_ms = ms[f"torch {label}"]
        rec.add(Figure(f"lite_torch_{label}_ms", f"lite torch restorer, {label}", torch_ms, "ms"))
        ort_ms = ms[f"onnxruntime {label}"]
        title = f"lite one-input ONNX, plain onnxruntime, {label}"
        rec.add(Figure(f"lite_onnxruntime_{label}_ms", title, ort_ms, "ms", "torch restorer", torch_ms))
    print("ratio (x): torch restorer time / onnxruntime time, measured in the same run (>1: onnxruntime faster)")
    print(f"load average (1 min) at the start / end: {load_start:.2f} / {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
