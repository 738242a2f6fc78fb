"""The live server against hostile or broken clients (issue 49, point 5; found by benchmarks/soak_live.py): a request
head that trickles in is closed at its deadline, the connections served at once are bounded, a client's reset is
no traceback, a deeply nested JSON body is a 400, and a recording stopped by a full disk is said in the terminal and
the status. No outcome depends on the machine's speed: the deadline runs on a clock the test moves, and every wait
is for something that must happen (bounded by ``WAIT_S``, which only a fault reaches)."""

from __future__ import annotations

import errno
import http.client
import json
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from murk.live import outputs
from murk.live.restore_loop import LivePipeline
from murk.live.run import LiveOptions, run_live
from murk.live.server import LiveServer
from tests.live._live import WAIT_S, clip, pipeline

DEADLINE_S = 600.0
"""The request deadline of the tests, on their clock (long in real time: a read never times out for real)."""


class Clock:
    """A clock that moves only when the test says so."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def live(tmp_path: Path) -> Iterator[LivePipeline]:
    p = pipeline(clip(tmp_path, n=20, fps=30.0), tmp_path / "out", "post", loop=True).start()
    try:
        assert p.wait_view(-1, WAIT_S) is not None, p.status()
        yield p
    finally:
        p.stop()


def serve(p: LivePipeline, **kwargs) -> LiveServer:
    return LiveServer(p, "127.0.0.1", 0, **kwargs).start()


def connect(server: LiveServer) -> socket.socket:
    return socket.create_connection(("127.0.0.1", server.server_port), timeout=WAIT_S)


def read_all(s: socket.socket) -> bytes:
    """Everything the server sends until it closes the connection."""
    data = b""
    while chunk := s.recv(65536):
        data += chunk
    return data


def until(condition, what: str) -> None:
    deadline = time.monotonic() + WAIT_S
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} never happened")
        time.sleep(0.01)


def get_status(s: socket.socket) -> int:
    """One keep-alive ``GET /api/status`` on ``s``: its status code."""
    s.sendall(b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
    r = http.client.HTTPResponse(s)
    r.begin()
    r.read()
    return r.status


def test_a_trickling_request_head_is_closed_at_its_deadline(live) -> None:
    clock = Clock()
    server = serve(live, request_deadline_s=DEADLINE_S, clock=clock)
    try:
        s = connect(server)
        s.sendall(b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # a head that never ends
        s.sendall(b"X")  # more of it: read before the deadline, so the connection is still served
        until(lambda: server.connections == 1, "the connection being served")
        clock.now += DEADLINE_S  # the deadline passes; the next byte is read, and then no more
        s.sendall(b"-a: b\r\n")
        assert read_all(s) == b""  # closed without an answer
        until(lambda: server.connections == 0, "the connection's end")
        # a request that arrives in time is answered, on the same clock
        with connect(server) as ok:
            assert get_status(ok) == 200
            clock.now += DEADLINE_S - 1  # a keep-alive connection: each request has its own deadline
            assert get_status(ok) == 200
    finally:
        server.stop()


def test_a_body_slower_than_the_deadline_is_closed(live) -> None:
    clock = Clock()
    server = serve(live, request_deadline_s=DEADLINE_S, clock=clock)
    try:
        s = connect(server)
        head = b"POST /api/record HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
        s.sendall(head + b"Content-Length: 20\r\n\r\n{")
        until(lambda: server.connections == 1, "the connection being served")
        clock.now += DEADLINE_S + 1
        s.sendall(b'"on"')
        assert read_all(s) == b""
        assert server.pipeline.status()["recording"] is None
    finally:
        server.stop()


def test_connections_beyond_the_cap_are_answered_503_and_served_again_when_one_ends(live) -> None:
    server = serve(live, max_connections=2)
    try:
        a, b = connect(server), connect(server)
        assert get_status(a) == 200 and get_status(b) == 200  # both served, both held (keep-alive)
        assert server.connections == 2
        with connect(server) as c:  # one more: answered at once, without a thread
            answer = read_all(c)
        assert answer.startswith(b"HTTP/1.1 503 ") and b"Retry-After: 1" in answer
        assert "try again" in json.loads(answer.split(b"\r\n\r\n", 1)[1])["error"]
        assert server.refused == 1 and server.connections == 2
        assert get_status(a) == 200  # the connections served go on
        a.close()
        until(lambda: server.connections == 1, "the closed connection's end")
        with connect(server) as d:
            assert get_status(d) == 200
        b.close()
    finally:
        server.stop()
    with pytest.raises(ValueError, match="max_connections"):
        LiveServer(live, "127.0.0.1", 0, max_connections=0)


def test_a_client_reset_prints_no_traceback_but_a_bug_does(live, capsys) -> None:
    server = serve(live)
    try:
        for _ in range(3):  # a reset before the request line is complete (the soak's vanishing viewers)
            s = connect(server)
            s.sendall(b"GET /api/fr")
            until(lambda: server.connections == 1, "the connection being served")
            s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
            s.close()  # RST
            until(lambda: server.connections == 0, "the reset connection's end")
        for exc in (ConnectionResetError(104, "reset"), BrokenPipeError(32, "pipe"), TimeoutError("slow")):
            try:
                raise exc
            except OSError:
                server.handle_error(None, ("127.0.0.1", 1))
        assert capsys.readouterr().err == ""
        try:
            raise KeyError("a bug")
        except KeyError:
            server.handle_error(None, ("127.0.0.1", 1))
        assert "KeyError: 'a bug'" in capsys.readouterr().err
    finally:
        server.stop()


def test_a_deeply_nested_json_body_is_a_400(live) -> None:
    server = serve(live)
    try:
        conn = http.client.HTTPConnection("127.0.0.1", server.server_port, timeout=WAIT_S)
        conn.request("POST", "/api/method", body=b"[" * 5000, headers={"Content-Type": "application/json"})
        r = conn.getresponse()
        body = json.loads(r.read())
        conn.close()
        assert r.status == 400 and "nested too deeply" in body["error"]
    finally:
        server.stop()


def full_disk(monkeypatch, writes: int = 2) -> None:
    """The recorder's writes fail with ENOSPC after ``writes`` frames."""
    written = {"n": 0}
    write = outputs.Recorder.write

    def write_until_full(self, index, image) -> None:
        if written["n"] >= writes:
            raise OSError(errno.ENOSPC, "No space left on device")
        written["n"] += 1
        write(self, index, image)

    monkeypatch.setattr(outputs.Recorder, "write", write_until_full)


