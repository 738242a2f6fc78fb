"""``murk live`` restores a light method (``lite``, ``post`` and chains of them) with one torch and OpenCV thread per
call, beside the capture and publish threads (issue 48, point 5); other methods keep the process's threads, and the
previous settings come back when the method changes and when the pipeline stops."""

from __future__ import annotations

import threading
from pathlib import Path

import cv2
import numpy as np
import torch

from murk.enhance.frame_overlap import one_thread_suits
from murk.enhance.post import PostRestorer
from murk.enhance.restorer import Restored, Restorer, create
from murk.live.restore_loop import LivePipeline
from murk.live.source import PacedSource, open_live_source, reopener
from tests.live._live import WAIT_S, clip


class _Counting:
    """Records the torch and OpenCV thread counts each restoration of a frame ran with."""

    def __init__(self) -> None:
        self.seen: list[tuple[int, int]] = []
        self.lock = threading.Lock()

    def note(self) -> None:
        with self.lock:
            self.seen.append((torch.get_num_threads(), cv2.getNumThreads()))


class _LightPost(PostRestorer):
    """``post`` (a light method) that records its thread counts."""

    def __init__(self, counts: _Counting) -> None:
        super().__init__()
        self.counts = counts

    def restore(self, images: np.ndarray) -> Restored:
        self.counts.note()
        return super().restore(images)


class _Heavy(Restorer):
    """Stands in for a heavy network (not declared reentrant): inverts, records its thread counts."""

    name = "heavy"

    def __init__(self, counts: _Counting) -> None:
        self.counts = counts

    def restore(self, images: np.ndarray) -> Restored:
        self.counts.note()
        return Restored(1.0 - images)


def test_light_methods_run_on_one_thread_and_others_keep_the_process_threads(tmp_path: Path) -> None:
    saved = torch.get_num_threads(), cv2.getNumThreads()
    torch.set_num_threads(2)  # the process's threads, whatever the machine (a 1-core runner defaults to 1)
    cv2.setNumThreads(2)
    try:
        _switch_and_count(tmp_path)
    finally:
        torch.set_num_threads(saved[0])
        cv2.setNumThreads(saved[1])


def _switch_and_count(tmp_path: Path) -> None:
    torch_before, cv_before = torch.get_num_threads(), cv2.getNumThreads()
    assert (torch_before, cv_before) == (2, 2)
    light, heavy = _Counting(), _Counting()
    make = {"post": lambda: _LightPost(light), "heavy": lambda: _Heavy(heavy)}
    path = clip(tmp_path, n=20, fps=30.0)
    source = PacedSource(open_live_source(str(path)), reopen=reopener(str(path), None), loop=True)
    p = LivePipeline(source, lambda spec: make[spec](), "post", tmp_path / "out").start()
    try:
        view = p.wait_view(-1, WAIT_S)
        assert view is not None, p.status()
        p.set_method("heavy")
        while view is not None and view.method != "heavy":  # views restored before the switch may still come
            view = p.wait_view(view.index, WAIT_S)
        assert view is not None, p.status()
        view = p.wait_view(view.index, WAIT_S)  # one more of the heavy method
        assert view is not None, p.status()
    finally:
        p.stop()
    assert light.seen and set(light.seen) == {(1, 1)}
    assert heavy.seen and set(heavy.seen) == {(torch_before, cv_before)}
    assert (torch.get_num_threads(), cv2.getNumThreads()) == (torch_before, cv_before)


def test_which_methods_one_thread_suits() -> None:
    assert one_thread_suits(create("lite")) and one_thread_suits(create("lite+post?temporal=0.8"))
    assert one_thread_suits(PostRestorer())
    assert not one_thread_suits(_Heavy(_Counting()))
