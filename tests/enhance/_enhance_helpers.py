"""Helpers shared by the enhance tests: frames, small videos, a scripted frame source, a fake depth method."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from murk.enhance.restorer import Restored, Restorer
from murk.io.video import Frame, FrameSource


def make_frames(n: int, h: int = 48, w: int = 64) -> list[np.ndarray]:
    """Smooth uint8 RGB frames; the red level encodes the index (20 + 8 i), robust to lossy codecs."""
    yy, xx = np.mgrid[0:h, 0:w]
    return [
        np.stack([np.full_like(xx, 20 + 8 * i), 60 + xx % 150, 100 + yy % 150], axis=-1).astype(np.uint8)
        for i in range(n)
    ]


def make_video(path: Path, n: int, fps: float = 10.0, h: int = 48, w: int = 64) -> Path:
    fourcc = cv2.VideoWriter_fourcc(*("MJPG" if path.suffix == ".avi" else "mp4v"))
    writer = cv2.VideoWriter(str(path), fourcc, fps, (w, h))
    for f in make_frames(n, h, w):
        writer.write(np.ascontiguousarray(f[:, :, ::-1]))
    writer.release()
    return path


def read_video(path: Path) -> list[np.ndarray]:
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        out.append(np.ascontiguousarray(bgr[:, :, ::-1]))
    cap.release()
    return out


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
