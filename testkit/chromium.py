"""Drive Debian's headless Chromium over its DevTools protocol (``--remote-debugging-port``) with the minimal
WebSocket client of :mod:`testkit.ws`: open a page, evaluate JavaScript, click, take a screenshot. No Playwright,
no Selenium. Used by the browser tests (``-m browser``), ``benchmarks/bench_live_view.py`` and
``benchmarks/soak_live.py``."""

from __future__ import annotations

import base64
import contextlib
import itertools
import json
import shutil
import subprocess
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from testkit.ws import WebSocket

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")


class Page:
    """One page target of a running Chromium."""

    def __init__(self, ws_url: str) -> None:
        self.ws = WebSocket(ws_url, timeout_s=60)
        self._ids = itertools.count(1)

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        msg_id = next(self._ids)
        self.ws.send_text(json.dumps({"id": msg_id, "method": method, "params": params}))
        while True:
            _, payload = self.ws.recv()
            data = json.loads(payload)
            if data.get("id") == msg_id:
                if "error" in data:
                    raise RuntimeError(f"{method}: {data['error']}")
                return data.get("result", {})

    def evaluate(self, expression: str) -> Any:
        """The value of a JavaScript expression (promises awaited)."""
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout_s: float = 30.0, every_s: float = 0.2) -> Any:
        """Poll ``expression`` until it is truthy; its value."""
        deadline = time.monotonic() + timeout_s
        while True:
            value = self.evaluate(expression)
            if value:
                return value
            if time.monotonic() > deadline:
                raise TimeoutError(f"{expression}: still {value!r} after {timeout_s} s")
            time.sleep(every_s)

    def screenshot(self, path: Path) -> Path:
        data = self.call("Page.captureScreenshot", format="png")["data"]
        path.write_bytes(base64.b64decode(data))
        return path

    def close(self) -> None:
        self.ws.close()


HEADLESS_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
)
"""The flags of every headless Chromium the tests start (no sandbox: tests run as root in containers)."""


@contextlib.contextmanager
def chromium(profile: Path, *, width: int = 1400, height: int = 900) -> Iterator[Any]:
    """A headless Chromium; yields ``open_page(url) -> Page``."""
    if CHROMIUM is None:
        raise RuntimeError("no Chromium on this machine (make browser-test installs it)")
    profile.mkdir(parents=True, exist_ok=True)
    port_file = profile / "DevToolsActivePort"
    port_file.unlink(missing_ok=True)
    proc = subprocess.Popen(
        [
            CHROMIUM,
            *HEADLESS_FLAGS,
            "--disable-background-timer-throttling",
            "--disable-renderer-backgrounding",
            f"--window-size={width},{height}",
            "--remote-debugging-port=0",
            f"--user-data-dir={profile}",
            "about:blank",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    pages: list[Page] = []
    try:
        deadline = time.monotonic() + 60
        while not (port_file.exists() and port_file.read_text().strip()):
            if proc.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"Chromium did not start (exit code {proc.poll()})")
            time.sleep(0.1)
        port = int(port_file.read_text().split()[0])

        def open_page(url: str) -> Page:
            req = urllib.request.Request(f"http://127.0.0.1:{port}/json/new?{url}", method="PUT")
            with urllib.request.urlopen(req, timeout=30) as r:
                target = json.load(r)
            page = Page(target["webSocketDebuggerUrl"])
            pages.append(page)
            page.call("Page.enable")
            page.call("Runtime.enable")
            return page

        yield open_page
    finally:
        for page in pages:
            with contextlib.suppress(Exception):
                page.close()
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
