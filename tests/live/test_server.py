"""The web server of murk live: the page, frames, controls, and every bad request answered without a crash."""

from __future__ import annotations

import http.client
import json
import socket
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.live.page import ASSETS, asset
from murk.live.server import PAGE_REFUSED_OPTIONS, LiveServer, RequestError, method_table, spec_from_page
from tests.live._live import WAIT_S, clip, pipeline


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[LiveServer, Path]]:
    """A server over a looping clip whose first frame is restored: a request never waits for the first frame
    (``/api/frame`` answers 204 after 2 s, which a busy machine can take to restore it)."""
    out = tmp_path / "out"
    p = pipeline(clip(tmp_path, n=20, fps=30.0), out, "post", loop=True).start()
    server = LiveServer(p, "127.0.0.1", 0, methods=method_table()).start()
    try:
        assert p.wait_view(-1, WAIT_S) is not None, p.status()
        yield server, out
    finally:
        server.stop()
        p.stop()


def request(server: LiveServer, verb: str, path: str, body: object = None, headers: dict | None = None):
    conn = http.client.HTTPConnection("127.0.0.1", server.server_port, timeout=20)
    data = body if isinstance(body, bytes) or body is None else json.dumps(body).encode()
    hdrs = {"Content-Type": "application/json"} if data is not None else {}
    conn.request(verb, path, body=data, headers=hdrs | (headers or {}))
    r = conn.getresponse()
    payload = r.read()
    conn.close()
    return r, payload


def test_page_files_are_served_by_exact_name_only(served) -> None:
    server, _ = served
    r, body = request(server, "GET", "/")
    assert r.status == 200 and r.getheader("Content-Type").startswith("text/html") and b"murk live" in body
    assert b'<script src="live.js">' in body and b"http" not in body.split(b"<body")[1]  # no CDN, no remote file
    r, body = request(server, "GET", "/live.js")
    assert r.status == 200 and b"murkStats" in body
    for path in ("/../../etc/passwd", "/assets/live.js", "/%2e%2e/pyproject.toml", "/live.js/..", "/etc/passwd"):
        r, body = request(server, "GET", path)
        assert r.status == 404, path
        assert "only serves the live page" in json.loads(body)["error"]
    assert set(ASSETS) == {"/", "/index.html", "/live.js", "/live.css"}
    assert asset("/run.py") is None


def test_frames_come_as_raw_restored_pairs_with_stamps(served) -> None:
    server, _ = served
    for _ in range(50):  # the pipeline may publish a newer frame between the reply and the look at its latest view
        r, body = request(server, "GET", "/api/frame?after=-1")
        assert r.status == 200 and r.getheader("Content-Type") == "application/octet-stream"
        index = int(r.getheader("X-Murk-Frame"))
        view = server.pipeline.wait_view(index - 1, 0)
        assert view is not None and view.index >= index
        if view.index == index:
            break
    assert float(r.getheader("X-Murk-Capture-Ms")) > 1.7e12 and r.getheader("X-Murk-Method") == "post"
    split = int(r.getheader("X-Murk-Raw-Bytes"))  # two JPEGs, raw then restored (the page's, shared)
    assert view.index == index and (body[:split], body[split:]) == view.page_jpegs()
    for part in (body[:split], body[split:]):
        assert cv2.imdecode(np.frombuffer(part, np.uint8), cv2.IMREAD_COLOR).shape == (48, 64, 3)
    r, _ = request(server, "GET", f"/api/frame?after={index}")
    assert r.status in (200, 204)
    if r.status == 200:
        assert int(r.getheader("X-Murk-Frame")) > index  # only newer frames
    r, body = request(server, "GET", "/api/frame?after=abc")
    assert r.status == 400 and "after" in json.loads(body)["error"]


def test_mjpeg_stream_sends_jpeg_parts(served) -> None:
    server, _ = served
    conn = http.client.HTTPConnection("127.0.0.1", server.server_port, timeout=20)
    conn.request("GET", "/stream.mjpg?view=restored")
    r = conn.getresponse()
    assert r.status == 200 and r.getheader("Content-Type").startswith("multipart/x-mixed-replace")
    data = b""
    while data.count(b"--murkframe") < 3:
        data += r.read1(65536)
    conn.close()
    part = data.split(b"--murkframe")[1]
    jpeg = part.split(b"\r\n\r\n", 1)[1]
    assert cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR).shape == (48, 64, 3)
    r, body = request(server, "GET", "/stream.mjpg?view=<b>")
    assert r.status == 400 and "view" in json.loads(body)["error"]


def test_method_switch_and_errors_from_the_page(served) -> None:
    server, _ = served
    r, body = request(server, "POST", "/api/method", {"method": "post", "options": {"lam": "0.5"}})
    assert r.status == 200 and json.loads(body) == {"method": "post?lam=0.5"}
    assert server.pipeline.method == "post?lam=0.5"
    cases = [
        ({"method": "nope"}, 400, "unknown 'nope'"),
        ({"method": "post", "options": {"lamb": "1"}}, 400, "unknown option 'lamb'"),
        ({"method": "post", "options": {"lam": "a,b=c"}}, 400, "option lam"),
        ({"method": "lite", "options": {"checkpoint": "/etc/passwd"}}, 403, "cannot be set from the page"),
        ({"method": "lite?checkpoint=/etc/passwd"}, 403, "cannot be set from the page"),
        ({"method": "post?trust_checkpoint=true"}, 403, "cannot be set from the page"),
        ({"options": {}}, 400, "expected"),
        (["post"], 400, "expected"),
    ]
    for body_, status, message in cases:
        r, body = request(server, "POST", "/api/method", body_)
        assert r.status == status, body_
        assert message in json.loads(body)["error"], body_
    assert server.pipeline.method == "post?lam=0.5"  # every refused switch left the running method


