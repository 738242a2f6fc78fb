"""The frame pipeline of murk live: newest frame wins, drops counted, method switch, snapshot, recording, end."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.live.restore_loop import PAGE_IMAGE_PX, PAGE_WIDTH_PX, LivePipeline, LiveView, page_pair
from testkit.video import read_video
from tests.live._live import WAIT_S, BurstRestorer, WatchedSource, clip, make_restorer, pipeline


def _views(p, n: int) -> list[LiveView]:
    return _views_after(p, -1, n)


def _views_after(p, after: int, n: int) -> list[LiveView]:
    """The next ``n`` views shown with an index above ``after``."""
    out: list[LiveView] = []
    while len(out) < n:
        view = p.wait_view(after, WAIT_S)
        assert view is not None, p.status()
        out.append(view)
        after = view.index
    return out


def test_frames_are_restored_in_order_and_shown_with_stamps(tmp_path: Path) -> None:
    p = pipeline(clip(tmp_path, n=20, fps=30.0), tmp_path / "out", "post", loop=True).start()
    try:
        views = _views(p, 5)
        status = p.status()
    finally:
        p.stop()
    indices = [v.index for v in views]
    assert indices == sorted(set(indices))
    v = views[-1]
    assert v.raw.shape == v.restored.shape == (48, 64, 3) and v.raw.dtype == v.restored.dtype == np.uint8
    assert not np.array_equal(v.raw, v.restored)  # post changed the frame
    assert v.capture_ns <= v.done_ns and v.method == "post"
    pair = cv2.imdecode(np.frombuffer(v.jpeg("pair"), np.uint8), cv2.IMREAD_COLOR)
    assert pair.shape == (48, 128, 3)  # raw | restored
    assert status["method"] == "post" and status["restored"] >= 5 and status["ended"] is None
    assert not (tmp_path / "out").exists()  # nothing written without a snapshot or a recording


def test_slow_method_drops_frames_and_never_queues(tmp_path: Path) -> None:
    """A method slower than the source: every frame is either restored or counted as dropped. Restoring frame 0
    takes until the source has delivered all 30, and the next restoration waits until view 0 has been shown
    (events, not a slow method: the outcome is exact however busy the machine is)."""
    source = WatchedSource(clip(tmp_path, n=30, fps=60.0))
    source.hold[1] = started = threading.Event()  # frame 1 comes once frame 0 is being restored
    shown = threading.Event()
    restorer = BurstRestorer(source, started, shown)
    p = LivePipeline(source, lambda spec: restorer, "burst", tmp_path / "out", hooks=[lambda v: shown.set()]).start()
    try:
        while p.wait_view(10**9, WAIT_S) is None and p.ended is None:
            pass
        assert p.ended == "end"
    finally:
        p.stop()
    # frame 0 restored and shown; 1..28 each replaced by the next while it waited; 29, the newest, restored and
    # shown (restored only once 0 was shown: no view was replaced before the publish thread took it)
    assert (p.restored, p.unshown, p.dropped) == (2, 0, 28)
    assert p.status()["dropped"] == p.dropped and p.status()["unshown"] == p.unshown
    view = p.latest()
    assert view is not None and view.index == 29


def test_method_switch_and_bad_method(tmp_path: Path) -> None:
    p = pipeline(clip(tmp_path, n=20, fps=30.0), tmp_path / "out", "post", loop=True).start()
    try:
        _views(p, 1)
        with pytest.raises(ValueError, match="unknown 'nope'"):
            p.set_method("nope")
        with pytest.raises(ValueError, match="unknown option 'lamb'"):
            p.set_method("post?lamb=0.2")
        assert p.method == "post"  # a refused method leaves the running one
        p.set_method("slow?delay=0")
        # views restored before the switch may still be shown (one restoring, one waiting to be shown, one being
        # shown): wait for the first of the new method, then every later view is of it
        view = p.wait_view(-1, WAIT_S)
        while view is not None and view.method != "slow?delay=0":
            assert view.method == "post"
            view = p.wait_view(view.index, WAIT_S)
        assert view is not None, p.status()
        views = [view, *_views_after(p, view.index, 2)]
    finally:
        p.stop()
    assert [v.method for v in views] == ["slow?delay=0"] * 3
    for v in views:
        assert np.array_equal(v.restored.astype(int), 255 - v.raw.astype(int))  # the inverting method ran


def test_snapshot_writes_full_resolution_pngs_and_a_sidecar(tmp_path: Path) -> None:
    out = tmp_path / "out"
    p = pipeline(clip(tmp_path, n=20, fps=30.0), out, "post?lam=0.2", loop=True)
    with pytest.raises(ValueError, match="no frame has been restored yet"):
        p.snapshot()
    p.start()
    try:
        _views(p, 2)
        files = p.snapshot()
        view = p.latest()
    finally:
        p.stop()
    raw, restored, meta = files
    assert {f.parent for f in files} == {out}
    assert raw.name.endswith("_raw.png") and restored.name.endswith("_restored.png")
    sidecar = json.loads(meta.read_text())
    frame = sidecar["frame"]
    assert sidecar["method"] == "post" and sidecar["options"] == {"lam": 0.2}
    assert sidecar["source"].endswith("clip.avi") and sidecar["size"] == [64, 48]
    assert sidecar["files"] == {"raw": raw.name, "restored": restored.name}
    assert f"_f{frame:06d}" in raw.name and "time" in sidecar and sidecar["capture_time_ns"] > 0
    assert "estimates" not in sidecar  # post estimates nothing
    saved = cv2.imread(str(raw))[:, :, ::-1]
    assert saved.shape == (48, 64, 3)
    assert view is not None and view.index >= frame


def test_what_the_method_estimates_reaches_the_status_and_the_snapshot(tmp_path: Path) -> None:
    """The water a method estimated on the latest frame is in the page's status and in a snapshot's sidecar (a
    figure that is not a number as null); a method that estimates nothing gives None."""
    p = pipeline(clip(tmp_path, n=20, fps=30.0), tmp_path / "out", "facts", loop=True).start()
    try:
        _views(p, 2)
        status = p.status()
        sidecar = json.loads(p.snapshot()[-1].read_text())
        p.set_method("post")
        after = _views_after(p, p.latest().index, 2)[-1]  # type: ignore[union-attr]
        while after.method != "post":
            after = _views_after(p, after.index, 1)[-1]
        plain = p.status()
    finally:
        p.stop()
    water = {"visibility_m": 12.5, "visibility_measurable": True, "far_distance_m": 8.0, "unmeasured": None}
    assert status["estimates"] == water and sidecar["estimates"] == water
    json.dumps(status, allow_nan=False)  # what the page reads is valid JSON
    assert plain["estimates"] is None


def test_recording_is_a_playable_video_of_restored_frames(tmp_path: Path) -> None:
    out = tmp_path / "out"
    source = WatchedSource(clip(tmp_path, n=25, fps=40.0), lockstep=True)  # nothing dropped: one frame at a time
    source.hold[1] = recording = threading.Event()  # frame 1 comes once the recording runs
    p = LivePipeline(source, make_restorer, "slow?delay=0", out, hooks=[source.restored]).start()
    try:
        _views(p, 1)
        path = p.set_recording(True)
        recording.set()
        assert path is not None and path.parent == out
        assert p.status()["recording"] == path.name
        while p.ended is None:
            p.wait_view(10**9, 0.5)
    finally:
        recordings = p.stop()  # the recording is still running: stop finishes it
    assert recordings == [path]
    frames = read_video(path)
    assert len(frames) == 24  # frames 1..24: frame 0 was shown, so past its recording, before the recording began
    # restored (inverted) frames: the red channel is 255 - (20 + 8 i), falling from frame to frame
    reds = [int(np.median(f[:, :, 0])) for f in frames]
    assert all(r <= 240 for r in reds) and reds[-1] < reds[0] - 20, reds


def test_end_of_source_is_reported(tmp_path: Path) -> None:
    p = pipeline(clip(tmp_path, n=5, fps=50.0), tmp_path / "out", "post").start()
    try:
        while p.ended is None:
            p.wait_view(10**9, 0.5)
        assert p.wait_view(10**9, 5.0) is None  # ended: readers are not kept waiting
    finally:
        p.stop()
    # every frame restored and shown, restored and replaced before it was shown, or dropped before restoration;
    # the last one is never replaced, and the end is reported once it has been shown
    assert p.status()["ended"] == "end" and p.restored + p.unshown + p.dropped == 5
    last = p.latest()
    assert last is not None and last.index == 4


def test_an_unexpected_error_in_restoration_ends_the_run_visibly(tmp_path: Path) -> None:
    """Found in review: an error outside the per-frame restore errors killed the thread without a word; the
    page froze and --exit-at-end never returned. Now the run ends with the reason."""
    p = pipeline(clip(tmp_path, n=10, fps=30.0), tmp_path / "out", "buggy").start()
    try:
        p.wait_view(10**9, WAIT_S)  # returns when the run has ended (or after the limit, a fault)
        assert p.ended is not None and "restoration failed (KeyError" in p.ended
    finally:
        p.stop()


def test_page_pair_is_encoded_at_most_page_width() -> None:
    """Issue 48: the page's pair of a 1920x1080 frame is encoded 1920 wide (each half at 1/2), a 640x480 pair as is;
    the raw and restored JPEGs keep the full resolution."""
    rng = np.random.default_rng(0)
    raw, restored = (rng.integers(0, 256, (1080, 1920, 3), dtype=np.uint8) for _ in range(2))
    pair = page_pair(raw, restored)
    assert pair.shape == (540, PAGE_WIDTH_PX, 3)
    assert np.array_equal(pair[:, 960:], cv2.resize(restored, (960, 540), interpolation=cv2.INTER_AREA))
    small = raw[:480, :640], restored[:480, :640]
    assert np.array_equal(page_pair(*small), np.concatenate(small, axis=1))
    view = LiveView(0, raw, restored, None, 0, 0, 0, "lite")
    decoded = cv2.imdecode(np.frombuffer(view.jpeg("pair"), np.uint8), cv2.IMREAD_COLOR)
    assert decoded.shape == (540, 1920, 3)
    assert cv2.imdecode(np.frombuffer(view.jpeg("restored"), np.uint8), cv2.IMREAD_COLOR).shape == (1080, 1920, 3)
    assert view.jpeg("pair") is view.jpeg("pair")  # encoded once, shared


def _shape(jpeg: bytes) -> tuple[int, ...]:
    return cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR).shape


def test_the_page_gets_raw_and_restored_at_most_half_the_page_wide_or_the_shared_full_jpegs() -> None:
    """Issue 48, point 5: the page's two JPEGs of a 1920x1080 frame are 960x540 each; one that a hook publishes at
    full resolution (Foxglove) is that very JPEG, encoded once for both; a 640x480 frame's are its own JPEGs."""
    rng = np.random.default_rng(1)
    raw, restored = (rng.integers(0, 256, (1080, 1920, 3), dtype=np.uint8) for _ in range(2))
    view = LiveView(0, raw, restored, None, 0, 0, 0, "lite")
    page_raw, page_restored = view.page_jpegs()
    assert _shape(page_raw) == _shape(page_restored) == (540, PAGE_IMAGE_PX, 3) and PAGE_IMAGE_PX == 960
    assert view.page_jpegs(("raw", "restored")) == (page_raw, page_restored)  # the first call decided
    assert set(view._jpeg) == {"raw@page", "restored@page"}  # no full-resolution JPEG was encoded

    shared = LiveView(1, raw, restored, None, 0, 0, 0, "lite")
    page_raw, page_restored = shared.page_jpegs(("restored",))
    assert page_restored is shared.jpeg("restored") and _shape(page_restored) == (1080, 1920, 3)
    assert _shape(page_raw) == (540, 960, 3)
    assert set(shared._jpeg) == {"raw@page", "restored@page", "restored:85"}  # three JPEGs, not four

    earlier = LiveView(2, raw, restored, None, 0, 0, 0, "lite")
    full_raw = earlier.jpeg("raw")  # encoded for someone else first (the MJPEG stream): the page takes it
    assert earlier.page_jpegs()[0] is full_raw

    small = LiveView(3, raw[:480, :640], restored[:480, :640], None, 0, 0, 0, "lite")
    assert small.page_jpegs() == (small.jpeg("raw"), small.jpeg("restored"))
    assert set(small._jpeg) == {"raw@page", "restored@page", "raw:85", "restored:85"}


class _FullRestored:
    """A hook like the Foxglove publisher with a client subscribed to the restored topic."""

    def __init__(self) -> None:
        self.shared: list[bool] = []

    def full_views(self) -> list[str]:
        return ["restored"]

    def __call__(self, view: LiveView) -> None:
        self.shared.append(view.page_jpegs()[1] is view.jpeg("restored"))


def test_the_publish_thread_encodes_what_a_hook_publishes_once_for_it_and_the_page(tmp_path: Path) -> None:
    hook = _FullRestored()
    p = pipeline(clip(tmp_path, n=20, fps=30.0, h=48, w=1000), tmp_path / "out", "post", loop=True, hooks=[hook])
    p.start()
    try:
        views = _views(p, 3)
    finally:
        p.stop()
    assert hook.shared and all(hook.shared)
    raw, restored = views[-1].page_jpegs()
    assert _shape(restored)[:2] == (48, 1000) and _shape(raw)[1] == PAGE_IMAGE_PX
