"""Helpers shared by the enhance tests: frames, small videos, a scripted frame source, a fake depth method."""

from __future__ import annotations

import numpy as np

from murk.enhance.restorer import Restored, Restorer
from murk.io.video import Frame, FrameSource
from testkit.video import make_frames, make_video, read_video

__all__ = ["FakeDepth", "FakeSource", "make_frames", "make_video", "read_video"]


class FakeSource(FrameSource):
    """A scripted frame source: ``broken`` indices come without an image; a live one disconnects after its
    frames (like a camera unplugged mid-recording)."""

    def __init__(
        self, frames: list[np.ndarray], *, live: bool, broken: tuple[int, ...] = (), fps: float | None = 10.0
    ) -> None:
        self.frames, self.live, self.broken, self.fps = frames, live, broken, fps
        self.frame_count = None if live else len(frames)
        self.name = "fake"
        self.label = "fake://source"
        self.closed = False
        self._i = 0

    def read(self) -> Frame | None:
        if self._i >= len(self.frames):
            self.end_reason = "disconnected or ended" if self.live else "end"
            return None
        i = self._i
        self._i += 1
        if i in self.broken:
            return Frame(i, None, "frame could not be decoded")
        return Frame(i, self.frames[i].copy())

    def close(self) -> None:
        self.closed = True


class FakeDepth(Restorer):
    """Returns the images unchanged (times ``gain``) and a depth map: 1 m at the top row to 4 m at the bottom."""

    name = "fakedepth"

    def __init__(self, gain: float = 1.0) -> None:
        self.gain = gain

    def restore(self, images: np.ndarray) -> Restored:
        b, h, w, _ = images.shape
        depth = np.broadcast_to(np.linspace(1.0, 4.0, h, dtype=np.float32)[:, None], (h, w))
        return Restored(np.clip(images * self.gain, 0, 1), np.ascontiguousarray(np.broadcast_to(depth, (b, h, w))))
