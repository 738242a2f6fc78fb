"""The web server of ``murk live``: the standard library's ``ThreadingHTTPServer`` (one thread per connection,
HTTP/1.1 keep-alive), no extra dependency. Why this server and this transport: docs/live.md.

Routes (everything else is 404; only the page's own files are served, by exact name, :mod:`murk.live.page`):

- ``GET /``, ``/live.js``, ``/live.css``: the page;
- ``GET /api/frame?after=N``: the newest restored frame newer than ``N`` as two JPEGs, raw then restored, one after
  the other in the body (``Content-Type: application/octet-stream``; the raw one is ``X-Murk-Raw-Bytes`` long;
  :meth:`murk.live.restore_loop.LiveView.page_jpegs`: at most 960 px wide each, or the full-resolution JPEGs
  Foxglove publishes), waiting up to :data:`FRAME_WAIT_S`; 204 when none came. Headers ``X-Murk-Frame`` (frame
  number), ``X-Murk-Capture-Ms`` (capture time, milliseconds since the epoch: the page measures glass-to-page
  latency against it) and ``X-Murk-Method``;
- ``GET /stream.mjpg?view=restored|raw|pair``: an MJPEG stream (``multipart/x-mixed-replace``) for other
  viewers (VLC, an ``<img>``);
- ``GET /api/status``, ``GET /api/methods``: JSON;
- ``POST /api/method`` ``{"method": "lite+post", "options": {"temporal": "0.8"}}``, ``POST /api/snapshot``,
  ``POST /api/record`` ``{"on": true}``: JSON bodies (``Content-Type: application/json``, at most 64 KiB).

Errors are JSON ``{"error": "..."}`` with a 4xx status (a bad request, an unknown method or option) or 500 (a
bug), shown in the page; no request can stop the server. Safety: with ``token`` set every request must carry it
(``X-Murk-Token`` header or ``?token=``); on a loopback address the ``Host`` header must name the loopback
(a web page cannot reach the server through DNS rebinding); POST bodies must be JSON (a cross-site form cannot
send one without the browser asking the server first, which this server does not allow).

Hostile or broken clients: a request's head and body must arrive within :data:`REQUEST_DEADLINE_S` of when the
server starts waiting for it (a connection that trickles a byte a second is closed then, as is a silent one);
at most :data:`MAX_CONNECTIONS` connections are served at once (one more is answered 503 and closed at once, in
the accepting thread); a client that resets its connection or stops reading is dropped without a traceback.
"""

from __future__ import annotations

import contextlib
import hmac
import io
import ipaddress
import json
import socket
import sys
import threading
import time
from collections.abc import Callable
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs, urlsplit

from murk.live.page import asset
from murk.live.restore_loop import LivePipeline

FRAME_WAIT_S = 2.0
"""How long ``/api/frame`` waits for a newer frame before answering 204."""
MAX_BODY_BYTES = 64 * 1024
REQUEST_DEADLINE_S = 30.0
"""A request's head and body must have arrived this long after the server started waiting for it (the idle
timeout, ``LiveHandler.timeout``, counts per read: a client sending a byte a second would never meet it)."""
MAX_CONNECTIONS = 64
"""Connections served at once (each has a thread); one more is answered 503 and closed. A page holds 2-3."""
PAGE_REFUSED_OPTIONS = ("checkpoint", "onnx", "trust_checkpoint", "device", "batch", "compile")
"""Method options the page may not set: they name files or run code on the server, or set the command's
settings (set them on the command line)."""
SUGGESTED = ("lite+post", "lite", "post", "jointid", "jointid+post", "lite?temporal=0.8")
LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")


class RequestError(Exception):
    """A request the server refuses: ``status`` and a message for the page."""

    def __init__(self, status: HTTPStatus, message: str) -> None:
        super().__init__(message)
        self.status = status


