"""``murk enhance`` end to end: folders, videos, a live HTTP stream, depth outputs, exit codes."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from murk.cli.enhance import method_options
from murk.cli.main import app
from murk.io import read_jsonl

from ._enhance_helpers import make_frames, make_video, read_video

runner = CliRunner()


def _out(res) -> str:
    """The command's output with line wrapping undone (rich wraps error lines at 80 columns when not a tty)."""
    return " ".join(res.output.split())


@pytest.fixture
def folder(tmp_path: Path, rng: np.random.Generator) -> Path:
    root = tmp_path / "dive"
    (root / "sub").mkdir(parents=True)
    for rel in ("a.png", "sub/b.png"):
        assert cv2.imwrite(str(root / rel), (rng.random((24, 32, 3)) * 255).astype(np.uint8))
    return root


def test_folder_run_reports_counts_rate_and_stage_latency(folder: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(tmp_path / "out"), "--recursive"])
    assert res.exit_code == 0, res.output
    assert "2 images processed" in _out(res) and "images/s; per image" in _out(res)
    assert "read" in _out(res) and "restore" in _out(res) and "write" in _out(res)
    assert (tmp_path / "out" / "sub" / "b.png").is_file()
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(tmp_path / "out"), "-r"])
    assert res.exit_code == 0 and "2 skipped" in _out(res)


def test_an_existing_output_that_is_no_image_is_an_error_left_as_it_is(folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "a.png").write_text("my notes")  # not an image: not murk's, neither done nor to be replaced
    (out / "sub").mkdir()
    (out / "sub" / "b.png").write_bytes(b"")  # empty
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(out), "-r"])
    assert res.exit_code == 1 and "2 failed" in _out(res) and "0 images processed" in _out(res)
    assert (out / "a.png").read_text() == "my notes" and (out / "sub" / "b.png").read_bytes() == b""
    records = sorted(read_jsonl(out / "errors.jsonl"), key=lambda r: r["input"])
    assert records[0]["error"] == f"output {out / 'a.png'} exists and is not an image; pass --overwrite to replace it"
    assert records[1]["error"].endswith("exists and is empty; pass --overwrite to replace it")
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(out), "-r", "--overwrite"])
    assert res.exit_code == 0 and cv2.imread(str(out / "a.png")) is not None
    one = runner.invoke(app, ["enhance", str(folder / "a.png"), "--out", str(out / "a.png")])
    assert one.exit_code == 0 and "1 skipped" in _out(one) and "use --overwrite to redo it" in _out(one)


def test_corrupt_input_exits_1_with_errors_jsonl(folder: Path, tmp_path: Path) -> None:
    (folder / "bad.jpg").write_bytes(b"\xff\xd8\xff not a jpeg")
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(tmp_path / "out"), "--format", "png"])
    assert res.exit_code == 1, res.output
    assert "1 failed" in _out(res) and "errors.jsonl" in _out(res)
    (record,) = read_jsonl(tmp_path / "out" / "errors.jsonl")
    assert record["input"] == str(folder / "bad.jpg") and record["stage"] == "read"
    assert (tmp_path / "out" / "a.png").is_file()  # the rest was processed


def test_video_to_video_and_to_frames(tmp_path: Path) -> None:
    video = make_video(tmp_path / "clip.avi", 6, fps=8.0)
    res = runner.invoke(app, ["enhance", str(video), "--out", str(tmp_path / "enh.mp4"), "--batch", "4"])
    assert res.exit_code == 0, res.output
    assert "6 frames processed" in _out(res) and "wrote" in _out(res)
    frames = read_video(tmp_path / "enh.mp4")
    assert len(frames) == 6 and frames[0].shape == (48, 64, 3)
    res = runner.invoke(
        app, ["enhance", str(video), "--out", str(tmp_path / "fr"), "--max-frames", "3", "--format", "png"]
    )
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (tmp_path / "fr").iterdir()) == [f"clip_{i:06d}.png" for i in range(3)]