def test_a_recording_stopped_by_a_full_disk_is_in_the_status_and_the_view_goes_on(live, monkeypatch) -> None:
    full_disk(monkeypatch)
    path = live.set_recording(True)
    until(lambda: live.recordings, "the recording's stop (its file finished)")
    state = live.status()
    assert state["recording"] is None
    assert "No space left on device" in state["recording_stopped"] and live.recording_stops == 1
    assert live.recordings == [path] and path.is_file()  # what was written is kept
    seen = live.latest().index
    assert live.wait_view(seen, WAIT_S) is not None and live.ended is None  # the view goes on
    monkeypatch.undo()
    live.set_recording(True)  # a new recording: the old reason is gone
    assert live.status()["recording_stopped"] is None
    live.set_recording(False)


def test_run_live_prints_why_a_recording_stopped(tmp_path: Path, monkeypatch) -> None:
    full_disk(monkeypatch)
    lines: list[str] = []
    said = threading.Event()
    deadline = time.monotonic() + WAIT_S

    def on_event(text: str) -> None:
        lines.append(text)
        if text.startswith("recording stopped:"):
            said.set()

    options = LiveOptions(
        str(clip(tmp_path, n=20, fps=30.0)), method="post", port=0, out_dir=tmp_path / "out", loop=True, record=True
    )
    report = run_live(options, on_event=on_event, should_stop=lambda: said.is_set() or time.monotonic() > deadline)
    assert said.is_set(), lines
    (line,) = [t for t in lines if t.startswith("recording stopped:")]
    assert "No space left on device" in line
    assert report.stopped and len(report.recordings) == 1
