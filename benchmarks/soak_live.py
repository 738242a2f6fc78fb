"""``murk live`` for a whole dive: a soak and abuse test of the live server (issue 49, point 5).

Run: PYTHONPATH=src python benchmarks/soak_live.py [--minutes 15] [--method greyworld] [--size 640x480]
     [--json soak.json]

It starts ``murk live CLIP --loop`` (the command itself, in a subprocess) on a short looping clip of the shipped
underwater samples, then, talking to it over 127.0.0.1 only and with loops that all end by themselves:

1. 4 viewers pull frames for the whole run as the page does (``GET /api/frame?after=N`` on a keep-alive
   connection). After a warm-up: the server's RSS grows less than 10 %, its thread count comes back to where it
   was, and every viewer gets frames in every 10-s window;
2. churn: 60 viewers that connect and vanish (close at once, after a few bytes, or with a reset) and 3 slow
   readers (an MJPEG stream and long polls read a few KiB at a time). No other viewer starves (each keeps
   >= 20 frames/s, no gap of 2 s), and afterwards the threads and connections go back (no leak);
3. slowloris: 20 connections that send part of a request and then nothing, or trickle a byte a second, or
   nothing at all, while the viewers watch (each >= 20 frames/s); the server must close each of them within
   its timeout (+ 15 s), and then a flood of idle connections must find the number the server holds bounded
   (``--max-connections``);
4. 500 malformed requests (bad methods, huge or broken headers and request lines, bodies larger than announced,
   bad lengths, invalid JSON to every POST endpoint, binary garbage), one connection each: every one answered
   or closed within 5 s; the server still answers and the viewers still get frames;
5. a disk that fills during a recording: ``--out`` on a tmpfs of ``--disk-kb`` KiB (mounted in a private mount
   namespace with ``unshare``: as root, or as a user where user namespaces are allowed; skipped otherwise).
   The recording stops and the file that is left plays; ``/api/status`` and the terminal say why (no space);
   the live view goes on. The page is checked in Chromium when one is installed (``testkit/chromium.py``).

Figures and checks are printed as a table; the exit code is 1 when a check fails (0 when all pass or were
skipped). The server's own timings depend on the machine: the method defaults to ``greyworld`` (the cheapest
registered method, no torch) so that the server, not the restoration, is what is measured.
"""

from __future__ import annotations

import argparse
import contextlib
import http.client
import itertools
import json
import os
import random
import re
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # testkit/video.py makes the clip, testkit/chromium.py drives Chromium
HOST = "127.0.0.1"
MIN_FPS = 20.0
"""Frames/s every viewer must keep while others misbehave."""
MAX_GAP_S = 2.0
"""Longest wait between two frames of a viewer while others misbehave (the long poll's own wait)."""
ANSWER_S = 5.0
"""A malformed request must be answered or closed within this."""
SERVER_TIMEOUT_S = 30.0
"""The live server's idle timeout (``LiveHandler.timeout``): a slow connection must be closed after it."""


# ------------------------------------------------------------------------------------------------ the figures


@dataclass
class Check:
    """One line of the table: a figure, the limit it is held to, and whether it held (None: not measured)."""

    name: str
    figure: str
    limit: str
    ok: bool | None
    note: str = ""


@dataclass
class Report:
    checks: list[Check] = field(default_factory=list)
    figures: dict[str, Any] = field(default_factory=dict)

    def add(self, name: str, figure: str, limit: str, ok: bool | None, note: str = "") -> None:
        self.checks.append(Check(name, figure, limit, ok, note))
        print(f"  {'pass' if ok else 'SKIP' if ok is None else 'FAIL'}  {name}: {figure} ({limit}) {note}", flush=True)

    @property
    def failed(self) -> list[Check]:
        return [c for c in self.checks if c.ok is False]

    def table(self) -> str:
        rows = [("check", "figure", "limit", "result")] + [
            (c.name, c.figure, c.limit, "pass" if c.ok else "skip" if c.ok is None else "FAIL") for c in self.checks
        ]
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        lines = ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip() for r in rows]
        lines.insert(1, "  ".join("-" * w for w in widths))
        notes = [f"- {c.name}: {c.note}" for c in self.checks if c.note]
        return "\n".join(lines + (["", *notes] if notes else []))


# ------------------------------------------------------------------------------------------------ the server


