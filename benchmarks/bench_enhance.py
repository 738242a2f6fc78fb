"""Frames per second of the ``post`` method (Eq. 9) and of the ``murk enhance`` video pipeline.

Run: PYTHONPATH=src python benchmarks/bench_enhance.py [--seconds 2]

CPU figures use ONE core (cv2.setNumThreads(1), torch.set_num_threads(1)). The baseline, measured in the same
run, is the plain OpenCV recipe a user would write for Eq. (9): uint8 RGB -> YCrCb, cv2.equalizeHist on Y, back
to RGB, then a float LoG as GaussianBlur(sigma 1) + Laplacian and the subtraction. murk's path adds the exact
float definition (16-bit safe, torch-twinned); the ratio says what that costs. Each size is measured twice:
interleaved (the functions called in turn) and each alone in its own loop. With CUDA, the torch twin runs
batched on the GPU (tensor already on the device, and end to end from numpy through pinned memory), compared
with the one-core OpenCV path.
"""

from __future__ import annotations

import argparse
import platform
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
from _common import Figure, Recorder

from murk.data import sample_underwater_images
from murk.enhance.api import OutputOptions, enhance_frames
from murk.enhance.api import restore_batch as _restore
from murk.enhance.post import PostRestorer, post_process, post_process_torch
from murk.io import read_rgb
from murk.io.video import CaptureSource

SIZES = {"1920x1080": (1080, 1920), "640x480": (480, 640)}


def call_times_s(
    fn: Callable[[], object],
    seconds: float,
    *,
    clock: Callable[[], float] = time.perf_counter,
    sync: Callable[[], None] = lambda: None,
    min_calls: int = 5,
) -> list[float]:
    """Seconds (by ``clock``) of each of repeated calls lasting about ``seconds`` in all, after two warm-up calls."""
    fn()
    fn()
    sync()
    times: list[float] = []
    start = time.perf_counter()
    while time.perf_counter() - start < seconds or len(times) < min_calls:
        t0 = clock()
        fn()
        sync()
        times.append(clock() - t0)
    return times


def per_call_s(fn: Callable[[], object], seconds: float, sync: Callable[[], None] = lambda: None) -> float:
    """Median wall seconds per call (:func:`call_times_s`)."""
    return statistics.median(call_times_s(fn, seconds, sync=sync))


def opencv_recipe(rgb_u8: np.ndarray, sigma_px: float = 1.0, lam: float = 0.3) -> np.ndarray:
    """The baseline: what one writes with OpenCV directly (8-bit equalisation, float LoG)."""
    ycc = cv2.cvtColor(rgb_u8, cv2.COLOR_RGB2YCrCb)
    ycc[:, :, 0] = cv2.equalizeHist(ycc[:, :, 0])
    he = cv2.cvtColor(ycc, cv2.COLOR_YCrCb2RGB).astype(np.float32) / 255.0
    log = cv2.Laplacian(cv2.GaussianBlur(he, (0, 0), sigma_px), cv2.CV_32F)
    return np.clip(he - lam * log, 0.0, 1.0)


def sample_frame(h: int, w: int) -> np.ndarray:
    src = read_rgb(sample_underwater_images()[0])
    return np.ascontiguousarray(cv2.resize(src, (w, h), interpolation=cv2.INTER_CUBIC).clip(0, 1))


def interleaved_s(fns: dict[str, Callable[[], object]], seconds: float) -> dict[str, tuple[float, float]]:
    """(fastest, median) CPU seconds of this thread per call for each function, the functions called in
    turn so that every one sees the same machine load; thread CPU time leaves out time spent descheduled."""
    for fn in fns.values():
        fn()
    times: dict[str, list[float]] = {k: [] for k in fns}
    start = time.perf_counter()
    while time.perf_counter() - start < seconds * len(fns) or min(len(v) for v in times.values()) < 10:
        for k, fn in fns.items():
            t0 = time.thread_time()
            fn()
            times[k].append(time.thread_time() - t0)
    return {k: (min(v), statistics.median(v)) for k, v in times.items()}


def alone_s(fn: Callable[[], object], seconds: float) -> tuple[float, float]:
    """(fastest, median) CPU seconds of this thread per call with ``fn`` called alone in its own loop, as a
    per-frame loop calls it (in :func:`interleaved_s` the functions' temporary arrays share the allocator's
    freed memory)."""
    times = call_times_s(fn, seconds, clock=time.thread_time, min_calls=10)
    return min(times), statistics.median(times)