@pytest.mark.parametrize("backend", ["opencv", "auto"])
def test_live_http_stream_is_recorded_headless(mjpeg_url: str, tmp_path: Path, backend: str) -> None:
    out = tmp_path / "rov.mp4"
    res = runner.invoke(app, ["enhance", mjpeg_url, "--out", str(out), "--video-backend", backend, "--fps", "10"])
    assert res.exit_code == 0, res.output
    text = _out(res)
    processed = int(re.search(r"(\d+) frames? processed", text).group(1))  # type: ignore[union-attr]
    dropped_note = re.search(r"(\d+) frame\(s\) dropped", text)  # the fake camera sends at 200 frames/s
    dropped = int(dropped_note.group(1)) if dropped_note else 0
    assert processed + dropped == 15 and processed >= 1 and "disconnected" in text
    frames = read_video(out)
    assert len(frames) == processed and frames[0].shape == (48, 64, 3)


def test_fake_depth_method_through_the_cli(folder: Path, tmp_path: Path, fake_depth_method: list[dict]) -> None:
    out = tmp_path / "out"
    res = runner.invoke(app, ["enhance", str(folder), "-o", str(out), "-m", "fakedepth", "-r", "--he", "rgb"])
    assert res.exit_code == 0, res.output
    raw = cv2.imread(str(out / "depth" / "sub" / "b.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16 and raw[0, 0] == 1000
    assert (out / "depth_preview" / "a.jpg").is_file()
    (options,) = fake_depth_method
    # The command hands over device, batch and the flags that were set; the factory's own defaults fill the rest.
    assert method_options(device="cpu", batch=1, he="rgb", lam=None, compile=False) == {
        "device": "cpu",
        "batch": 1,
        "he": "rgb",
    }
    assert options["he"] == "rgb" and options["device"] == "cpu" and options["batch"] == 1
    assert options["lam"] == 0.3 and options["precision"] == "fp32" and options["checkpoint"] is None


def test_usage_errors_exit_2(folder: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(tmp_path / "o"), "--method", "nope"])
    assert res.exit_code == 2 and "unknown 'nope'" in _out(res) and "post" in _out(res)
    res = runner.invoke(app, ["enhance", "97", "--out", str(tmp_path / "cam.mp4")])
    assert res.exit_code == 2 and "camera 97: cannot open camera" in _out(res)
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(folder)])
    assert res.exit_code == 2 and "this is the input folder" in _out(res)
    res = runner.invoke(app, ["enhance", str(tmp_path / "missing.png"), "--out", str(tmp_path / "o")])
    assert res.exit_code == 2 and "not found" in _out(res)
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(tmp_path / "o"), "-m", "post", "--sigma-px", "0"])
    assert res.exit_code == 2 and "sigma_px" in _out(res)
    if not torch.cuda.is_available():
        res = runner.invoke(app, ["enhance", str(folder), "--out", str(tmp_path / "o"), "--device", "cuda"])
        assert res.exit_code == 2 and "CUDA is not available" in _out(res)


def test_sigterm_closes_a_live_recording_cleanly(mjpeg_server: Callable[..., str], tmp_path: Path) -> None:
    # An endless stream; the recording is stopped with SIGTERM as a service manager would. OpenCV's MP4 writer
    # only produces a playable file when it is released, so a readable file proves the clean close. The output
    # appears with its first frame, and a stop writes every frame already restored: however slowly the machine
    # starts murk, the video holds at least that frame.
    url = mjpeg_server(make_frames(30), 0.01, loop=True)
    out = tmp_path / "rov.mp4"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src")}
    cmd = [sys.executable, "-m", "murk", "enhance", url, "--out", str(out), "--video-backend", "opencv"]
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 600  # only a fault reaches it
        while not out.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)
        assert out.exists() and proc.poll() is None, "the recording never started"
        proc.send_signal(signal.SIGTERM)
        output, _ = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, output
    assert "processed" in output and "disconnected" not in output  # stopped by the signal, not by the stream
    frames = read_video(out)
    assert len(frames) >= 1 and frames[0].shape == (48, 64, 3)


