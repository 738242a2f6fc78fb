"""Shared pieces of the live tests: a synthetic clip, a pipeline over it, restorers that are slow or fail, and a
source whose reads the test orders with events (no outcome of a test may depend on the machine's speed)."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np

from murk.enhance.restorer import Restored, Restorer, create
from murk.live.restore_loop import LivePipeline, LiveView
from murk.live.source import LiveFrame, PacedSource, open_live_source, reopener
from testkit.video import make_video


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


class FactsRestorer(Restorer):
    """Leaves the image and reports the water it "estimated" (stands in for the ``water`` method's facts)."""

    name = "facts"

    def restore(self, images: np.ndarray) -> Restored:
        water = {"visibility_m": 12.5, "visibility_measurable": True, "far_distance_m": 8.0, "unmeasured": float("nan")}
        return Restored(images.copy(), facts=tuple(dict(water) for _ in images))


class BuggyRestorer(Restorer):
    """Raises an error that is not one of the restore errors a frame may fail with (a bug in a method)."""

    name = "buggy"

    def restore(self, images: np.ndarray) -> Restored:
        raise KeyError("a bug")


def clip(folder: Path, n: int = 30, fps: float = 30.0, h: int = 48, w: int = 64) -> Path:
    return make_video(folder / "clip.avi", n, fps=fps, h=h, w=w)


def make_restorer(spec: str) -> Restorer:
    if spec == "depth":
        return DepthRestorer()
    if spec == "buggy":
        return BuggyRestorer()
    if spec == "facts":
        return FactsRestorer()
    if spec.startswith("slow"):
        return SlowRestorer(float(spec.partition("?delay=")[2] or 0.05))
    return create(spec, shared={"device": "cpu", "batch": 1})


def pipeline(path: Path, out: Path, method: str = "post", *, loop: bool = False, hooks=None) -> LivePipeline:
    source = PacedSource(open_live_source(str(path)), reopen=reopener(str(path), None), loop=loop)
    return LivePipeline(source, make_restorer, method, out, hooks=hooks)


WAIT_S = 60.0
"""Limit of a wait for something that must happen (only a fault reaches it)."""


class WatchedSource(PacedSource):
    """A paced clip whose reads the test orders: reading frame ``i`` waits for ``hold[i]`` (when given);
    ``ended`` is set when the clip's end is read. With ``lockstep``, frame ``i + 1`` is read only after frame
    ``i`` was restored, recorded and published: pass :meth:`restored` as the pipeline's last hook."""

    def __init__(self, path: Path, *, lockstep: bool = False) -> None:
        super().__init__(open_live_source(str(path)))
        self.hold: dict[int, threading.Event] = {}
        self.ended = threading.Event()
        self._turn = threading.Semaphore(1) if lockstep else None

    def _wait(self, event: threading.Event | threading.Semaphore, what: str) -> bool:
        """Wait for ``event`` (False: stopped meanwhile)."""
        deadline = time.monotonic() + WAIT_S
        while not (event.wait(0.05) if isinstance(event, threading.Event) else event.acquire(timeout=0.05)):
            if self._stop.is_set():
                return False
            if time.monotonic() > deadline:
                raise TimeoutError(f"{what} never came")
        return True

    def read(self) -> LiveFrame | None:
        i = self._index
        if self._turn is not None and not self._wait(self._turn, f"the restoration of frame {i - 1}"):
            return None
        if i in self.hold and not self._wait(self.hold[i], f"the release of frame {i}"):
            return None
        frame = super().read()
        if frame is None:
            self.ended.set()
        return frame

    def restored(self, view: LiveView) -> None:
        if self._turn is not None:
            self._turn.release()


class BurstRestorer(SlowRestorer):
    """Inverts the image; its first call sets ``started`` and waits until ``source`` has delivered everything:
    restoration slower than the source by construction. With ``shown`` (an event a pipeline hook sets when the
    first view is published), the later calls wait for it: the publish thread has taken the first view before a
    newer one is restored, so none is replaced unshown however the threads are scheduled."""

    name = "burst"

    def __init__(self, source: WatchedSource, started: threading.Event, shown: threading.Event | None = None) -> None:
        super().__init__(0.0)
        self.source, self.started, self.shown = source, started, shown
        self.calls = 0

    def restore(self, images: np.ndarray) -> Restored:
        self.calls += 1
        if self.calls == 1:
            self.started.set()
            if not self.source.ended.wait(WAIT_S):
                raise TimeoutError("the source never reached its end")
        elif self.shown is not None and not self.shown.wait(WAIT_S):
            raise TimeoutError("the first view was never shown")
        return super().restore(images)
