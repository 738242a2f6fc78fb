"""``murk enhance`` on ROS bags (issue 17): bag -> bag round trips in ROS 1, ROS 2 MCAP and ROS 2 SQLite3, equality
with the file-based ``murk enhance`` of the same frames, stamps and frame ids, depth and copied topics, numbered
frames with ``frames.jsonl``, resume after a kill, and bad inputs."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("rosbags", reason="ROS bag support needs the optional 'ros' extra: pip install 'murk[ros]'")

from murk.cli.main import app
from murk.io import read_jsonl, rosbag_writer
from murk.io import rosbag as rosbag_mod
from murk.io.atomic import TMP_PREFIX
from murk.io.jobs import read_errors
from murk.io.ros_image import COMPRESSED_MSG, IMAGE_MSG, decode_image_msg

from .._rosbags import BagBuilder, frames, read_topic, stamp_ns, topic_types

runner = CliRunner()
FAMILIES = [("ros1", None), ("ros2", "mcap"), ("ros2", "sqlite3")]
N = 3


def _name(family: str, storage: str | None, stem: str) -> str:
    return f"{stem}.bag" if family == "ros1" else f"{stem}_{storage}"


def _make(tmp_path: Path, family: str, storage: str | None) -> Path:
    fr = frames(N)
    b = BagBuilder(tmp_path / _name(family, storage, "dive"), family, storage or "mcap")
    b.image("/cam/bgr", fr, "bgr8", frame_id="cam_bgr").image("/cam/rgb", fr, "rgb8").image("/cam/mono", fr, "mono8")
    b.compressed("/cam/image_raw/compressed", fr, frame_id="cam_jpg").camera_info("/cam/camera_info", N)
    return b.close()


@pytest.fixture(params=FAMILIES, ids=["ros1", "ros2-mcap", "ros2-sqlite3"])
def bag(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    return _make(tmp_path, *request.param)


def _enhance(*args: str | Path) -> object:
    return runner.invoke(app, ["enhance", *map(str, args), "--quiet"])


def _file_based(tmp_path: Path, suffix: str, encoder: str = ".png", grey: bool = False) -> list[np.ndarray]:
    """``murk enhance`` of the same frames stored as files (PNG: lossless; JPEG: the bag's compressed bytes)."""
    src = tmp_path / f"files{suffix}"
    src.mkdir()
    for i, rgb in enumerate(frames(N)):
        px = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY) if grey else np.ascontiguousarray(rgb[:, :, ::-1])
        ok, buf = cv2.imencode(encoder, px)
        assert ok
        (src / f"f{i}{encoder}").write_bytes(buf.tobytes())
    out = tmp_path / f"files_out{suffix}"
    res = _enhance(src, "--out", out)
    assert res.exit_code == 0, res.output
    return [cv2.imread(str(out / f"f{i}{encoder}"), cv2.IMREAD_COLOR)[:, :, ::-1] for i in range(N)]


@pytest.mark.parametrize("topic", ["/cam/bgr", "/cam/rgb", "/cam/mono"])
def test_raw_image_round_trip_equals_file_based_enhance(bag: Path, tmp_path: Path, topic: str) -> None:
    out = bag.with_name(_name("ros1" if bag.suffix else "ros2", bag.name.split("_")[-1], "restored"))
    res = _enhance(bag, "--topic", topic, "--out", out)
    assert res.exit_code == 0, res.output
    msgs = read_topic(out, f"{topic}/restored")
    src = read_topic(bag, topic)
    assert len(msgs) == len(src) == N
    assert [t for t, _ in msgs] == [t for t, _ in src]  # bag record times kept
    assert [m.header.stamp for _, m in msgs] == [m.header.stamp for _, m in src]
    assert [m.header.frame_id for _, m in msgs] == [m.header.frame_id for _, m in src]
    assert {m.encoding for _, m in msgs} == {topic.rsplit("/", 1)[-1] + "8"}
    expected = _file_based(tmp_path, topic.replace("/", "_"), grey=topic == "/cam/mono")
    for (_, m), ref in zip(msgs, expected, strict=True):
        got = decode_image_msg(m, IMAGE_MSG)
        if topic == "/cam/mono":  # grey stays grey: the luma of the restored colour frame
            ref = np.repeat(cv2.cvtColor(np.ascontiguousarray(ref), cv2.COLOR_RGB2GRAY)[:, :, None], 3, axis=2)
        assert np.array_equal(got, ref)
    assert not (out.parent / "errors.jsonl").exists()


