"""Fixtures for the enhance tests: a fake depth-estimating method and an MJPEG-over-HTTP camera on localhost."""

from __future__ import annotations

import http.server
import socketserver
import threading
import time
from collections.abc import Callable, Iterator
from typing import ClassVar

import cv2
import numpy as np
import pytest

from murk.enhance import restorer as restorer_mod

from ._enhance_helpers import FakeDepth, make_frames


@pytest.fixture
def fake_depth_method(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, object]]:
    """Registers ``fakedepth`` for the test; returns the list of option dicts its factory received."""
    calls: list[dict[str, object]] = []

    def factory(**options: object) -> FakeDepth:
        calls.append(options)
        return FakeDepth()

    restorer_mod._load_builtin()
    monkeypatch.setitem(restorer_mod._REGISTRY, "fakedepth", factory)
    return calls


class _MJPEGHandler(http.server.BaseHTTPRequestHandler):
    frames: ClassVar[list[np.ndarray]] = []
    delay_s: ClassVar[float] = 0.005

    def do_GET(self) -> None:
        self.send_response(200)
        self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
        self.end_headers()
        try:
            for f in self.frames:
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


@pytest.fixture
def mjpeg_server() -> Iterator[Callable[[list[np.ndarray], float], str]]:
    """Start MJPEG-over-HTTP cameras on localhost: ``start(frames, delay_s) -> url``; each serves its frames to
    a client, then disconnects."""
    servers: list[socketserver.ThreadingTCPServer] = []

    def start(frames: list[np.ndarray], delay_s: float = 0.005) -> str:
        handler = type("H", (_MJPEGHandler,), {"frames": frames, "delay_s": delay_s})
        server = socketserver.ThreadingTCPServer(("127.0.0.1", 0), handler)
        server.daemon_threads = True
        threading.Thread(target=server.serve_forever, daemon=True).start()
        servers.append(server)
        return f"http://127.0.0.1:{server.server_address[1]}/cam.mjpg"

    try:
        yield start
    finally:
        for server in servers:
            server.shutdown()
            server.server_close()


@pytest.fixture
def mjpeg_url(mjpeg_server: Callable[[list[np.ndarray], float], str]) -> str:
    """A camera on localhost streaming 15 MJPEG frames over HTTP, then disconnecting."""
    return mjpeg_server(make_frames(15), 0.005)