def test_video_with_a_broken_frame_continues_and_exits_1(tmp_path: Path) -> None:
    video = make_video(tmp_path / "clip.avi", 10)
    data = bytearray(video.read_bytes())
    soi = [i for i in range(len(data) - 1) if data[i] == 0xFF and data[i + 1] == 0xD8]
    data[soi[4] : soi[4] + 200] = bytes(200)  # frame 4's JPEG (about 300 bytes) destroyed
    video.write_bytes(bytes(data))
    res = runner.invoke(app, ["enhance", str(video), "--out", str(tmp_path / "out" / "enh.avi")])
    assert res.exit_code == 1, res.output
    assert "9 frames processed" in _out(res) and "1 failed" in _out(res)
    assert len(read_video(tmp_path / "out" / "enh.avi")) == 10  # the broken frame is replaced, timing kept
    (record,) = read_jsonl(tmp_path / "out" / "errors.jsonl")
    assert record["frame"] == 4 and record["stage"] == "read" and record["input"] == str(video)


def test_bombs_are_recorded_and_the_batch_goes_on(folder: Path, tmp_path: Path) -> None:
    """Decompression bombs next to good images: exit 1, each bomb named in errors.jsonl, the good ones written;
    `murk --max-pixels` lowers the limit for any command."""
    from tests.io._bombs import jpeg_bomb, png_bomb

    png_bomb(folder / "bomb.png")
    jpeg_bomb(folder / "bomb2.jpg")
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(tmp_path / "out"), "--format", "png"])
    assert res.exit_code == 1, res.output
    records = read_jsonl(tmp_path / "out" / "errors.jsonl")
    assert sorted(Path(r["input"]).name for r in records) == ["bomb.png", "bomb2.jpg"]
    assert all("over the limit" in r["error"] for r in records)
    assert (tmp_path / "out" / "a.png").is_file()  # the good image next to the bombs
    res = runner.invoke(app, ["--max-pixels", "100", "enhance", str(folder / "a.png"), "--out", str(tmp_path / "o2")])
    assert res.exit_code == 1 and "1 failed" in _out(res)
    (record,) = read_jsonl(tmp_path / "o2" / "errors.jsonl")
    assert "declares 32x24 = 768 pixels, over the limit of 100" in record["error"]


@pytest.mark.parametrize("value", ["abc", "0"])
def test_a_bad_pixel_limit_in_the_environment_is_a_usage_error(
    folder: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, value: str
) -> None:
    monkeypatch.setenv("MURK_MAX_PIXELS", value)
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(tmp_path / "out")])
    assert res.exit_code == 2 and f"MURK_MAX_PIXELS: expected a positive integer, got '{value}'" in _out(res)
    assert not (tmp_path / "out").exists()  # refused before any image was read, nothing recorded as failed