def test_compressed_round_trip_copies_camera_info_and_equals_file_based(bag: Path, tmp_path: Path) -> None:
    ros2 = not bag.suffix
    out = tmp_path / ("restored" if ros2 else "restored.bag")
    res = _enhance(bag, "--topic", "/cam/image_raw/compressed", "--out", out, "--copy-topics", "camera_info")
    assert res.exit_code == 0, res.output
    assert topic_types(out) == {
        "/cam/image_raw/restored/compressed": COMPRESSED_MSG,
        "/cam/camera_info": "sensor_msgs/msg/CameraInfo",
    }
    msgs = read_topic(out, "/cam/image_raw/restored/compressed")
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in msgs] == [stamp_ns(i) for i in range(N)]
    assert {m.header.frame_id for _, m in msgs} == {"cam_jpg"} and "jpeg" in msgs[0][1].format
    info_in, info_out = read_topic(bag, "/cam/camera_info"), read_topic(out, "/cam/camera_info")
    assert [t for t, _ in info_out] == [t for t, _ in info_in] and len(info_out) == N
    expected = _file_based(tmp_path, "_jpg", ".jpg")  # same decoder, restorer and JPEG encoder (quality 95)
    for (_, m), ref in zip(msgs, expected, strict=True):
        assert np.array_equal(decode_image_msg(m, COMPRESSED_MSG), ref)
    if ros2:
        assert rosbag_mod.bag_storage(out) == rosbag_mod.bag_storage(bag)


def test_storage_option_and_depth_topic(tmp_path: Path, fake_depth_method: list[dict[str, object]]) -> None:
    bag = _make(tmp_path, "ros2", "mcap")
    out = tmp_path / "lite"
    res = _enhance(bag, "--topic", "/cam/rgb", "--out", out, "--storage", "sqlite3", "-m", "fakedepth")
    assert res.exit_code == 0, res.output
    assert rosbag_mod.bag_storage(out) == "sqlite3"
    depth = read_topic(out, "/cam/rgb/depth")
    assert len(depth) == N and depth[0][1].encoding == "32FC1" and depth[0][1].header.frame_id == "cam"
    d = np.frombuffer(bytes(depth[0][1].data), "<f4").reshape(depth[0][1].height, -1)
    assert d[0, 0] == pytest.approx(1.0) and d[-1, 0] == pytest.approx(4.0)  # metres, as the method returned
    res = _enhance(bag, "--topic", "/cam/rgb", "--out", tmp_path / "x.bag", "--storage", "mcap")
    assert res.exit_code == 2 and "a ROS 2 input gives a ROS 2 bag" in res.output


