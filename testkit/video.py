"""Video helpers of the tests and benchmarks: synthetic frames, small video files, an MJPEG camera, a clip of the
shipped underwater photographs, and reading a video back."""

from __future__ import annotations

import contextlib
import http.server
import itertools
import socketserver
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar

import cv2
import numpy as np


def make_frames(n: int, h: int = 48, w: int = 64) -> list[np.ndarray]:
    """Smooth uint8 RGB frames; the red level encodes the index (20 + 8 i), robust to lossy codecs."""
    yy, xx = np.mgrid[0:h, 0:w]
    return [
        np.stack([np.full_like(xx, 20 + 8 * i), 60 + xx % 150, 100 + yy % 150], axis=-1).astype(np.uint8)
        for i in range(n)
    ]


def make_video(path: Path, n: int, fps: float = 10.0, h: int = 48, w: int = 64) -> Path:
    """Write ``make_frames(n)`` as MJPEG (.avi) or mp4v (other suffixes) with OpenCV."""
    fourcc = cv2.VideoWriter_fourcc(*("MJPG" if path.suffix == ".avi" else "mp4v"))
    writer = cv2.VideoWriter(str(path), fourcc, fps, (w, h))
    for f in make_frames(n, h, w):
        writer.write(np.ascontiguousarray(f[:, :, ::-1]))
    writer.release()
    return path


def underwater_clip(path: Path, n: int = 90, fps: float = 30.0, w: int = 640, h: int = 480) -> Path:
    """An MJPEG clip of the shipped underwater samples panning slowly (real image content), ``n`` frames."""
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


def read_video(path: Path) -> list[np.ndarray]:
    """Every frame of a video file as uint8 RGB."""
    cap = cv2.VideoCapture(str(path))
    out = []
    while True:
        ok, bgr = cap.read()
        if not ok:
            break
        out.append(np.ascontiguousarray(bgr[:, :, ::-1]))
    cap.release()
    return out


class _MJPEGHandler(http.server.BaseHTTPRequestHandler):
    frames: ClassVar[list[np.ndarray]] = []
    delay_s: ClassVar[float] = 0.005
    loop: ClassVar[bool] = False

    def do_GET(self) -> None:
        self.send_response(200)
        self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
        self.end_headers()
        try:
            for f in itertools.cycle(self.frames) if self.loop else self.frames:
                _, buf = cv2.imencode(".jpg", np.ascontiguousarray(f[:, :, ::-1]))
                b = buf.tobytes()
                head = b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n" % len(b)
                self.wfile.write(head + b + b"\r\n")
                self.wfile.flush()
                time.sleep(self.delay_s)
        except (BrokenPipeError, ConnectionResetError):
            pass  # the client went away
        # returning closes the connection: the camera "disconnects"

    def log_message(self, *args: object) -> None:
        pass


@contextlib.contextmanager
def mjpeg_camera(frames: list[np.ndarray], delay_s: float = 0.005, *, loop: bool = False) -> Iterator[str]:
    """An MJPEG-over-HTTP camera on localhost: yields its URL; it serves ``frames`` to a client, then disconnects
    (with ``loop``: serves them over and over until the client goes away)."""
    handler = type("H", (_MJPEGHandler,), {"frames": frames, "delay_s": delay_s, "loop": loop})
    with serve_http(handler) as url:
        yield url


@contextlib.contextmanager
def serve_http(handler: type[http.server.BaseHTTPRequestHandler], path: str = "/cam.mjpg") -> Iterator[str]:
    """Serve ``handler`` on a free localhost port in a daemon thread; yields the URL of ``path`` and stops the server
    on exit."""
    server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), handler)
    server.daemon_threads = True
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}{path}"
    finally:
        server.shutdown()
        server.server_close()
