"""Shared helpers of the benchmark scripts: one-core pinning, side-by-side timing, and the figures (value + the
baseline measured in the same run) that the scripts print and ``gpu_suite.py`` records."""

from __future__ import annotations

import itertools
import math
import os
import platform
import statistics
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any, TypeVar

T = TypeVar("T")

ONE_CORE_ENV = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS", "NUMEXPR_NUM_THREADS")


def tree_envs(before_src: Any, *, warm: str) -> dict[str, dict[str, str]]:
    """The environments of the trees a CLI benchmark compares: ``now`` (this tree) and, with ``before_src`` (the
    ``src/`` folder of an earlier murk), ``before`` first. ``MURK_DEBUG`` is dropped; each tree imports ``warm``
    once so that its .pyc files are compiled before any timed run."""
    import subprocess
    import sys
    from pathlib import Path

    env = dict(os.environ)
    env.pop("MURK_DEBUG", None)
    trees = {"now": env}
    if before_src is not None:
        trees = {"before": {**env, "PYTHONPATH": str(Path(before_src).resolve())}, "now": env}
    for tree_env in trees.values():
        subprocess.run([sys.executable, "-c", f"import {warm}"], check=True, env=tree_env)
    return trees


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


# ---------------------------------------------------------------------------------------------------------------
# Figures: what the scripts print and what gpu_suite.py records, measured by the same functions.


def median_s(
    fn: Callable[[], object], *, repeats: int, warmup: int = 1, sync: Callable[[], None] | None = None
) -> float:
    """Median seconds per call of ``fn`` over ``repeats`` calls after ``warmup`` calls; ``sync`` (e.g.
    ``torch.cuda.synchronize``) runs after every call, so device work is inside the timing."""
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


def device_sync(device: object) -> Callable[[], None] | None:
    """``torch.cuda.synchronize`` for a CUDA device, None for the CPU."""
    import torch

    dev = torch.device(device)  # type: ignore[arg-type]
    return (lambda: torch.cuda.synchronize(dev)) if dev.type == "cuda" else None


@dataclass
class Figure:
    """One measured figure with the baseline measured in the same run (units: ``ms``, ``ms/image``, ``img/s``,
    ``frames/s``, ``variants/s``, ``scenes/s``, ``GiB``, ``dB``, ``m``, ``%``)."""

    key: str
    label: str
    value: float
    unit: str
    baseline: str | None = None
    baseline_value: float | None = None
    target: str | None = None

    @property
    def ratio(self) -> float | None:
        """How many times better than the baseline (>1: faster): rate / rate, or time / time inverted."""
        if not self.baseline_value or not self.value:
            return None
        if self.unit.endswith("/s"):
            return self.value / self.baseline_value
        if self.unit.startswith("ms") or self.unit == "s":
            return self.baseline_value / self.value
        return None

    def to_dict(self) -> dict[str, Any]:
        return {**asdict(self), "ratio": self.ratio}

    def __str__(self) -> str:
        s = f"{self.label}: {_fmt(self.value)} {self.unit}"
        if self.baseline is not None and self.baseline_value is not None:
            ratio = f", x{self.ratio:.2f}" if self.ratio is not None else ""
            s += f"  (baseline {self.baseline}: {_fmt(self.baseline_value)} {self.unit}{ratio})"
        return s + (f"  [target {self.target}]" if self.target else "")


def _fmt(v: float) -> str:
    return f"{v:,.0f}" if abs(v) >= 1000 else f"{v:.3g}" if abs(v) < 10 else f"{v:.1f}"


class Recorder:
    """Collects figures as they are measured. The scripts print them (``echo``); ``gpu_suite.py`` saves them after
    each one (``on_change``), so a part killed at its budget keeps what it had measured.

    :meth:`attempt` runs one measurement: a failure is recorded (and the rest goes on) instead of raised, and a
    measurement that needs more than the time left before ``deadline`` (``time.monotonic()``) is skipped; its wall
    seconds go to ``attempt_s`` (label -> seconds: where a part's time went)."""

    def __init__(
        self,
        *,
        deadline: float | None = None,
        echo: bool = False,
        on_change: Callable[[Recorder], None] | None = None,
    ) -> None:
        self.deadline = deadline
        self.echo = echo
        self.on_change = on_change
        self.figures: list[Figure] = []
        self.problems: list[dict[str, str]] = []
        self.notes: list[str] = []
        self.attempt_s: dict[str, float] = {}

    def left_s(self) -> float:
        return math.inf if self.deadline is None else self.deadline - time.monotonic()

    def _changed(self) -> None:
        if self.on_change:
            self.on_change(self)

    def add(self, fig: Figure) -> Figure:
        if not math.isfinite(fig.value):
            raise ValueError(f"{fig.label}: expected a finite figure, got {fig.value}")
        self.figures.append(fig)
        if self.echo:
            print(fig, flush=True)
        self._changed()
        return fig

    def note(self, text: str) -> None:
        self.notes.append(text)
        if self.echo:
            print(f"note: {text}", flush=True)
        self._changed()

    def problem(self, label: str, kind: str, why: str) -> None:
        """Record a measurement that did not happen: ``kind`` is ``failed``, ``budget`` or ``skipped`` (it cannot
        happen here: :meth:`skip`)."""
        self.problems.append({"label": label, "kind": kind, "why": why})
        if self.echo:
            print(f"{label}: {kind.upper()} ({why})", flush=True)
        self._changed()

    def skip(self, label: str, why: str) -> None:
        """Record a measurement that cannot happen on this machine (a CUDA graph without CUDA) and why."""
        if not why.strip():
            raise ValueError(f"{label}: expected the reason of the skip, got {why!r}")
        self.problem(label, "skipped", why)

    def attempt(self, label: str, fn: Callable[[], T], *, need_s: float = 0.0) -> T | None:
        """``fn()``, or None when it raised (recorded as failed) or needs more than the time left (recorded)."""
        left = self.left_s()
        if left < need_s:
            self.problem(label, "budget", f"{left:.0f} s left of the part's budget, needs about {need_s:.0f} s")
            return None
        t0 = time.perf_counter()
        try:
            return fn()
        except Exception as exc:  # one failing configuration must not hide the others
            first = (str(exc).strip().splitlines() or [""])[0][:300]
            self.problem(label, "failed", f"{type(exc).__name__}: {first}")
            _release_device_memory()
            return None
        finally:
            self.attempt_s[label] = round(time.perf_counter() - t0, 3)


def _release_device_memory() -> None:
    import gc

    gc.collect()
    try:
        import torch

        if torch.cuda.is_available() and torch.cuda.is_initialized():
            torch.cuda.empty_cache()
    except Exception:  # a broken CUDA context: the next measurement reports it
        pass