def test_rerun_skips_a_finished_bag_and_a_killed_run_leaves_no_bag(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    bag = _make(tmp_path, "ros1", None)
    out = tmp_path / "out" / "restored.bag"
    ref = tmp_path / "ref.bag"
    assert _enhance(bag, "--topic", "/cam/bgr", "--out", ref).exit_code == 0

    class Killed(BaseException):
        """Stands for SIGKILL: nothing after it runs (no abort, no cleanup)."""

    real_write = rosbag_writer.BagSink.write_image
    calls = {"n": 0}

    def dying_write(self: rosbag_writer.BagSink, *args: object, **kwargs: object) -> None:
        calls["n"] += 1
        if calls["n"] == 2:
            raise Killed
        real_write(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(rosbag_writer.BagSink, "write_image", dying_write)
    monkeypatch.setattr(rosbag_writer.BagSink, "abort", lambda self: None)
    with pytest.raises(Killed):
        from murk.enhance.bag import enhance_bag
        from murk.enhance.post import PostRestorer

        with rosbag_mod.BagSource(bag, "/cam/bgr") as src:
            enhance_bag(src, PostRestorer(), out)
    assert not out.exists()
    assert [p.name.startswith(TMP_PREFIX) for p in out.parent.iterdir()] == [True]  # only the temporary bag
    monkeypatch.undo()
    res = _enhance(bag, "--topic", "/cam/bgr", "--out", out)
    assert res.exit_code == 0 and "3 frames processed" in res.output
    assert [p.name for p in out.parent.iterdir()] == ["restored.bag"]  # the stale temporary was removed
    assert [m.data.tobytes() for _, m in read_topic(out, "/cam/bgr/restored")] == [
        m.data.tobytes() for _, m in read_topic(ref, "/cam/bgr/restored")
    ]
    before = out.stat().st_mtime_ns
    res = _enhance(bag, "--topic", "/cam/bgr", "--out", out)
    assert res.exit_code == 0 and "0 frames processed, 1 skipped" in " ".join(res.output.split())
    assert out.stat().st_mtime_ns == before
    res = _enhance(bag, "--topic", "/cam/bgr", "--out", out, "--overwrite")
    assert res.exit_code == 0 and "3 frames processed" in res.output and len(read_topic(out, "/cam/bgr/restored")) == N


def test_undecodable_frames_go_to_errors_jsonl_and_the_run_continues(tmp_path: Path) -> None:
    bag = BagBuilder(tmp_path / "b.bag", "ros1").compressed("/c/compressed", frames(4), broken=[1]).close()
    out = tmp_path / "o" / "r.bag"
    res = _enhance(bag, "--topic", "/c/compressed", "--out", out)
    assert res.exit_code == 1 and "1 failed" in res.output
    errors = read_errors(out.parent / "errors.jsonl")
    assert [(e.input, e.stage, e.frame) for e in errors] == [(f"{bag}:/c/compressed", "decode", 1)]
    msgs = read_topic(out, "/c/restored/compressed")
    assert [m.header.stamp.nanosec for _, m in msgs] == [stamp_ns(i) % 10**9 for i in (0, 2, 3)]


def test_numbered_frames_with_stamps_resume(tmp_path: Path) -> None:
    bag = _make(tmp_path, "ros2", "mcap")
    out = tmp_path / "frames"
    res = _enhance(bag, "--topic", "/cam/bgr", "--out", out, "--format", "png", "--every", "2")
    assert res.exit_code == 0, res.output
    rows = read_jsonl(out / "frames.jsonl")
    assert [r["file_name"] for r in rows] == ["dive_mcap_000000.png", "dive_mcap_000001.png"]
    assert [(r["message"], r["stamp_ns"], r["frame_id"]) for r in rows] == [
        (0, stamp_ns(0), "cam_bgr"),
        (2, stamp_ns(2), "cam_bgr"),
    ]
    (out / "dive_mcap_000001.png").unlink()
    (out / "frames.jsonl").unlink()
    res = _enhance(bag, "--topic", "/cam/bgr", "--out", out, "--format", "png", "--every", "2")
    assert res.exit_code == 0 and "1 frame processed, 1 skipped" in " ".join(res.output.split())
    assert read_jsonl(out / "frames.jsonl") == rows
    ros1 = _make(tmp_path, "ros1", None)  # ROS 1: any name without .bag is a folder of frames
    res = _enhance(ros1, "--topic", "/cam/rgb", "--out", tmp_path / "f1")
    assert res.exit_code == 0 and len(read_jsonl(tmp_path / "f1" / "frames.jsonl")) == N


def test_bad_inputs_are_one_clear_line(tmp_path: Path) -> None:
    bag = _make(tmp_path, "ros1", None)
    out = tmp_path / "o.bag"
    res = _enhance(bag, "--out", out)
    assert res.exit_code == 2 and "choose an image topic with --topic" in res.output and "/cam/bgr" in res.output
    res = _enhance(bag, "--topic", "/cam/camera_info", "--out", out)
    assert res.exit_code == 2 and "is not sensor_msgs/Image" in res.output
    res = _enhance(bag, "--topic", "/cam/bgr", "--out", out, "--copy-topics", "/nope")
    assert res.exit_code == 2 and "--copy-topics /nope: no such topic" in res.output
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"\x00" * 100)
    res = _enhance(junk, "--topic", "/cam", "--out", out)
    assert res.exit_code == 2 and "junk.bag: cannot read bag" in res.output and "Traceback" not in res.output
    res = _enhance(tmp_path / "frames_dir_does_not_exist", "--topic", "/cam", "--out", out)
    assert res.exit_code == 2 and "need a ROS bag" in res.output
    assert not out.exists()


def test_copy_all_topics_makes_a_self_contained_bag(tmp_path: Path) -> None:
    bag = _make(tmp_path, "ros1", None)
    out = tmp_path / "all.bag"
    res = _enhance(bag, "--topic", "/cam/rgb", "--out", out, "--copy-topics", "all", "--copy-topics", "camera_info")
    assert res.exit_code == 0, res.output
    assert topic_types(out) == {**topic_types(bag), "/cam/rgb/restored": IMAGE_MSG}
    assert [m.data.tobytes() for _, m in read_topic(out, "/cam/bgr")] == [
        m.data.tobytes() for _, m in read_topic(bag, "/cam/bgr")
    ]


def test_without_rosbags_the_error_says_how_to_install(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bag = _make(tmp_path, "ros1", None)
    monkeypatch.setattr(rosbag_mod, "rosbags_available", lambda: False)
    res = _enhance(bag, "--topic", "/cam/rgb", "--out", tmp_path / "o.bag")
    assert res.exit_code == 2 and "pip install 'murk[ros]'" in res.output


def test_temporal_averaging_runs_over_a_topic_as_over_a_video(tmp_path: Path) -> None:
    bag = _make(tmp_path, "ros2", "mcap")
    outs = {}
    for name, extra in {"plain": [], "temporal": ["--temporal", "0.8"]}.items():
        out = tmp_path / f"restored_{name}"
        res = _enhance(bag, "--topic", "/cam/rgb", "--out", out, *extra)
        assert res.exit_code == 0, res.output
        outs[name] = [decode_image_msg(m, IMAGE_MSG) for _, m in read_topic(out, "/cam/rgb/restored")]
        frames_out = tmp_path / f"frames_{name}"
        res = _enhance(bag, "--topic", "/cam/rgb", "--out", frames_out, "--format", "png", *extra)
        assert res.exit_code == 0, res.output
        as_frames = [cv2.imread(str(p))[:, :, ::-1] for p in sorted(frames_out.glob("*.png"))]
        assert all(np.array_equal(a, b) for a, b in zip(outs[name], as_frames, strict=True))  # bag == frames
    assert np.array_equal(outs["plain"][0], outs["temporal"][0])  # the topic's first frame has no history
    assert any(not np.array_equal(a, b) for a, b in zip(outs["plain"][1:], outs["temporal"][1:], strict=True))