class LiveServer(ThreadingHTTPServer):
    """The HTTP server around a :class:`LivePipeline`. ``port=0`` picks a free port (see ``server_port``)."""

    daemon_threads = True
    allow_reuse_address = True

    def __init__(
        self,
        pipeline: LivePipeline,
        host: str = "127.0.0.1",
        port: int = 8080,
        *,
        token: str | None = None,
        methods: dict[str, list[dict[str, Any]]] | None = None,
        max_connections: int = MAX_CONNECTIONS,
        request_deadline_s: float = REQUEST_DEADLINE_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if max_connections < 1 or request_deadline_s <= 0:
            raise ValueError("max_connections: expected >= 1; request_deadline_s: expected > 0")
        self.address_family = socket.AF_INET6 if ":" in host else socket.AF_INET
        super().__init__((host, port), LiveHandler)
        self.pipeline = pipeline
        self.token = token or None
        self.methods = methods or {}
        self.loopback = _is_loopback(host)
        self.max_connections = max_connections
        self.request_deadline_s = request_deadline_s
        self.clock = clock
        """The clock of the request deadline (a test passes one it controls)."""
        self.connections = 0
        """Connections being served now (at most ``max_connections``)."""
        self.refused = 0
        """Connections answered 503 because ``max_connections`` were being served."""
        self._count_lock = threading.Lock()
        self._thread: threading.Thread | None = None

    @property
    def url(self) -> str:
        host = str(self.server_address[0])
        host = f"[{host}]" if ":" in host else host
        query = f"?token={self.token}" if self.token else ""
        return f"http://{host}:{self.server_port}/{query}"

    def start(self) -> LiveServer:
        self._thread = threading.Thread(target=self.serve_forever, name="murk-live-http", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self.shutdown()
        self.server_close()

    # -- connections: bounded, and clients that go away are no error ------------------------------------------

    def process_request(self, request: Any, client_address: Any) -> None:
        with self._count_lock:
            busy = self.connections >= self.max_connections
            if not busy:
                self.connections += 1
            else:
                self.refused += 1
        if busy:  # answered here, in the accepting thread: no thread for it, and at once
            _refuse(request)
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:  # its thread did not start
            self._release()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._release()

    def _release(self) -> None:
        with self._count_lock:
            self.connections -= 1

    def handle_error(self, request: Any, client_address: Any) -> None:
        if isinstance(sys.exc_info()[1], (ConnectionError, TimeoutError)):
            return  # a client that reset its connection, stopped reading or timed out: nothing to report
        super().handle_error(request, client_address)  # a bug: its traceback


_BUSY_BODY = b'{"error": "503 murk live is serving as many connections as it may; try again"}'
_BUSY = (
    b"HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\nRetry-After: 1\r\n"
    b"Connection: close\r\nContent-Length: " + str(len(_BUSY_BODY)).encode() + b"\r\n\r\n" + _BUSY_BODY
)


def _refuse(sock: socket.socket) -> None:
    """Answer 503 on a fresh connection without waiting for anything (the accepting thread must not block)."""
    with contextlib.suppress(OSError):
        sock.setblocking(False)
        sock.send(_BUSY)
        with contextlib.suppress(OSError):  # what the client sent already: read, so closing sends no reset
            sock.recv(65536)


class _DeadlineReader(io.RawIOBase):
    """The socket reader of a :class:`LiveHandler`: every read waits at most the idle timeout and at most until
    the handler's ``deadline`` (``server.clock`` time; None: no deadline); past it, reading raises TimeoutError."""

    def __init__(self, handler: LiveHandler) -> None:
        super().__init__()
        self._handler = handler

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        h = self._handler
        sock, idle = h.connection, h.timeout
        if h.deadline is None:
            return sock.recv_into(buffer)
        left = h.deadline - h.server.clock()
        if left <= 0:
            raise TimeoutError(f"the request did not arrive within {h.server.request_deadline_s:g} s")
        sock.settimeout(left if idle is None else min(idle, left))
        try:
            return sock.recv_into(buffer)
        finally:
            sock.settimeout(idle)  # writes keep the idle timeout


def _is_loopback(host: str) -> bool:
    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def method_table() -> dict[str, list[dict[str, Any]]]:
    """Every registered method with the options the page may set (name, type, default, help: its declaration)."""
    from murk.enhance.restorer import available, options_of

    table = {}
    for name in available():
        table[name] = [
            {
                "name": o.name,
                "type": o.type,
                "default": o.default if _jsonable(o.default) else str(o.default),
                "help": o.help,
            }
            for o in options_of(name).values()
            if o.name not in PAGE_REFUSED_OPTIONS
        ]
    return table


def _jsonable(value: Any) -> bool:
    return value is None or isinstance(value, (bool, int, float, str))


def spec_from_page(body: Any) -> str:
    """The method spec of a ``POST /api/method`` body ``{"method": str, "options": {name: value}}``.

    Raises:
        RequestError: a body of the wrong shape, an option the page may not set, or a value holding one of the
            spec's separators.
    """
    if not isinstance(body, dict) or not isinstance(body.get("method"), str) or not body["method"].strip():
        raise RequestError(HTTPStatus.BAD_REQUEST, 'expected {"method": "NAME", "options": {...}}')
    method = body["method"].strip()
    options = body.get("options") or {}
    if not isinstance(options, dict):
        raise RequestError(HTTPStatus.BAD_REQUEST, "options: expected an object of option: value")
    spec_method, spec_options = method.partition("?")[0], method.partition("?")[2]
    items = [i for i in spec_options.split(",") if i.strip()]
    for key, value in options.items():
        if not isinstance(key, str) or not key.isidentifier():  # "temporal=0.5,checkpoint" would smuggle a second
            raise RequestError(HTTPStatus.BAD_REQUEST, f"option {key!r}: expected an option name")
        text = str(value).strip()
        if not isinstance(value, (str, int, float, bool)) or any(c in text for c in ",?=+") or not text:
            raise RequestError(HTTPStatus.BAD_REQUEST, f"option {key}: expected a number or a word, got {value!r}")
        items.append(f"{key}={text}")
    for item in items:
        key = item.partition("=")[0].strip()
        if key in PAGE_REFUSED_OPTIONS:
            raise RequestError(
                HTTPStatus.FORBIDDEN,
                f"option {key} cannot be set from the page (it names files or settings of the server); "
                "start murk live with it instead",
            )
    spec = spec_method + (f"?{','.join(items)}" if items else "")
    from murk.enhance.options import parse_spec

    try:  # the options as murk will read them: none may be one the page may not set
        parsed = parse_spec(spec)[1]
    except ValueError as exc:
        raise RequestError(HTTPStatus.BAD_REQUEST, str(exc)) from None
    refused = sorted(set(parsed) & set(PAGE_REFUSED_OPTIONS))
    if refused:
        raise RequestError(HTTPStatus.FORBIDDEN, f"option {refused[0]} cannot be set from the page")
    return spec


class LiveHandler(BaseHTTPRequestHandler):
    server: LiveServer
    protocol_version = "HTTP/1.1"
    # TCP_NODELAY: a frame's last partial segment must not wait for the page's delayed ACK (Nagle's algorithm
    # held it for about 40 ms on every keep-alive response, capping the page at about 21 frames/s)
    disable_nagle_algorithm = True
    timeout = 30  # an idle connection frees its thread after 30 s of silence (a frame request waits 2 s)
    server_version = "murk-live"
    error_content_type = "application/json"
    error_message_format = '{"error": "%(code)d %(message)s"}'

    deadline: float | None = None
    """When the request being read must have arrived (``server.clock`` time; see :data:`REQUEST_DEADLINE_S`)."""

    def log_message(self, format: str, *args: Any) -> None:
        pass  # the terminal shows the live status, not one line per frame

    def setup(self) -> None:
        super().setup()
        plain, self.rfile = self.rfile, io.BufferedReader(_DeadlineReader(self))
        plain.close()  # (the socket stays open: it is closed when the connection ends)

    def handle_one_request(self) -> None:
        # a trickling or silent client is closed at the deadline (TimeoutError: the base class closes)
        self.deadline = self.server.clock() + self.server.request_deadline_s
        super().handle_one_request()

    # -- dispatch --------------------------------------------------------------------------------------------

    def do_GET(self) -> None:
        self._handle("GET")

    def do_POST(self) -> None:
        self._handle("POST")

    def do_PUT(self) -> None:
        self._handle("PUT")

    def do_DELETE(self) -> None:
        self._handle("DELETE")

    def _handle(self, verb: str) -> None:
        try:
            parts = urlsplit(self.path)
            query = parse_qs(parts.query)
            page = asset(parts.path) if verb == "GET" else None
            # the page's own files hold no data: a page opened with ?token=... loads its script and style
            self._check_access(query, token_needed=page is None or parts.path == "/")
            route = (verb, parts.path)
            if page is not None:
                self._send(HTTPStatus.OK, page[0], page[1])
            elif route == ("GET", "/api/frame"):
                self._frame(query)
            elif route == ("GET", "/stream.mjpg"):
                self._mjpeg(query)
            elif route == ("GET", "/api/status"):
                self._json(HTTPStatus.OK, self.server.pipeline.status())
            elif route == ("GET", "/api/methods"):
                self._json(HTTPStatus.OK, self._methods())
            elif verb == "POST" and parts.path in ("/api/method", "/api/snapshot", "/api/record"):
                self._post(parts.path, self._body())
            elif parts.path in ("/api/method", "/api/snapshot", "/api/record", "/api/frame", "/api/status"):
                raise RequestError(HTTPStatus.METHOD_NOT_ALLOWED, f"{verb} {parts.path}: not allowed")
            else:
                raise RequestError(HTTPStatus.NOT_FOUND, "not found (this server only serves the live page)")
        except RequestError as exc:
            if verb != "GET":
                self.close_connection = True  # an unread body must not be taken for the next request
            self._json(exc.status, {"error": str(exc)})
        except (BrokenPipeError, ConnectionResetError, TimeoutError):
            self.close_connection = True
        except Exception as exc:  # a bug: reported to the page, the server goes on
            self._json(HTTPStatus.INTERNAL_SERVER_ERROR, {"error": f"{type(exc).__name__}: {exc}"})

    def _check_access(self, query: dict[str, list[str]], token_needed: bool = True) -> None:
        if self.server.loopback:
            host = (self.headers.get("Host") or "").strip()
            name = host.rsplit(":", 1)[0] if not host.startswith("[") else host[1:].split("]")[0]
            if name not in LOOPBACK_NAMES:
                raise RequestError(HTTPStatus.FORBIDDEN, f"Host {host!r}: this server answers on 127.0.0.1 only")
        token = self.server.token
        if token and token_needed:
            given = self.headers.get("X-Murk-Token") or (query.get("token") or [""])[0]
            if not hmac.compare_digest(given.encode(), token.encode()):
                raise RequestError(HTTPStatus.UNAUTHORIZED, "missing or wrong access token (open the URL murk printed)")

    def _body(self) -> Any:
        ctype = (self.headers.get("Content-Type") or "").split(";")[0].strip().lower()
        if ctype != "application/json":
            raise RequestError(
                HTTPStatus.UNSUPPORTED_MEDIA_TYPE, "expected a JSON body (Content-Type: application/json)"
            )
        try:
            length = int(self.headers.get("Content-Length") or 0)
        except ValueError:
            raise RequestError(HTTPStatus.BAD_REQUEST, "Content-Length: expected a number") from None
        if length < 0 or length > MAX_BODY_BYTES:
            self.close_connection = True
            raise RequestError(HTTPStatus.REQUEST_ENTITY_TOO_LARGE, f"body: at most {MAX_BODY_BYTES} bytes")
        raw = self.rfile.read(length) if length else b"{}"
        try:
            return json.loads(raw or b"{}")
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise RequestError(HTTPStatus.BAD_REQUEST, f"body: not JSON ({exc})") from None
        except RecursionError:  # '[' x 5000: the decoder's recursion limit
            raise RequestError(HTTPStatus.BAD_REQUEST, "body: JSON nested too deeply") from None

    # -- routes ----------------------------------------------------------------------------------------------

    def _methods(self) -> dict[str, Any]:
        table = self.server.methods
        return {
            "current": self.server.pipeline.method,
            "methods": [{"name": k, "options": v} for k, v in sorted(table.items())],
            "suggested": [s for s in SUGGESTED if all(n in table for n in s.split("?")[0].split("+"))],
            "refused_options": list(PAGE_REFUSED_OPTIONS),
        }

    def _frame(self, query: dict[str, list[str]]) -> None:
        try:
            after = int((query.get("after") or ["-1"])[0])
        except ValueError:
            raise RequestError(HTTPStatus.BAD_REQUEST, "after: expected a frame number") from None
        view = self.server.pipeline.wait_view(after, FRAME_WAIT_S)
        if view is None:
            self._send(HTTPStatus.NO_CONTENT, b"", None)
            return
        headers = {
            "X-Murk-Frame": str(view.index),
            "X-Murk-Capture-Ms": f"{view.capture_ns / 1e6:.3f}",
            "X-Murk-Source-Ns": str(view.source_ns),
            "X-Murk-Method": _header_text(view.method),
        }
        raw, restored = view.page_jpegs()  # encoded by the publish thread already (once, shared with Foxglove)
        headers["X-Murk-Raw-Bytes"] = str(len(raw))
        self._send(HTTPStatus.OK, raw + restored, "application/octet-stream", headers)

    def _mjpeg(self, query: dict[str, list[str]]) -> None:
        kind = (query.get("view") or ["restored"])[0]
        if kind not in ("restored", "raw", "pair"):
            raise RequestError(HTTPStatus.BAD_REQUEST, f"view: expected restored, raw or pair, got {kind!r}")
        self.send_response(HTTPStatus.OK)
        self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=murkframe")
        self.send_header("Cache-Control", "no-store")
        self.send_header("Connection", "close")
        self.end_headers()
        self.close_connection = True
        after = -1
        pipeline = self.server.pipeline
        while pipeline.ended is None or (pipeline.latest() is not None and pipeline.latest().index > after):  # type: ignore[union-attr]
            view = pipeline.wait_view(after, FRAME_WAIT_S)
            if view is None:
                continue
            after = view.index
            data = view.jpeg(kind)
            head = f"--murkframe\r\nContent-Type: image/jpeg\r\nContent-Length: {len(data)}\r\n\r\n".encode()
            self.wfile.write(head + data + b"\r\n")
            self.wfile.flush()

    def _post(self, path: str, body: Any) -> None:
        pipeline = self.server.pipeline
        if path == "/api/method":
            spec = spec_from_page(body)
            try:
                pipeline.set_method(spec)
            except (ValueError, TypeError, OSError) as exc:
                raise RequestError(HTTPStatus.BAD_REQUEST, str(exc)) from None
            self._json(HTTPStatus.OK, {"method": spec})
        elif path == "/api/snapshot":
            view = pipeline.latest()
            try:
                files = pipeline.snapshot()
            except (ValueError, OSError) as exc:
                raise RequestError(HTTPStatus.CONFLICT, str(exc)) from None
            self._json(HTTPStatus.OK, {"frame": None if view is None else view.index, "files": [f.name for f in files]})
        else:
            if not isinstance(body, dict) or not isinstance(body.get("on"), bool):
                raise RequestError(HTTPStatus.BAD_REQUEST, 'expected {"on": true} or {"on": false}')
            try:
                path_ = pipeline.set_recording(body["on"])
            except (ValueError, OSError) as exc:
                raise RequestError(HTTPStatus.CONFLICT, str(exc)) from None
            if body["on"]:
                self._json(HTTPStatus.OK, {"recording": None if path_ is None else path_.name})
            else:
                self._json(HTTPStatus.OK, {"recording": None, "saved": None if path_ is None else path_.name})

    # -- answers ---------------------------------------------------------------------------------------------

    def _json(self, status: HTTPStatus, data: Any) -> None:
        self._send(status, json.dumps(data).encode(), "application/json")

    def _send(self, status: HTTPStatus, body: bytes, ctype: str | None, headers: dict[str, str] | None = None) -> None:
        self.send_response(status)
        if ctype:
            self.send_header("Content-Type", ctype)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Content-Security-Policy", "default-src 'self'; img-src 'self' blob:")
        for k, v in (headers or {}).items():
            self.send_header(k, v)
        self.end_headers()
        if body:
            self.wfile.write(body)


def _header_text(text: str) -> str:
    """``text`` safe in an HTTP header (printable ASCII)."""
    return "".join(c if 32 <= ord(c) < 127 else "?" for c in text)
