"""Shared pieces of the live tests: a synthetic clip, a pipeline over it, restorers that are slow or fail."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from murk.enhance.restorer import Restored, Restorer, create
from murk.live.pipeline import LivePipeline
from murk.live.source import PacedSource, open_live_source, reopener
from tests._video import make_video


class SlowRestorer(Restorer):
    """Inverts the image after ``delay_s`` (slower than the source: frames must be dropped, never queued)."""

    name = "slow"

    def __init__(self, delay_s: float) -> None:
        self.delay_s = delay_s

    def restore(self, images: np.ndarray) -> Restored:
        time.sleep(self.delay_s)
        return Restored(1.0 - images)


class DepthRestorer(Restorer):
    """Leaves the image and estimates a constant 3 m depth (stands in for a method that estimates depth)."""

    name = "depth"

    def restore(self, images: np.ndarray) -> Restored:
        return Restored(images.copy(), np.full(images.shape[:3], 3.0, np.float32))


class BuggyRestorer(Restorer):
    """Raises an error that is not one of the restore errors a frame may fail with (a bug in a method)."""

    name = "buggy"

    def restore(self, images: np.ndarray) -> Restored:
        raise KeyError("a bug")


def clip(folder: Path, n: int = 30, fps: float = 30.0, h: int = 48, w: int = 64) -> Path:
    return make_video(folder / "clip.avi", n, fps=fps, h=h, w=w)


def underwater_clip(path: Path, n: int = 90, fps: float = 30.0, w: int = 640, h: int = 480) -> Path:
    """An MJPEG clip of the shipped underwater samples panning slowly (real image content), ``n`` frames."""
    import cv2

    from murk.data import sample_underwater_images
    from murk.io import read_rgb

    base = [
        cv2.resize((read_rgb(p) * 255 + 0.5).astype(np.uint8)[:, :, ::-1], (w + 64, h), interpolation=cv2.INTER_AREA)
        for p in sample_underwater_images()[:3]
    ]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (w, h))
    for i in range(n):
        writer.write(np.ascontiguousarray(base[(i // 60) % len(base)][:, (i % 64) : (i % 64) + w]))
    writer.release()
    return path


def make_restorer(spec: str) -> Restorer:
    if spec == "depth":
        return DepthRestorer()
    if spec == "buggy":
        return BuggyRestorer()
    if spec.startswith("slow"):
        return SlowRestorer(float(spec.partition("?delay=")[2] or 0.05))
    return create(spec, shared={"device": "cpu", "batch": 1})


def pipeline(path: Path, out: Path, method: str = "post", *, loop: bool = False, hooks=None) -> LivePipeline:
    source = PacedSource(open_live_source(str(path)), reopen=reopener(str(path), None), loop=loop)
    return LivePipeline(source, make_restorer, method, out, hooks=hooks)