def bench_cpu(seconds: float) -> None:
    cv2.setNumThreads(1)
    torch.set_num_threads(1)
    print("== CPU, one core: frames/s of one image at a time (fastest call; median in brackets)")
    print(f"{'size':>10} {'opencv recipe':>18} {'murk post (y)':>18} {'ratio':>6} {'post rgb':>9} {'post clahe':>11}"
          f" {'torch twin':>11}")  # fmt: skip
    for label, (h, w) in SIZES.items():
        img = sample_frame(h, w)
        u8 = (img * 255 + 0.5).astype(np.uint8)
        t = torch.from_numpy(img).permute(2, 0, 1)[None].contiguous()
        r = interleaved_s(
            {
                "recipe": lambda u8=u8: opencv_recipe(u8),
                "y": lambda img=img: post_process(img),
                "rgb": lambda img=img: post_process(img, he="rgb"),
                "clahe": lambda img=img: post_process(img, he="clahe"),
                "twin": lambda t=t: post_process_torch(t),
            },
            seconds,
        )
        fps = {k: (1 / v[0], 1 / v[1]) for k, v in r.items()}
        print(
            f"{label:>10} {fps['recipe'][0]:8.1f} ({fps['recipe'][1]:6.1f}) {fps['y'][0]:8.1f} ({fps['y'][1]:6.1f})"
            f" {r['recipe'][0] / r['y'][0]:6.2f} {fps['rgb'][0]:9.1f} {fps['clahe'][0]:11.1f} {fps['twin'][0]:11.1f}"
            "   (interleaved)"
        )
        alone = {
            "recipe": alone_s(lambda u8=u8: opencv_recipe(u8), seconds),
            "y": alone_s(lambda img=img: post_process(img), seconds),
        }
        fa = {k: (1 / v[0], 1 / v[1]) for k, v in alone.items()}
        print(
            f"{label:>10} {fa['recipe'][0]:8.1f} ({fa['recipe'][1]:6.1f}) {fa['y'][0]:8.1f} ({fa['y'][1]:6.1f})"
            f" {alone['recipe'][0] / alone['y'][0]:6.2f}   (each alone in its loop)"
        )


def gpu_figures(
    rec: Recorder,
    device: str | torch.device,
    *,
    sizes: dict[str, tuple[int, int]] = SIZES,
    batches: tuple[int, ...] = (1, 8, 32),
    seconds: float = 1.0,
) -> None:
    """Frames/s of ``post_process_torch`` on ``device`` (tensor already there, and end to end from numpy through
    pinned memory), against ``post_process`` on one CPU core in the same run."""
    dev = torch.device(device)
    sync = torch.cuda.synchronize if dev.type == "cuda" else (lambda: None)
    cv2.setNumThreads(1)
    restorer = PostRestorer(device=dev)
    for label, (h, w) in sizes.items():
        img = sample_frame(h, w)
        cpu = per_call_s(lambda img=img: post_process(img), min(seconds, 1.0))
        base = f"post_process numpy/OpenCV, 1 core, {label}"
        rec.add(Figure(f"cpu_{label}_fps", base, 1 / cpu, "frames/s"))
        for batch in batches:
            x_np = np.ascontiguousarray(np.broadcast_to(img, (batch, h, w, 3)))
            x = torch.from_numpy(x_np).permute(0, 3, 1, 2).contiguous().to(dev)
            on_dev = rec.attempt(
                f"post_process_torch {label} batch {batch}",
                lambda x=x: per_call_s(lambda: post_process_torch(x), seconds, sync),
            )
            if on_dev is not None:
                name = f"post_process_torch {dev.type}, {label}, batch {batch}, on device"
                rec.add(Figure(f"torch_{label}_b{batch}_fps", name, batch / on_dev, "frames/s", base, 1 / cpu))
            e2e = rec.attempt(
                f"post restorer {label} batch {batch} from numpy",
                lambda x_np=x_np: per_call_s(lambda: _restore(restorer, x_np), seconds, sync),
            )
            if e2e is not None:
                name = f"post restorer {dev.type}, {label}, batch {batch}, numpy in and out"
                rec.add(Figure(f"e2e_{label}_b{batch}_fps", name, batch / e2e, "frames/s", base, 1 / cpu))


def bench_gpu(seconds: float) -> None:
    if not torch.cuda.is_available():
        print("== GPU: not measured (torch.cuda.is_available() is False on this machine)")
        return
    print(f"== GPU ({torch.cuda.get_device_name()}): frames/s of post_process_torch, batched, float32")
    gpu_figures(Recorder(echo=True), "cuda", seconds=seconds)


def bench_pipeline(seconds: float) -> None:
    cv2.setNumThreads(1)
    torch.set_num_threads(1)
    print("== murk enhance pipeline, one core: 640x480 MJPEG .avi in -> .avi out (decode, post, encode)")
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "in.avi"
        frame = (sample_frame(480, 640) * 255 + 0.5).astype(np.uint8)[:, :, ::-1]
        writer = cv2.VideoWriter(str(src), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (640, 480))
        n = max(30, int(25 * seconds))
        for i in range(n):
            writer.write(np.roll(frame, 4 * i, axis=1))
        writer.release()
        with CaptureSource(src) as source:
            report = enhance_frames(source, PostRestorer(), Path(tmp) / "out.avi", OutputOptions(overwrite=True))
        ms = report.stage_ms()
        print(
            f"{report.processed} frames: {report.fps:.1f} frames/s; per frame: read {ms['read']:.1f} ms, "
            f"restore {ms['restore']:.1f} ms, write {ms['write']:.1f} ms"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="time spent per measurement")
    args = parser.parse_args()
    print(
        f"python {platform.python_version()}, torch {torch.__version__}, OpenCV {cv2.__version__}, "
        f"numpy {np.__version__}, {platform.machine()}"
    )
    bench_cpu(args.seconds)
    bench_pipeline(args.seconds)
    bench_gpu(args.seconds)


if __name__ == "__main__":
    main()