def test_malformed_requests_get_clear_errors_and_the_server_keeps_running(served) -> None:
    server, _ = served
    r, body = request(server, "POST", "/api/method", b"{not json")
    assert r.status == 400 and "not JSON" in json.loads(body)["error"]
    r, body = request(server, "POST", "/api/snapshot", b"{}", headers={"Content-Type": "text/plain"})
    assert r.status == 415
    r, body = request(server, "POST", "/api/method", b"x" * 70_000)
    assert r.status == 413
    r, body = request(server, "PUT", "/api/method", {"method": "post"})
    assert r.status == 405
    r, body = request(server, "POST", "/api/record", {"on": "yes"})
    assert r.status == 400 and "on" in json.loads(body)["error"]
    r, body = request(server, "GET", "/", headers={"Host": "attacker.example:8080"})
    assert r.status == 403 and "127.0.0.1 only" in json.loads(body)["error"]
    with socket.create_connection(("127.0.0.1", server.server_port), timeout=20) as sock:  # not HTTP at all
        sock.sendall(b"\x00\xff garbage \x01\r\n\r\n")
        assert b"400 Bad request" in sock.recv(500)  # answered (as JSON), not crashed
    r, body = request(server, "GET", "/api/status")
    assert r.status == 200 and json.loads(body)["method"] == "post"


def test_snapshot_and_record_from_requests(served) -> None:
    server, out = served
    request(server, "GET", "/api/frame?after=-1")
    r, body = request(server, "POST", "/api/snapshot", {})
    assert r.status == 200
    files = json.loads(body)["files"]
    assert len(files) == 3 and all((out / f).is_file() for f in files)
    r, body = request(server, "POST", "/api/record", {"on": True})
    name = json.loads(body)["recording"]
    assert r.status == 200 and name.startswith("recording_")
    for _ in range(3):
        request(server, "GET", "/api/frame?after=-1")
    # two views after the switch: the restore thread records a view before it publishes the next one
    first = server.pipeline.wait_view(server.pipeline.latest().index, WAIT_S)
    assert first is not None and server.pipeline.wait_view(first.index, WAIT_S) is not None
    r, body = request(server, "POST", "/api/record", {"on": False})
    assert r.status == 200 and json.loads(body)["saved"] == name
    assert (out / name).stat().st_size > 0
    assert sorted(p.name for p in out.iterdir()) == sorted([*files, name])  # nothing else, nowhere else


def test_token_is_required_when_set(tmp_path: Path) -> None:
    p = pipeline(clip(tmp_path, n=10, fps=30.0), tmp_path / "out", "post", loop=True).start()
    server = LiveServer(p, "127.0.0.1", 0, token="s3cret").start()
    try:
        assert server.url.endswith("/?token=s3cret")
        r, body = request(server, "GET", "/")
        assert r.status == 401 and "token" in json.loads(body)["error"]
        assert request(server, "GET", "/?token=wrong")[0].status == 401
        assert request(server, "GET", "/?token=s3cret")[0].status == 200
        assert request(server, "GET", "/api/status", headers={"X-Murk-Token": "s3cret"})[0].status == 200
        assert request(server, "GET", "/api/status")[0].status == 401
        assert request(server, "GET", "/api/frame?after=-1")[0].status == 401
        for name in ("/live.js", "/live.css"):  # the page loads its own files without the token (they hold no data)
            assert request(server, "GET", name)[0].status == 200
    finally:
        server.stop()
        p.stop()


def test_page_options_exclude_files_and_code() -> None:
    table = method_table()
    assert {"lite", "post", "jointid"} <= set(table)
    names = {o["name"] for opts in table.values() for o in opts}
    assert not names & set(PAGE_REFUSED_OPTIONS) and "lam" in names
    assert spec_from_page({"method": " lite+post ", "options": {"temporal": 0.8}}) == "lite+post?temporal=0.8"
    with pytest.raises(RequestError, match="option x: expected a number or a word"):
        spec_from_page({"method": "post", "options": {"x": {"a": 1}}})
    # a key that smuggles a second option past the check (found in review) is refused
    with pytest.raises(RequestError, match="expected an option name"):
        spec_from_page({"method": "lite", "options": {"temporal=0.5,checkpoint": "/tmp/evil.pt"}})
    with pytest.raises(RequestError, match="cannot be set from the page"):
        spec_from_page({"method": "lite?temporal=0.5,device=cuda", "options": {}})
    with pytest.raises(RequestError, match="cannot be set from the page"):
        spec_from_page({"method": "jointid", "options": {"onnx": "model"}})


def test_the_page_never_parses_server_or_user_text_as_html() -> None:
    script = asset("/live.js")[0].decode()  # type: ignore[index]
    assert "innerHTML" not in script and "outerHTML" not in script and "insertAdjacentHTML" not in script
    assert "document.write" not in script and "eval(" not in script