def test_method_options_in_the_spec_and_misspelt_ones(folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "o"
    res = runner.invoke(app, ["enhance", str(folder), "-o", str(out), "-r", "-m", "post?lam=0.5,he=rgb"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(app, ["enhance", str(folder), "-o", str(tmp_path / "o2"), "-m", "post?lamda=0.9"])
    assert res.exit_code == 2 and "unknown option 'lamda' (did you mean 'lam'?)" in _out(res)
    assert not (tmp_path / "o2").exists()


def test_a_flag_the_method_does_not_take_is_an_error(folder: Path, tmp_path: Path) -> None:
    from murk.io import read_rgb

    res = runner.invoke(
        app, ["enhance", str(folder), "-o", str(tmp_path / "o1"), "-r", "-m", "lite", "--lambda", "0.5"]
    )
    assert res.exit_code == 2, res.output
    assert "--lambda is an option of post, not of the method 'lite'" in _out(res) and "'lite+post'" in _out(res)
    assert not (tmp_path / "o1").exists()
    res = runner.invoke(app, ["enhance", str(folder), "-o", str(tmp_path / "o2"), "-m", "post", "--tile", "256"])
    assert res.exit_code == 2 and "--tile is an option of jointid" in _out(res), res.output
    # The flag reaches the stage that takes it: --lambda 0.5 equals the spec's own option.
    a, b = tmp_path / "a", tmp_path / "b"
    assert (
        runner.invoke(app, ["enhance", str(folder), "-o", str(a), "-r", "-m", "post", "--lambda", "0.5"]).exit_code == 0
    )
    assert runner.invoke(app, ["enhance", str(folder), "-o", str(b), "-r", "-m", "post?lam=0.5"]).exit_code == 0
    c = tmp_path / "c"
    assert runner.invoke(app, ["enhance", str(folder), "-o", str(c), "-r", "-m", "post"]).exit_code == 0
    files = sorted(p.relative_to(a) for p in a.rglob("*.png"))
    assert files and files == sorted(p.relative_to(b) for p in b.rglob("*.png"))
    assert all((read_rgb(a / f) == read_rgb(b / f)).all() for f in files)
    assert any((read_rgb(a / f) != read_rgb(c / f)).any() for f in files)  # the default lambda (0.3) differs


def test_the_default_method_is_lite(folder: Path, tmp_path: Path) -> None:
    from murk.io import read_rgb

    runs = {"default": [], "lite": ["-m", "lite"], "post": ["-m", "post"]}
    for name, extra in runs.items():
        res = runner.invoke(app, ["enhance", str(folder), "-o", str(tmp_path / name), "-r", *extra])
        assert res.exit_code == 0, res.output
    files = sorted(p.relative_to(tmp_path / "default") for p in (tmp_path / "default").rglob("*.png"))
    assert files and files == sorted(p.relative_to(tmp_path / "lite") for p in (tmp_path / "lite").rglob("*.png"))
    assert all((read_rgb(tmp_path / "default" / f) == read_rgb(tmp_path / "lite" / f)).all() for f in files)
    assert any((read_rgb(tmp_path / "default" / f) != read_rgb(tmp_path / "post" / f)).any() for f in files)
    # post's flags without a method name the chain that takes them.
    res = runner.invoke(app, ["enhance", str(folder), "-o", str(tmp_path / "x"), "--lambda", "0.5"])
    assert res.exit_code == 2 and "not of the method 'lite'" in _out(res) and "'lite+post'" in _out(res)


def test_temporal_flag_reaches_post_for_videos_only(folder: Path, tmp_path: Path) -> None:
    video = make_video(tmp_path / "clip.avi", 8, fps=8.0)
    runs = {
        "flag": ["-m", "post", "--temporal", "0.8"],
        "spec": ["-m", "post?temporal=0.8"],
        "plain": ["-m", "post"],
    }
    for name, extra in runs.items():
        res = runner.invoke(app, ["enhance", str(video), "-o", str(tmp_path / name), "--format", "png", *extra])
        assert res.exit_code == 0, res.output
    frames = {n: [cv2.imread(str(p)) for p in sorted((tmp_path / n).rglob("*.png"))] for n in runs}
    assert len(frames["flag"]) == 8
    assert all((a == b).all() for a, b in zip(frames["flag"], frames["spec"], strict=True))
    assert (frames["flag"][0] == frames["plain"][0]).all()  # the first frame has no history
    assert any((a != b).any() for a, b in zip(frames["flag"][1:], frames["plain"][1:], strict=True))
    res = runner.invoke(app, ["enhance", str(folder), "-o", str(tmp_path / "j"), "-m", "jointid", "--temporal", "0.8"])
    assert res.exit_code == 2 and "--temporal is an option of" in _out(res), res.output
    res = runner.invoke(
        app, ["enhance", str(video), "-o", str(tmp_path / "c"), "-m", "post", "--he", "clahe", "--temporal", "0.5"]
    )
    assert res.exit_code == 2 and "CLAHE" in _out(res), res.output