class LiveProcess:
    """``murk live`` in a subprocess: its terminal lines, its port, and its RSS, threads and sockets from /proc.

    With ``disk_kb``, ``out_dir`` is a tmpfs of that size in a private mount namespace (``unshare``); the
    process's files are then read through ``/proc/PID/root``.
    """

    def __init__(self, clip: Path, out_dir: Path, method: str, *, disk_kb: int | None, threads: int) -> None:
        cmd = [sys.executable, "-m", "murk", "live", str(clip), "--method", method, "--port", "0", "--loop"]
        cmd += ["--out", str(out_dir)]
        if disk_kb:
            mount = f'mount -t tmpfs -o size={int(disk_kb)}k tmpfs "$0" && exec "$@"'
            user = [] if os.geteuid() == 0 else ["--map-root-user"]
            cmd = ["unshare", *user, "--mount", "--propagation", "private", "sh", "-c", mount, str(out_dir), *cmd]
        out_dir.mkdir(parents=True, exist_ok=True)
        thread_env = {k: str(threads) for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")}
        env = (
            os.environ
            | thread_env
            | {"PYTHONPATH": os.pathsep.join([str(ROOT / "src"), os.environ.get("PYTHONPATH", "")])}
        )
        self.proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        self.lines: list[tuple[float, str]] = []
        self._reader = threading.Thread(target=self._read, name="murk-live-stdout", daemon=True)
        self._reader.start()
        self.port = self._wait_port()
        self.pid = self.proc.pid

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append((time.monotonic(), line.rstrip("\n")))

    def _wait_port(self, limit_s: float = 120.0) -> int:
        deadline = time.monotonic() + limit_s
        while time.monotonic() < deadline:
            for _, line in list(self.lines):
                m = re.search(r"live view: http://127\.0\.0\.1:(\d+)/", line)
                if m:
                    return int(m.group(1))
            if self.proc.poll() is not None:
                break
            time.sleep(0.1)
        self.proc.kill()
        raise RuntimeError("murk live did not start:\n" + "\n".join(t for _, t in self.lines))

    def text_since(self, t0: float) -> str:
        return "\n".join(t for ts, t in list(self.lines) if ts >= t0)

    def path(self, p: Path) -> Path:
        """``p`` as the process sees it (inside its mount namespace)."""
        return Path(f"/proc/{self.pid}/root") / str(p).lstrip("/")

    def sample(self) -> dict[str, float]:
        """RSS (MiB), threads, open sockets of the server process."""
        fields = {}
        with open(f"/proc/{self.pid}/status", encoding="ascii") as f:
            for line in f:
                key, _, value = line.partition(":")
                if key in ("VmRSS", "Threads"):
                    fields[key] = int(value.split()[0])
        sockets = 0
        with contextlib.suppress(OSError):
            for fd in os.listdir(f"/proc/{self.pid}/fd"):
                with contextlib.suppress(OSError):
                    sockets += os.readlink(f"/proc/{self.pid}/fd/{fd}").startswith("socket:")
        return {"rss_mib": fields["VmRSS"] / 1024, "threads": fields["Threads"], "sockets": sockets}

    def alive(self) -> bool:
        return self.proc.poll() is None

    def stop(self, limit_s: float = 60.0) -> int:
        """Ctrl+C, as the operator would; killed when it does not exit within ``limit_s``."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(limit_s)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._reader.join(10)
        return int(self.proc.returncode)


class Monitor(threading.Thread):
    """Samples the server every second (time, RSS, threads, sockets) until stopped."""

    def __init__(self, server: LiveProcess, stop: threading.Event) -> None:
        super().__init__(name="soak-monitor", daemon=True)
        self.server, self.stop_event = server, stop
        self.samples: list[dict[str, float]] = []

    def run(self) -> None:
        while not self.stop_event.is_set() and self.server.alive():
            with contextlib.suppress(OSError, KeyError):
                self.samples.append({"t": time.monotonic(), **self.server.sample()})
            self.stop_event.wait(1.0)

    def between(self, t0: float, t1: float, key: str) -> list[float]:
        return [s[key] for s in list(self.samples) if t0 <= s["t"] <= t1]


# ------------------------------------------------------------------------------------------------ clients


def request(port: int, method: str, path: str, body: Any = None, timeout_s: float = 30.0) -> tuple[int, Any]:
    conn = http.client.HTTPConnection(HOST, port, timeout=timeout_s)
    try:
        data = None if body is None else json.dumps(body).encode()
        headers = {"Content-Type": "application/json"} if data is not None else {}
        conn.request(method, path, body=data, headers=headers)
        r = conn.getresponse()
        raw = r.read()
        with contextlib.suppress(ValueError):
            return r.status, json.loads(raw) if raw else None
        return r.status, raw
    finally:
        conn.close()


class Viewer(threading.Thread):
    """Pulls frames as the page does: ``GET /api/frame?after=N`` on one keep-alive connection, N the last frame it
    got; 204 (no newer frame in 2 s) asks again. Records the arrival time and number of every frame."""

    def __init__(self, port: int, name: str, stop: threading.Event) -> None:
        super().__init__(name=name, daemon=True)
        self.port, self.stop_event = port, stop
        self.arrivals: list[tuple[float, int]] = []
        self.errors: list[str] = []

    def run(self) -> None:
        after, conn = -1, None
        while not self.stop_event.is_set():
            try:
                if conn is None:
                    conn = http.client.HTTPConnection(HOST, self.port, timeout=30)
                conn.request("GET", f"/api/frame?after={after}")
                r = conn.getresponse()
                body = r.read()
                if r.status == 200 and body[:2] == b"\xff\xd8":
                    after = int(r.getheader("X-Murk-Frame", after))
                    self.arrivals.append((time.monotonic(), after))
                elif r.status != 204:
                    self.errors.append(f"{r.status} {body[:80]!r}")
            except (OSError, http.client.HTTPException) as exc:
                self.errors.append(f"{type(exc).__name__}: {exc}")
                if conn is not None:
                    conn.close()
                conn = None
                self.stop_event.wait(0.5)
        if conn is not None:
            conn.close()

    def fps(self, t0: float, t1: float) -> float:
        return sum(t0 <= t < t1 for t, _ in list(self.arrivals)) / max(t1 - t0, 1e-9)

    def max_gap(self, t0: float, t1: float) -> float:
        times = [t0] + [t for t, _ in list(self.arrivals) if t0 <= t < t1] + [t1]
        return max(b - a for a, b in itertools.pairwise(times))


def viewers_during(report: Report, viewers: list[Viewer], t0: float, t1: float, what: str) -> None:
    """The check that no viewer starved in [t0, t1): each >= MIN_FPS frames/s with no gap over MAX_GAP_S. The
    figure also gives the rate of frames the server had to give (the distinct frames any viewer got): when that
    is below MIN_FPS, the restoration, not the server, fell short (a busy machine)."""
    fps = [v.fps(t0, t1) for v in viewers]
    gaps = [v.max_gap(t0, t1) for v in viewers]
    shown = len({i for v in viewers for t, i in list(v.arrivals) if t0 <= t < t1}) / max(t1 - t0, 1e-9)
    report.figures[f"viewers_fps_{what}"] = {"each": fps, "distinct": shown}
    report.add(
        f"{what}: every viewer keeps getting frames",
        f"min {min(fps):.1f} frames/s of {shown:.1f} served, longest gap {max(gaps):.2f} s",
        f">= {MIN_FPS:g} frames/s, gap < {MAX_GAP_S:g} s",
        min(fps) >= MIN_FPS and max(gaps) < MAX_GAP_S,
    )


def connect(port: int, timeout_s: float = 10.0) -> socket.socket:
    s = socket.create_connection((HOST, port), timeout=timeout_s)
    s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return s


def closed_by_peer(s: socket.socket) -> bool:
    """Whether the server has closed ``s`` (EOF or reset; an answer it then closes counts as closed once read)."""
    s.setblocking(False)
    try:
        while True:
            data = s.recv(65536)
            if not data:
                return True
    except BlockingIOError:
        return False
    except OSError:
        return True
    finally:
        s.setblocking(True)


def settle(server: LiveProcess, threads: float, sockets: float, limit_s: float) -> float | None:
    """Seconds until the server is back to at most ``threads`` threads and ``sockets`` sockets (None: never)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit_s:
        with contextlib.suppress(OSError, KeyError):
            now = server.sample()
            if now["threads"] <= threads and now["sockets"] <= sockets:
                return time.monotonic() - t0
        time.sleep(0.5)
    return None


# ---------------------------------------------------------------------------------------------------- churn


def churn(port: int, seconds: float, vanishers: int = 60) -> dict[str, int]:
    """Viewers that vanish (close at once, after reading a few bytes, or with a TCP reset) and 3 slow readers."""
    stop = threading.Event()
    counts = {"vanished": 0, "slow_read_kib": 0}

    def slow(path: str) -> None:
        while not stop.is_set():
            with contextlib.suppress(OSError), connect(port) as s:
                s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
                s.sendall(f"GET {path} HTTP/1.1\r\nHost: {HOST}\r\n\r\n".encode())
                s.settimeout(10)
                while not stop.wait(0.1):
                    data = s.recv(2048)
                    if not data:
                        break
                    counts["slow_read_kib"] += len(data) // 1024

    readers = [
        threading.Thread(target=slow, args=(p,), daemon=True)
        for p in ("/stream.mjpg?view=pair", "/stream.mjpg?view=raw", "/api/frame?after=-1")
    ]
    for t in readers:
        t.start()
    t_end = time.monotonic() + seconds
    for i in range(vanishers):
        with contextlib.suppress(OSError):
            s = connect(port)
            s.sendall(f"GET /api/frame?after=-1 HTTP/1.1\r\nHost: {HOST}\r\n\r\n".encode())
            if i % 3 == 1:
                s.settimeout(5)
                s.recv(100)
            elif i % 3 == 2:
                s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
            s.close()
            counts["vanished"] += 1
        time.sleep(max(0.0, min(0.5, (t_end - time.monotonic()) / max(1, vanishers - i))))
    while time.monotonic() < t_end:
        time.sleep(0.2)
    stop.set()
    for t in readers:
        t.join(15)
    return counts


# ------------------------------------------------------------------------------------------------ slowloris


def slowloris(port: int, seconds: float, n: int = 20) -> dict[str, Any]:
    """``n`` connections that send part of a request and stop (a third), trickle one header byte a second (a
    third) or send nothing (the rest), held for ``seconds``; when the server closed each."""
    socks: list[tuple[str, socket.socket, float]] = []
    for i in range(n):
        kind = ("partial", "trickle", "silent")[i % 3]
        s = connect(port)
        if kind != "silent":
            s.sendall(f"GET /api/status HTTP/1.1\r\nHost: {HOST}\r\n".encode())
        socks.append((kind, s, time.monotonic()))
    closed: dict[int, float] = {}
    t_end = time.monotonic() + seconds
    tick = 0
    while time.monotonic() < t_end and len(closed) < n:
        for i, (kind, s, t0) in enumerate(socks):
            if i in closed:
                continue
            if closed_by_peer(s):
                closed[i] = time.monotonic() - t0
            elif kind == "trickle":
                try:
                    s.sendall(b"X-a: b\r\n"[tick % 8 : tick % 8 + 1])
                except OSError:
                    closed[i] = time.monotonic() - t0
        tick += 1
        time.sleep(1.0)
    for _, s, _ in socks:
        s.close()
    by_kind: dict[str, list[float | None]] = {}
    for i, (kind, _, _) in enumerate(socks):
        by_kind.setdefault(kind, []).append(closed.get(i))
    return {"closed_after_s": by_kind, "open_at_end": n - len(closed)}


def flood(port: int, server: LiveProcess, n: int, hold_s: float = 5.0) -> dict[str, float]:
    """``n`` idle connections at once (a scanner, a broken client): the most sockets and threads the server held."""
    socks = []
    peak = {"sockets": 0.0, "threads": 0.0}
    try:
        for _ in range(n):
            with contextlib.suppress(OSError):
                socks.append(connect(port, timeout_s=5))
        t_end = time.monotonic() + hold_s
        while time.monotonic() < t_end:
            with contextlib.suppress(OSError, KeyError):
                now = server.sample()
                peak = {k: max(peak[k], now[k]) for k in peak}
            time.sleep(0.25)
    finally:
        for s in socks:
            s.close()
    return {"opened": len(socks), **peak}


# ------------------------------------------------------------------------------------------------ malformed


def malformed_requests(n: int, seed: int = 49) -> Iterator[tuple[str, bytes, bool]]:
    """``(kind, bytes to send, half-close after)`` of ``n`` malformed requests, the kinds in turn."""
    rng = random.Random(seed)
    h = f"Host: {HOST}\r\n"
    posts = ("/api/method", "/api/snapshot", "/api/record")  # a snapshot is only ever sent a body that is not JSON
    bad_json = (b"{", b"not json", b"\xff\xfe\x00", b'{"on": "yes"}', b"[]", b"null", b'{"method": 5}', b"[" * 5000)

    def post(path: str, body: bytes, length: int | str | None = None, ctype: str = "application/json") -> bytes:
        n_ = len(body) if length is None else length
        return f"POST {path} HTTP/1.1\r\n{h}Content-Type: {ctype}\r\nContent-Length: {n_}\r\n\r\n".encode() + body

    methods = ("FOO", "PATCH", "get", "CONNECT", "TRACE", "OPTIONS", "HEAD", "G\x01T")
    headers = ("no colon here", "X-a:\x00b", " folded: line", "X-\xe9: v", ": empty name")
    lines = ("GET", "GET / HTTP/9.9", "GET /" + "a" * 70_000 + " HTTP/1.1", "/ GET HTTP/1.1", "GET  HTTP/1.1")
    lengths = ("abc", "-1", str(10**12), "1e3", "")

    def get(extra: str = "", line: str = "GET /api/status HTTP/1.1") -> bytes:
        return f"{line}\r\n{h}{extra}\r\n".encode("latin-1")

    kinds: list[tuple[str, Callable[[int], tuple[bytes, bool]]]] = [
        ("bad method", lambda i: (get(line=f"{methods[i % 8]} / HTTP/1.1"), False)),
        ("huge header line", lambda i: (get(f"X-Big: {'a' * (70_000 + i)}\r\n"), False)),
        ("too many headers", lambda i: (get("".join(f"X-{k}: v\r\n" for k in range(150))), False)),
        ("broken header", lambda i: (get(f"{headers[i % 5]}\r\n"), False)),
        ("broken request line", lambda i: (get(line=lines[i % 5]), False)),
        ("body larger than announced", lambda i: (post(posts[i % 3], b'{"method": "post"}' + b" " * 4000, 5), False)),
        ("bad content length", lambda i: (post(posts[i % 2 * 2], b"{}", length=lengths[i % 5]), False)),
        ("invalid JSON", lambda i: (post(posts[i % 3], bad_json[i % (2 if i % 3 == 1 else len(bad_json))]), False)),
        ("wrong content type", lambda i: (post(posts[i % 3], b"method=post", ctype="text/plain"), False)),
        (
            "binary garbage",
            lambda i: (rng.randbytes(rng.randint(1, 4096)) + (b"\r\n\r\n" if i % 2 else b""), i % 2 == 0),
        ),
    ]
    for i in range(n):
        kind, make = kinds[i % len(kinds)]
        data, half_close = make(i // len(kinds))
        yield kind, data, half_close


def send_malformed(port: int, data: bytes, half_close: bool, limit_s: float = ANSWER_S) -> tuple[str, float]:
    """``(outcome, seconds)``: ``"<status>"`` when answered, ``"closed"`` when the server closed or reset the
    connection first, ``"timeout"`` when neither came within ``limit_s``."""
    t0 = time.monotonic()
    try:
        s = connect(port, timeout_s=limit_s)
    except OSError as exc:
        return f"refused ({exc})", time.monotonic() - t0
    with s:
        try:
            s.sendall(data)
            if half_close:
                s.shutdown(socket.SHUT_WR)
        except OSError:
            pass  # the server answered and closed while we were still sending: read what it said
        got = b""
        while True:
            left = limit_s - (time.monotonic() - t0)
            if left <= 0:
                return "timeout", time.monotonic() - t0
            s.settimeout(left)
            try:
                chunk = s.recv(65536)
            except TimeoutError:
                return "timeout", time.monotonic() - t0
            except OSError:
                chunk = b""
            got += chunk
            m = re.match(rb"HTTP/1\.[01] (\d{3})", got)
            if m:
                return m.group(1).decode(), time.monotonic() - t0
            if not chunk:
                return "closed", time.monotonic() - t0


# ------------------------------------------------------------------------------------------------ disk full


def disk_full(report: Report, server: LiveProcess, out_dir: Path, viewers: list[Viewer], limit_s: float) -> None:
    """Record onto the small tmpfs until it is full; check what is left and what the server says."""
    t0 = time.monotonic()
    status, answer = request(server.port, "POST", "/api/record", {"on": True})
    report.figures["record_answer"] = [status, answer]
    if status != 200:
        report.add("disk full: recording starts", f"{status} {answer}", "200", False)
        return
    state: dict[str, Any] = {}
    while time.monotonic() - t0 < limit_s:
        _, state = request(server.port, "GET", "/api/status")
        if not state.get("recording"):
            break
        time.sleep(0.25)
    stopped_s = time.monotonic() - t0
    report.figures["disk_full_status"] = state
    report.add(
        "disk full: the recording stops",
        f"after {stopped_s:.1f} s" if not state.get("recording") else "still recording",
        f"< {limit_s:g} s",
        not state.get("recording"),
    )
    why = str(state.get("last_error") or "")
    no_space = re.compile(r"no space|disk is full|errno 28|enospc|file too large", re.I)
    report.add("disk full: /api/status says why", repr(why[:90]), "names no space", bool(no_space.search(why)))
    time.sleep(3.0)  # the terminal line, if any, comes within the status poll of run_live
    said = [t for t in server.text_since(t0).splitlines() if "record" in t.lower()]
    report.figures["disk_full_terminal"] = said
    report.add(
        "disk full: the terminal says why",
        repr(" | ".join(said)[:90]) if said else "nothing printed",
        "a line naming no space",
        any(no_space.search(t) for t in said),
    )
    page = page_says_why(server)
    report.add("disk full: the page says why", page[0], "visible text naming no space", page[1], page[2])
    files = sorted(server.path(out_dir).glob("recording_*"))
    frames, size = (playable(files[-1]), files[-1].stat().st_size) if files else (0, 0)
    report.figures["disk_full_recording"] = {"files": [f.name for f in files], "bytes": size, "frames": frames}
    report.add(
        "disk full: the recording left plays",
        f"{files[-1].name if files else 'no file'}: {size / 1024:.0f} KiB, {frames} frames decoded",
        ">= 1 frame",
        frames >= 1,
    )
    t1 = time.monotonic()
    time.sleep(10.0)
    _, after = request(server.port, "GET", "/api/status")
    viewers_during(report, viewers, t1, time.monotonic(), "after the disk filled")
    report.add(
        "disk full: the live view goes on",
        f"ended={after.get('ended')!r}",
        "source not ended",
        after.get("ended") is None,
    )


def playable(path: Path) -> int:
    """Frames decoded from the start of ``path`` (a copy: the server may still hold the file)."""
    import cv2

    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / path.name
        shutil.copyfile(path, copy)
        cap = cv2.VideoCapture(str(copy))
        n = 0
        while cap.isOpened() and cap.read()[0]:
            n += 1
        cap.release()
    return n


def page_says_why(server: LiveProcess) -> tuple[str, bool | None, str]:
    """The live page's visible text in headless Chromium, when one is installed."""
    try:
        from testkit.chromium import CHROMIUM, chromium
    except ImportError:
        CHROMIUM = None
    if CHROMIUM is None:
        return "not measured", None, "no Chromium on this machine (make browser-test installs it)"
    with tempfile.TemporaryDirectory() as tmp, chromium(Path(tmp) / "profile") as open_page:
        page = open_page(f"http://{HOST}:{server.port}/")
        with contextlib.suppress(Exception):
            page.wait_for("window.murkStats && murkStats.frames >= 5", timeout_s=60)
        time.sleep(2.0)  # a status poll or two
        text = str(page.evaluate("document.body.innerText"))
    found = re.search(r"[^\n]*(no space|disk is full|errno 28)[^\n]*", text, re.I)
    return (repr(found.group(0)[:90]) if found else "not shown"), bool(found), ""


# ------------------------------------------------------------------------------------------------ the run


@dataclass
class Soak:
    """One run: the server, its monitor, the viewers, and the report being filled."""

    args: argparse.Namespace
    server: LiveProcess
    monitor: Monitor
    viewers: list[Viewer]
    out_dir: Path
    disk_kb: int | None
    report: Report = field(default_factory=Report)
    t_start: float = field(default_factory=time.monotonic)
    base: dict[str, float] = field(default_factory=dict)
    """RSS (MiB), threads and sockets of the server after the warm-up (medians over 5 s)."""

    def phase(self, name: str) -> None:
        self.report.figures.setdefault("phases", []).append([round(time.monotonic() - self.t_start, 1), name])
        print(f"[{time.monotonic() - self.t_start:6.0f} s] {name}", flush=True)

    def now(self, seconds: float = 5.0) -> dict[str, float]:
        """The server's RSS, threads and sockets: medians over the last ``seconds`` (waited for)."""
        t0 = time.monotonic()
        time.sleep(seconds)
        return {k: statistics.median(self.monitor.between(t0, time.monotonic(), k)) for k in RESOURCES}

    def settle(self, slack: float = 1.0) -> float | None:
        """Seconds until threads and sockets are back to the warm-up's (+ ``slack``); None: not within the
        server's timeout + 15 s."""
        return settle(self.server, self.base["threads"] + slack, self.base["sockets"] + slack, SERVER_TIMEOUT_S + 15)


RESOURCES = ("rss_mib", "threads", "sockets")


def soak(args: argparse.Namespace) -> Report:
    """Start ``murk live`` and its viewers, run the phases, stop it with Ctrl+C; the report."""
    from testkit.video import underwater_clip

    total_s = args.minutes * 60.0
    w, h = (int(v) for v in args.size.split("x"))
    disk_kb = args.disk_kb if args.disk_kb and can_mount() else None
    with tempfile.TemporaryDirectory(prefix="murk-soak-") as tmp:
        clip = underwater_clip(Path(tmp) / "dive.avi", n=90, fps=30.0, w=w, h=h)
        out_dir = Path(tmp) / "out"
        t_start = time.monotonic()
        server = LiveProcess(clip, out_dir, args.method, disk_kb=disk_kb, threads=args.threads)
        stop = threading.Event()
        monitor = Monitor(server, stop)
        monitor.start()
        viewers = [Viewer(server.port, f"viewer-{i}", stop) for i in range(args.viewers)]
        for v in viewers:
            v.start()
        run = Soak(args, server, monitor, viewers, out_dir, disk_kb, t_start=t_start)
        try:
            warm_up(run)
            t_warm = time.monotonic()
            abuse_s = args.churn_s + args.slowloris_s + 40.0 + (30.0 if disk_kb else 0.0)  # roughly, settling included
            viewers_only(run, max(0.0, (total_s - (t_warm - t_start) - abuse_s) / 2))
            abuse(run)
            run.phase("settle after the abuse")
            run.settle()
            after_abuse = run.now()
            run.report.figures["after_abuse"] = after_abuse
            t_after = time.monotonic()
            rest = total_s - (t_after - t_start) - 5.0
            run.phase(f"viewers only: {max(rest, 0):.0f} s")
            time.sleep(max(rest, 0.0))
            finish(run, t_warm, t_after, after_abuse)
        finally:
            stop.set()
            for v in viewers:
                v.join(35)
            monitor.join(5)
            code = server.stop()
        terminal = [t for _, t in server.lines]
        run.report.figures["terminal"] = terminal
        run.report.figures["samples"] = [
            {k: round(v - t_start if k == "t" else v, 1) for k, v in sample.items()} for sample in monitor.samples[::5]
        ]
        tracebacks = sum(t.startswith("Traceback") for t in terminal)
        said = next((t for t in terminal if t.startswith(("ConnectionResetError", "BrokenPipeError"))), "")
        run.report.add(
            "terminal: clients cannot print tracebacks",
            f"{tracebacks} tracebacks" + (f" ({said})" if said else ""),
            "0",
            tracebacks == 0,
        )
        run.report.add("Ctrl+C: murk live exits 130", str(code), "130", code == 130)
    return run.report


def warm_up(run: Soak) -> None:
    args = run.args
    run.phase(f"warm-up ({args.warmup_s:g} s): {len(run.viewers)} viewers, {args.method}, {args.size}")
    time.sleep(args.warmup_s)
    t0 = time.monotonic()
    run.base = run.now()
    run.report.figures["after_warmup"] = run.base
    b = run.base
    run.phase(f"after warm-up: RSS {b['rss_mib']:.1f} MiB, {b['threads']:.0f} threads, {b['sockets']:.0f} sockets")
    viewers_during(run.report, run.viewers, t0, time.monotonic(), "warm-up")


def viewers_only(run: Soak, seconds: float) -> None:
    """The viewers alone for ``seconds``: the server's RSS must not grow by 10 % (the steady soak)."""
    run.phase(f"viewers only: {seconds:.0f} s")
    t0 = time.monotonic()
    time.sleep(seconds)
    now = run.now()
    t1 = time.monotonic()
    run.report.figures["before_abuse"] = now
    growth = (now["rss_mib"] / run.base["rss_mib"] - 1) * 100
    rss = run.monitor.between(t0, t1, "rss_mib")
    run.report.add(
        f"viewers only ({t1 - t0:.0f} s): RSS growth",
        f"{growth:+.1f} % ({run.base['rss_mib']:.1f} -> {now['rss_mib']:.1f} MiB, peak {max(rss):.1f})",
        "< 10 %",
        growth < 10.0,
    )
    viewers_during(run.report, run.viewers, t0, t1, "viewers only")


def abuse(run: Soak) -> None:
    """Churn, slowloris (and the flood), malformed requests, the full disk: one after the other."""
    args, report, server = run.args, run.report, run.server
    run.phase("churn: 60 viewers vanish, 3 slow readers")
    t0 = time.monotonic()
    report.figures["churn"] = churn(server.port, args.churn_s)
    viewers_during(report, run.viewers, t0, time.monotonic(), "churn")
    left = run.settle()
    report.add(
        "churn: threads and sockets come back (no leak)",
        f"after {left:.1f} s" if left is not None else f"not within {SERVER_TIMEOUT_S + 15:g} s: {server.sample()}",
        f"<= {run.base['threads'] + 1:.0f} threads, <= {run.base['sockets'] + 1:.0f} sockets",
        left is not None,
    )
    slow_connections(run)
    run.settle()
    malformed(run)
    if run.disk_kb:
        run.phase(f"disk full: recording onto a {run.disk_kb} KiB tmpfs")
        disk_full(report, server, run.out_dir, run.viewers, limit_s=120.0)
    else:
        report.add("disk full", "not measured", "", None, "cannot mount a tmpfs here (unshare or mount refused)")


def slow_connections(run: Soak) -> None:
    """20 slowloris connections while the viewers watch, and a flood of idle connections in the middle."""
    args, report, server = run.args, run.report, run.server
    run.phase(f"slowloris: 20 slow connections for {args.slowloris_s:g} s")
    t0 = time.monotonic()
    result: dict[str, Any] = {}
    worker = threading.Thread(target=lambda: result.update(slowloris(server.port, args.slowloris_s)), daemon=True)
    worker.start()
    time.sleep(min(10.0, args.slowloris_s / 3))
    run.phase(f"flood: {args.flood} idle connections")
    flooded = flood(server.port, server, args.flood)
    worker.join(args.slowloris_s + 30)
    report.figures["slowloris"] = result
    report.figures["flood"] = flooded
    viewers_during(report, run.viewers, t0, time.monotonic(), "slowloris")
    for kind, closed in result.get("closed_after_s", {}).items():
        done = [c for c in closed if c is not None]
        report.add(
            f"slowloris: '{kind}' connections time out",
            f"{len(done)}/{len(closed)} closed" + (f", after {min(done):.0f}-{max(done):.0f} s" if done else ""),
            f"all, within {SERVER_TIMEOUT_S + 15:g} s",
            len(done) == len(closed),
        )
    held = flooded["sockets"] - 1  # the listening socket
    report.add(
        "slowloris: connections held are bounded",
        f"{held:.0f} held, {flooded['threads']:.0f} threads, with {flooded['opened']:.0f} idle + 24 others open",
        f"<= {args.max_connections}",
        held <= args.max_connections,
    )


def malformed(run: Soak) -> None:
    """The malformed requests, one connection each; then the server must still answer."""
    report, port = run.report, run.server.port
    run.phase(f"malformed: {run.args.malformed} requests")
    t0 = time.monotonic()
    outcomes: dict[str, dict[str, int]] = {}
    slowest = (0.0, "")
    late: list[str] = []
    for kind, data, half in malformed_requests(run.args.malformed):
        outcome, took = send_malformed(port, data, half)
        outcomes.setdefault(kind, {}).setdefault(outcome, 0)
        outcomes[kind][outcome] += 1
        slowest = max(slowest, (took, kind))
        if not (outcome.isdigit() or outcome == "closed"):
            late.append(f"{kind}: {outcome}")
    report.figures["malformed"] = outcomes
    n_answered = sum(v for o in outcomes.values() for k, v in o.items() if k.isdigit())
    n_closed = sum(o.get("closed", 0) for o in outcomes.values())
    n_500 = sum(o.get("500", 0) for o in outcomes.values())
    report.add(
        "malformed: each answered or closed in time",
        f"{n_answered} answered ({n_500} with 500), {n_closed} closed, {len(late)} late; slowest {slowest[0]:.2f} s "
        f"({slowest[1]})",
        f"all within {ANSWER_S:g} s",
        not late,
        "; ".join(sorted(set(late))[:5]),
    )
    try:
        code, state = request(port, "GET", "/api/status", timeout_s=10)
        up = code == 200 and state.get("ended") is None
    except OSError as exc:
        code, up = str(exc), False
    report.add("malformed: the server stays up", f"/api/status {code}", "200, source running", up)
    viewers_during(report, run.viewers, t0, time.monotonic(), "malformed")


def finish(run: Soak, t_warm: float, t_after: float, after_abuse: dict[str, float]) -> None:
    """The checks over the whole run: RSS after the abuse, threads, frames in every 10-s window."""
    report, monitor = run.report, run.monitor
    end = run.now()
    t_end = time.monotonic()
    report.figures["at_end"] = end
    growth = (end["rss_mib"] / after_abuse["rss_mib"] - 1) * 100
    report.add(
        f"after the abuse ({t_end - t_after:.0f} s): RSS growth",
        f"{growth:+.1f} % ({after_abuse['rss_mib']:.1f} -> {end['rss_mib']:.1f} MiB)",
        "< 10 %",
        growth < 10.0,
        f"whole run after warm-up: {run.base['rss_mib']:.1f} -> {end['rss_mib']:.1f} MiB "
        f"({(end['rss_mib'] / run.base['rss_mib'] - 1) * 100:+.1f} %)",
    )
    threads = monitor.between(t_warm, t_end, "threads")
    report.add(
        "thread count stable",
        f"{run.base['threads']:.0f} -> {end['threads']:.0f} (range {min(threads):.0f}-{max(threads):.0f})",
        f"end <= {run.base['threads'] + 1:.0f}",
        end["threads"] <= run.base["threads"] + 1,
    )
    windows = [(t, min(t + 10.0, t_end)) for t in frange(t_warm, t_end, 10.0)]
    worst = min(v.fps(a, b) for v in run.viewers for a, b in windows)
    errors = sum(len(v.errors) for v in run.viewers)
    report.figures["viewer_errors"] = {v.name: v.errors[:5] for v in run.viewers if v.errors}
    report.figures["viewer_frames"] = [len(v.arrivals) for v in run.viewers]
    report.add(
        "every viewer gets frames in every 10-s window",
        f"worst {worst:.1f} frames/s; {sum(len(v.arrivals) for v in run.viewers)} frames, {errors} errors",
        "> 0 in each window",
        worst > 0,
    )


def frange(start: float, stop: float, step: float) -> Iterator[float]:
    while start < stop:
        yield start
        start += step


def can_mount() -> bool:
    """Whether ``unshare`` can give the server a private tmpfs (root, or user namespaces allowed)."""
    if shutil.which("unshare") is None:
        return False
    user = [] if os.geteuid() == 0 else ["--map-root-user"]
    cmd = ["unshare", *user, "--mount", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt"]
    return subprocess.run(cmd, capture_output=True, timeout=30).returncode == 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=15.0, help="length of the whole run (the abuse included)")
    parser.add_argument("--method", default="greyworld", help="restoration method of murk live")
    parser.add_argument("--size", default="640x480", help="frame size of the looping clip (WxH)")
    parser.add_argument("--threads", type=int, default=2, help="OpenMP/BLAS threads of the server")
    parser.add_argument("--viewers", type=int, default=4)
    parser.add_argument("--warmup-s", type=float, default=15.0)
    parser.add_argument("--churn-s", type=float, default=20.0)
    parser.add_argument("--slowloris-s", type=float, default=SERVER_TIMEOUT_S + 15.0)
    parser.add_argument("--flood", type=int, default=150, help="idle connections opened at once")
    parser.add_argument("--max-connections", type=int, default=64, help="the most connections the server may hold")
    parser.add_argument("--malformed", type=int, default=500)
    parser.add_argument("--disk-kb", type=int, default=2048, help="size of the tmpfs the recording fills (0: skip)")
    parser.add_argument("--json", type=Path, help="write the checks and figures here")
    args = parser.parse_args(argv)
    report = soak(args)
    print()
    print(report.table())
    if args.json:
        doc = {"args": {k: str(v) for k, v in vars(args).items()}, "checks": [asdict(c) for c in report.checks]}
        args.json.write_text(json.dumps(doc | {"figures": report.figures}, indent=2, default=str) + "\n")
    return 1 if report.failed else 0


if __name__ == "__main__":
    sys.exit(main())
