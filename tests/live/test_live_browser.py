"""The live page in a real headless Chromium (Debian's), driven over the DevTools protocol: frames arrive and
change, the method is switched from the page (and a hostile method name is shown as text, never run), a
snapshot and a recording are made from the page and their files checked. Saves a screenshot (docs/live.md's
``docs/images/live.png`` when ``MURK_UPDATE_DOCS_IMAGES=1``).

Marked ``browser`` (CI skips it): run with ``make browser-test``.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
from pathlib import Path

import cv2
import pytest

from murk.live.server import LiveServer, method_table
from testkit.chromium import CHROMIUM, chromium
from testkit.video import read_video, underwater_clip
from tests.live._live import clip, pipeline

DOCS_IMAGE = Path(__file__).parents[2] / "docs" / "images" / "live.png"


@pytest.mark.browser
@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (make browser-test installs it)")
def test_live_page_in_chromium(tmp_path: Path) -> None:
    out = tmp_path / "out"
    p = pipeline(underwater_clip(tmp_path / "dive.avi", n=120), out, "lite+post", loop=True).start()
    server = LiveServer(p, "127.0.0.1", 0, methods=method_table()).start()
    try:
        with chromium(tmp_path / "profile") as open_page:
            page = open_page(server.url)
            page.wait_for("window.murkStats && murkStats.frames >= 10", timeout_s=120)
            first = page.evaluate("murkStats.lastFrame")
            pixels = (
                "Array.from(document.getElementById('restored').getContext('2d').getImageData(0, 0, 640, 480)"
                ".data.filter((_, i) => i % 4097 === 0)).join(',')"
            )
            before = page.evaluate(pixels)
            page.wait_for(f"murkStats.lastFrame > {first} + 10", timeout_s=60)
            assert page.evaluate(pixels) != before  # the restored picture changes
            assert page.evaluate("murkStats.latencyMedianMs") > 0
            assert page.evaluate("document.getElementById('source').textContent").endswith("dive.avi")
            assert page.evaluate("document.getElementById('restored').width") == 640

            # an unknown, hostile method name: a clear error shown as text, nothing run, the server goes on
            page.evaluate(
                "document.getElementById('method').value = '<img src=x onerror=\"window.pwned=1\">';"
                "document.getElementById('apply').click()"
            )
            error = page.wait_for(
                "document.getElementById('message').className === 'error' && "
                "document.getElementById('message').textContent"
            )
            assert "unknown" in error and '<img src=x onerror="window.pwned=1">' in error
            assert page.evaluate("document.querySelectorAll('#message img').length") == 0
            assert page.evaluate("typeof window.pwned") == "undefined"

            # switch the method with an option, from the page's own controls
            page.evaluate(
                "const m = document.getElementById('method'); m.value = 'post';"
                "m.dispatchEvent(new Event('change'));"
                "document.querySelector('#options input[name=lam]').value = '0.5';"
                "document.getElementById('apply').click()"
            )
            page.wait_for("murkStats.method === 'post?lam=0.5'", timeout_s=60)
            assert p.method == "post?lam=0.5"

            # snapshot from the page
            page.evaluate("document.getElementById('snapshot').click()")
            message = page.wait_for(
                "document.getElementById('message').textContent.includes('saved') && "
                "document.getElementById('message').textContent"
            )
            sidecar_path = next(out.glob("snapshot_*.json"))
            assert sidecar_path.name in message
            sidecar = json.loads(sidecar_path.read_text())
            assert sidecar["method"] == "post" and sidecar["options"] == {"lam": 0.5}
            assert sidecar["size"] == [640, 480] and sidecar["source"].endswith("dive.avi")
            for key in ("raw", "restored"):
                assert cv2.imread(str(out / sidecar["files"][key])).shape == (480, 640, 3)

            # record from the page: on, a few frames, off
            page.evaluate("document.getElementById('record').click()")
            page.wait_for("document.getElementById('record').getAttribute('aria-pressed') === 'true'")
            seen = page.evaluate("murkStats.lastFrame")
            page.wait_for(f"murkStats.lastFrame > {seen} + 10", timeout_s=60)
            shot = page.screenshot(tmp_path / "live.png")
            page.evaluate("document.querySelector('input[name=layout][value=split]').click()")
            page.evaluate(
                "const s = document.getElementById('split'); s.value = 40; s.dispatchEvent(new Event('input'))"
            )
            assert page.evaluate("document.getElementById('split-canvas').width") == 640
            assert page.evaluate("getComputedStyle(document.getElementById('side2')).display") == "none"
            page.evaluate("document.getElementById('record').click()")
            saved = page.wait_for(
                "document.getElementById('message').textContent.includes('recording saved') && "
                "document.getElementById('message').textContent"
            )
            (recording,) = out.glob("recording_*")
            assert recording.name in saved
            assert len(read_video(recording)) >= 5
            assert page.evaluate("murkStats.errors") == 1  # only the refused method
    finally:
        server.stop()
        p.stop()
    image = cv2.imread(str(shot))
    assert image is not None and image.shape[1] >= 1000
    if os.environ.get("MURK_UPDATE_DOCS_IMAGES"):
        shutil.copyfile(shot, DOCS_IMAGE)


class _SharesRestored:
    """A hook like the Foxglove publisher with a client subscribed to /murk/restored: publishes its full JPEG."""

    def __init__(self) -> None:
        self.published: dict[int, bytes] = {}

    def full_views(self) -> list[str]:
        return ["restored"]

    def __call__(self, view) -> None:
        self.published[view.index] = view.jpeg("restored")


@pytest.mark.browser
@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (make browser-test installs it)")
def test_the_page_at_1920x1080_shows_the_jpegs_foxglove_publishes(tmp_path: Path) -> None:
    """Issue 48, point 5: at 1920x1080 the page shows raw at 960x540 and the restored JPEG a Foxglove client gets at
    full resolution (encoded once for both); both layouts, the snapshot and the recording work at that size."""
    out, hook = tmp_path / "out", _SharesRestored()
    clip = underwater_clip(tmp_path / "hd.avi", n=20, w=1920, h=1080)
    p = pipeline(clip, out, "post", loop=True, hooks=[hook]).start()
    server = LiveServer(p, "127.0.0.1", 0, methods=method_table()).start()
    try:
        with chromium(tmp_path / "profile") as open_page:
            page = open_page(server.url)
            page.wait_for("window.murkStats && murkStats.frames >= 5", timeout_s=120)
            size = "[document.getElementById('{}').width, document.getElementById('{}').height]"
            assert page.evaluate(size.format("raw", "raw")) == [960, 540]
            assert page.evaluate(size.format("restored", "restored")) == [1920, 1080]
            shown = p.latest()
            assert shown is not None and shown.page_jpegs()[1] is hook.published.get(
                shown.index, shown.jpeg("restored")
            )
            page.evaluate("document.querySelector('input[name=layout][value=split]').click()")
            assert page.evaluate(size.format("split-canvas", "split-canvas")) == [1920, 1080]
            page.evaluate("document.getElementById('snapshot').click()")
            page.wait_for("document.getElementById('message').textContent.includes('saved')")
            sidecar = json.loads(next(out.glob("snapshot_*.json")).read_text())
            assert sidecar["size"] == [1920, 1080]
            for key in ("raw", "restored"):
                assert cv2.imread(str(out / sidecar["files"][key])).shape == (1080, 1920, 3)
            page.evaluate("document.getElementById('record').click()")
            page.wait_for("document.getElementById('record').getAttribute('aria-pressed') === 'true'")
            seen = page.evaluate("murkStats.lastFrame")
            page.wait_for(f"murkStats.lastFrame > {seen} + 5", timeout_s=60)
            page.evaluate("document.getElementById('record').click()")
            page.wait_for("document.getElementById('message').textContent.includes('recording saved')")
            frames = read_video(next(out.glob("recording_*")))
            assert len(frames) >= 5 and frames[0].shape == (1080, 1920, 3)
            assert page.evaluate("murkStats.errors") == 0
    finally:
        server.stop()
        p.stop()


@pytest.mark.browser
@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (make browser-test installs it)")
def test_the_page_says_why_a_recording_stopped(tmp_path: Path, monkeypatch) -> None:
    from murk.live import outputs

    def disk_full(self, index, image) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs.Recorder, "write", disk_full)
    p = pipeline(underwater_clip(tmp_path / "dive.avi", n=30, w=320, h=240), tmp_path / "out", "post", loop=True)
    server = LiveServer(p.start(), "127.0.0.1", 0, methods=method_table()).start()
    try:
        with chromium(tmp_path / "profile") as open_page:
            page = open_page(server.url)
            page.wait_for("window.murkStats && murkStats.frames >= 3", timeout_s=120)
            page.evaluate("document.getElementById('record').click()")
            said = page.wait_for(
                "!document.getElementById('rec-stopped').hidden && document.getElementById('rec-stopped').innerText",
                timeout_s=60,
            )
            assert said == "recording stopped: [Errno 28] No space left on device"
            assert "No space left on device" in page.evaluate("document.body.innerText")  # visible, not a tooltip
            seen = page.evaluate("murkStats.lastFrame")
            page.wait_for(f"murkStats.lastFrame > {seen} + 5", timeout_s=60)  # the view goes on
    finally:
        server.stop()
        p.stop()


@pytest.mark.browser
@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine (make browser-test installs it)")
def test_the_page_shows_the_estimated_visibility(tmp_path: Path) -> None:
    """With a method that estimates the water, the page's statistics show the latest frame's visibility; with one
    that does not, the field is hidden."""
    p = pipeline(clip(tmp_path, n=30, fps=30.0), tmp_path / "out", "facts", loop=True).start()
    server = LiveServer(p, "127.0.0.1", 0, methods=method_table()).start()
    try:
        with chromium(tmp_path / "profile") as open_page:
            page = open_page(server.url)
            shown = page.wait_for(
                "!document.getElementById('water').hidden && document.getElementById('visibility').textContent",
                timeout_s=60,
            )
            assert shown == "12.5 m"
            p.set_method("post")
            page.wait_for("document.getElementById('water').hidden", timeout_s=60)
    finally:
        server.stop()
        p.stop()
