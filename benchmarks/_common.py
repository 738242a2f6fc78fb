"""Shared helpers of the benchmark scripts: one-core pinning and side-by-side timing."""

from __future__ import annotations

import itertools
import os
import platform
import statistics
import time
from collections.abc import Callable

ONE_CORE_ENV = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS")


def pin_one_core() -> None:
    """Restrict numpy/OpenCV/torch to one thread, and tune the allocator as the murk command line does
    (see murk/_perf.py)."""
    from murk._perf import tune_allocator

    tune_allocator()
    for k in ONE_CORE_ENV:
        os.environ[k] = "1"
    import cv2
    import torch

    cv2.setNumThreads(1)
    torch.set_num_threads(1)


def interleaved(fns: dict[str, Callable[[], object]], *, rounds: int = 7, inner: int = 3) -> dict[str, float]:
    """Median milliseconds per call of each function, measured in alternating rounds (noise hits all equally)."""
    for f in fns.values():
        f()  # warm-up
    samples: dict[str, list[float]] = {k: [] for k in fns}
    for _ in range(rounds):
        for k, f in fns.items():
            t0 = time.perf_counter()
            for _ in range(inner):
                f()
            samples[k].append((time.perf_counter() - t0) / inner * 1e3)
    return {k: statistics.median(v) for k, v in samples.items()}


def cycler(items: list) -> Callable[[], object]:
    """A function returning the items of ``items`` in turn (so repeated timings see varied parameters)."""
    it = itertools.cycle(items)
    return lambda: next(it)


def machine() -> str:
    import cv2
    import numpy as np
    import torch

    return (
        f"{platform.machine()} {os.cpu_count()} cpus, Python {platform.python_version()}, numpy {np.__version__}, "
        f"OpenCV {cv2.__version__}, torch {torch.__version__}"
    )
