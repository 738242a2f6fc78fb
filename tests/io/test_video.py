"""Video sources and sinks: round trips, broken frames, a live MJPEG-over-HTTP stream, kill-safe recording."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.errors import InputFileError, ShapeError
from murk.io.atomic import TMP_PREFIX
from murk.io.video import CaptureSource, VideoSink, default_name, is_stream_url, open_source, redact_url
from testkit.video import make_frames, read_video

REPO_SRC = Path(__file__).resolve().parents[2] / "src"


def test_generated_video_round_trips_through_capture_source(tmp_path: Path) -> None:
    frames = make_frames(12)
    writer = cv2.VideoWriter(str(tmp_path / "in.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), 10.0, (64, 48))
    for f in frames:
        writer.write(np.ascontiguousarray(f[:, :, ::-1]))
    writer.release()
    with CaptureSource(tmp_path / "in.mp4") as src:
        assert not src.live and src.fps == pytest.approx(10.0) and src.frame_count == 12 and src.name == "in"
        got = list(src)
        assert src.end_reason == "end"
    assert [f.index for f in got] == list(range(12))
    assert all(f.image is not None and f.image.shape == (48, 64, 3) and f.image.dtype == np.uint8 for f in got)
    red = [float(f.image[:, :, 0].mean()) for f in got]  # type: ignore[index]
    np.testing.assert_allclose(red, [20 + 8 * i for i in range(12)], atol=3.0)  # RGB order and content kept


@pytest.mark.parametrize("suffix", [".mp4", ".avi", ".mkv"])
def test_video_sink_round_trip_is_atomic(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"out{suffix}"
    sink = VideoSink(path, 12.0, (64, 48))
    for f in make_frames(9):
        sink.write(f)
    assert not path.exists() and len(list(tmp_path.glob(f"{TMP_PREFIX}*"))) == 1  # still a temporary file
    assert sink.close() == path
    assert not list(tmp_path.glob(f"{TMP_PREFIX}*"))
    back = read_video(path)
    assert len(back) == 9 and back[0].shape == (48, 64, 3)
    cap = cv2.VideoCapture(str(path))
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(12.0)
    cap.release()
    assert abs(float(back[5][:, :, 0].mean()) - (20 + 8 * 5)) < 4


def test_video_sink_pads_odd_sizes_and_abort_removes_the_temporary(tmp_path: Path) -> None:
    with VideoSink(tmp_path / "odd.avi", 10.0, (63, 47)) as sink:
        for f in make_frames(3, 47, 63):
            sink.write(f)
    assert read_video(tmp_path / "odd.avi")[0].shape == (48, 64, 3)  # codecs need even sizes: padded, not cropped
    sink = VideoSink(tmp_path / "gone.mp4", 10.0, (64, 48))
    sink.write(make_frames(1)[0])
    sink.abort()
    assert not (tmp_path / "gone.mp4").exists() and not list(tmp_path.glob(f"{TMP_PREFIX}*"))


def test_video_sink_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"expected a video suffix"):
        VideoSink(tmp_path / "x.webm", 10.0, (64, 48))
    with pytest.raises(ValueError, match="fps: expected a finite number > 0"):
        VideoSink(tmp_path / "x.mp4", 0.0, (64, 48))
    with pytest.raises(ValueError, match="backend: expected 'opencv' or 'av'"):
        VideoSink(tmp_path / "x.mp4", 10.0, (64, 48), backend="gst")  # type: ignore[arg-type]
    sink = VideoSink(tmp_path / "x.mp4", 10.0, (64, 48))
    with pytest.raises(ShapeError, match=r"expected shape \(48, 64, 3\)"):
        sink.write(np.zeros((48, 63, 3), np.uint8))
    with pytest.raises(TypeError, match="expected a uint8"):
        sink.write(np.zeros((48, 64, 3), np.float32))
    sink.close()
    with pytest.raises(ValueError, match="write after close"):
        sink.write(np.zeros((48, 64, 3), np.uint8))


def test_killed_pyav_recording_stays_playable(tmp_path: Path) -> None:
    pytest.importorskip("av")
    path = tmp_path / "live.mp4"
    code = textwrap.dedent(
        f"""
        import os, numpy as np
        from murk.io.video import VideoSink
        sink = VideoSink({str(path)!r}, 10.0, (64, 48), backend="av", atomic=False)
        for i in range(35):
            sink.write(np.full((48, 64, 3), 7 * i, np.uint8))
        os._exit(0)  # killed: no close, no trailer
        """
    )
    env = {"PYTHONPATH": str(REPO_SRC), "PATH": "/usr/bin:/bin"}
    subprocess.run([sys.executable, "-c", code], check=True, env=env, timeout=120)
    n = len(read_video(path))
    assert 20 <= n <= 35  # fragments every second (10 frames) are complete; at most the last one is lost


def test_broken_frame_is_reported_and_the_video_continues(tmp_path: Path) -> None:
    path = tmp_path / "c.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (64, 48))
    for f in make_frames(10):
        writer.write(np.ascontiguousarray(f[:, :, ::-1]))
    writer.release()
    data = bytearray(path.read_bytes())
    soi = [i for i in range(len(data) - 1) if data[i] == 0xFF and data[i + 1] == 0xD8]
    assert len(soi) == 10
    data[soi[4] : soi[4] + 200] = bytes(200)  # wipe most of frame 4's JPEG (about 300 bytes)
    path.write_bytes(bytes(data))
    with CaptureSource(path) as src:
        got = list(src)
    assert [f.index for f in got] == list(range(10))
    assert got[4].image is None and "could not be decoded" in (got[4].error or "")
    assert all(f.image is not None for i, f in enumerate(got) if i != 4)
    assert abs(float(got[5].image[:, :, 0].mean()) - (20 + 8 * 5)) < 4  # type: ignore[index]  # frame 5 is frame 5


def test_mjpeg_http_stream_is_read_live_until_disconnect(mjpeg_url: str) -> None:
    with open_source(mjpeg_url) as src:
        assert src.live and src.frame_count is None and src.name == "127.0.0.1_cam.mjpg"
        got = list(src)
        assert src.end_reason == "disconnected or ended"
    assert len(got) == 15 and all(f.image is not None and f.image.shape == (48, 64, 3) for f in got)
    assert abs(float(got[3].image[:, :, 0].mean()) - (20 + 8 * 3)) < 4  # type: ignore[index]


def test_source_errors(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="video file not found"):
        CaptureSource(tmp_path / "missing.mp4")
    (tmp_path / "fake.mp4").write_text("not a video")
    with pytest.raises(InputFileError, match=r"fake\.mp4: cannot open video"):
        CaptureSource(tmp_path / "fake.mp4")
    with pytest.raises(InputFileError, match="camera 99: cannot open camera"):
        open_source("99")


def test_url_helpers() -> None:
    assert is_stream_url("rtsp://cam/live") and is_stream_url("HTTP://x") and not is_stream_url("video.mp4")
    assert redact_url("rtsp://admin:secret@10.0.0.5:554/ch1") == "rtsp://10.0.0.5:554/ch1"
    assert redact_url("http://host/a") == "http://host/a"
    assert default_name("rtsp://admin:secret@10.0.0.5:554/live/ch1") == "10.0.0.5_live_ch1"
    assert default_name(2) == "camera2" and default_name("/data/dive 3.mp4") == "dive_3"
    assert default_name("tauchgang ü.mp4") != default_name("tauchgang ä.mp4")  # not folded to one ASCII name
    assert default_name("潜水.mp4") == "潜水" and default_name("a/b:c?.mp4") == "b_c"


@pytest.mark.parametrize("suffix", [".mp4", ".mov", ".mkv", ".avi"])
def test_pyav_sink_round_trip(tmp_path: Path, suffix: str) -> None:
    pytest.importorskip("av")
    path = tmp_path / f"av{suffix}"
    with VideoSink(path, 10.0, (63, 47), backend="av") as sink:
        for f in make_frames(12, 47, 63):
            sink.write(f)
    back = read_video(path)
    assert len(back) == 12 and back[0].shape == (48, 64, 3)
    assert abs(float(back[7][:47, :63, 0].mean()) - (20 + 8 * 7)) < 4
    assert not list(tmp_path.glob(f"{TMP_PREFIX}*"))
