"""ROS bag reading and writing (issue 17): topics, encodings, stamps, bad bags, the atomic writer.

Bags are built with ``rosbags`` itself (tests/_rosbags.py), independently of murk's writer.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

pytest.importorskip("rosbags", reason="ROS bag support needs the optional 'ros' extra: pip install 'murk[ros]'")

from murk.errors import InputFileError
from murk.io.atomic import TMP_PREFIX
from murk.io.ros_image import IMAGE_MSG, decode_image_msg
from murk.io.rosbag import BagSource, bag_family, bag_storage, image_topics, is_bag, list_topics
from murk.io.rosbag_writer import BagSink

from .._rosbags import BagBuilder, frames, read_topic, stamp_ns, topic_types

FAMILIES = [("ros1", None), ("ros2", "mcap"), ("ros2", "sqlite3")]
N = 3


def _bag_path(tmp_path: Path, family: str, storage: str | None, name: str = "dive") -> Path:
    return tmp_path / (f"{name}.bag" if family == "ros1" else f"{name}_{storage}")


@pytest.fixture(params=FAMILIES, ids=["ros1", "ros2-mcap", "ros2-sqlite3"])
def bag(request: pytest.FixtureRequest, tmp_path: Path) -> Path:
    family, storage = request.param
    path = _bag_path(tmp_path, family, storage)
    fr = frames(N)
    b = BagBuilder(path, family, storage or "mcap")
    for enc in ("bgr8", "rgb8", "mono8", "16UC1", "bayer_rggb8"):
        b.image(f"/cam/{enc}", fr, enc, frame_id=f"cam_{enc}")
    b.compressed("/cam/image_raw/compressed", fr).camera_info("/cam/camera_info", N).empty("/cam/empty")
    b.image("/cam/yuv", fr, "yuv422").string("/log", 2)
    return b.close()


def test_what_a_path_is(bag: Path, tmp_path: Path) -> None:
    assert is_bag(bag) and not is_bag(tmp_path / "nothing.bag") and not is_bag(tmp_path)
    assert bag_family(bag) == ("ros1" if bag.suffix == ".bag" else "ros2")
    assert bag_storage(bag) == (None if bag.suffix == ".bag" else bag.name.split("_")[-1])


def test_image_topics_are_listed_with_counts(bag: Path) -> None:
    names = {t.name: t for t in image_topics(bag)}
    assert set(names) == {f"/cam/{e}" for e in ("bgr8", "rgb8", "mono8", "16UC1", "bayer_rggb8", "yuv", "empty")} | {
        "/cam/image_raw/compressed"
    }
    assert names["/cam/bgr8"].count == N and names["/cam/empty"].count == 0
    assert {t.name for t in list_topics(bag)} >= {"/cam/camera_info", "/log"}


def test_frames_carry_header_stamps_frame_ids_and_record_times(bag: Path) -> None:
    with BagSource(bag, "/cam/bgr8") as src:
        got = list(src)
        assert src.end_reason == "end" and src.frame_count == N and src.msgtype == IMAGE_MSG
    assert [f.index for f in got] == list(range(N))
    assert [f.stamp_ns for f in got] == [stamp_ns(i) for i in range(N)]
    assert [f.log_time_ns for f in got] == [stamp_ns(i) + 5_000_000 for i in range(N)]
    assert {f.frame_id for f in got} == {"cam_bgr8"}


@pytest.mark.parametrize("encoding", ["bgr8", "rgb8"])
def test_colour_encodings_decode_exactly(bag: Path, encoding: str) -> None:
    with BagSource(bag, f"/cam/{encoding}") as src:
        got = [f.image for f in src]
    for g, ref in zip(got, frames(N), strict=True):
        assert g is not None and g.dtype == np.uint8 and np.array_equal(g, ref)


def test_grey_16bit_bayer_and_jpeg_decode(bag: Path) -> None:
    ref = frames(N)
    with BagSource(bag, "/cam/mono8") as src:
        mono = [f.image for f in src]
    grey = cv2.cvtColor(ref[1], cv2.COLOR_RGB2GRAY)
    assert np.array_equal(mono[1], np.repeat(grey[:, :, None], 3, axis=2))
    with BagSource(bag, "/cam/16UC1") as src:
        deep = next(iter(src)).image
    assert deep is not None and deep.dtype == np.uint16
    assert np.array_equal(deep[:, :, 0], cv2.cvtColor(ref[0], cv2.COLOR_RGB2GRAY).astype(np.uint16) * 257)
    with BagSource(bag, "/cam/bayer_rggb8") as src:
        bayer = [f.image for f in src]
    # the frames are smooth: demosaicing restores them closely away from the border (and red stays red)
    diff = np.abs(bayer[2][2:-2, 2:-2].astype(int) - ref[2][2:-2, 2:-2].astype(int))
    assert diff.max() <= 6
    with BagSource(bag, "/cam/image_raw/compressed") as src:
        jpeg = [f.image for f in src]
    ok, buf = cv2.imencode(".jpg", np.ascontiguousarray(ref[0][:, :, ::-1]))
    assert ok and np.array_equal(jpeg[0], cv2.imdecode(buf, cv2.IMREAD_COLOR)[:, :, ::-1])


def test_every_nth_message(bag: Path) -> None:
    with BagSource(bag, "/cam/rgb8", every=2) as src:
        got = list(src)
        assert src.frame_count == 2
    assert [f.message for f in got] == [0, 2] and [f.index for f in got] == [0, 1]
    assert [f.stamp_ns for f in got] == [stamp_ns(0), stamp_ns(2)]


def test_topic_errors_name_the_bag_and_list_image_topics(bag: Path) -> None:
    with pytest.raises(InputFileError, match=r"choose an image topic with --topic; image topics: .*/cam/bgr8"):
        BagSource(bag, None)
    with pytest.raises(InputFileError, match=r"topic '/cam/nope' not found; image topics: .*/cam/rgb8 \("):
        BagSource(bag, "/cam/nope")
    with pytest.raises(InputFileError, match=r"topic /cam/camera_info: message type sensor_msgs/msg/CameraInfo is not"):
        BagSource(bag, "/cam/camera_info")
    with pytest.raises(InputFileError, match=r"topic /cam/empty holds no messages"):
        BagSource(bag, "/cam/empty")
    with pytest.raises(InputFileError, match=r"topic /cam/yuv: encoding 'yuv422' is not supported") as info:
        BagSource(bag, "/cam/yuv")
    assert str(bag) in str(info.value)


def test_corrupt_and_truncated_bags_are_named(tmp_path: Path) -> None:
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\n" + b"\x00garbage" * 50)
    with pytest.raises(InputFileError, match=r"junk\.bag: cannot read bag"):
        BagSource(junk, "/cam")
    full = BagBuilder(tmp_path / "full.bag", "ros1").image("/cam", frames(4), "rgb8").close()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(full.read_bytes()[: full.stat().st_size // 2])
    with pytest.raises(InputFileError, match=r"cut\.bag: cannot read bag"):
        BagSource(cut, "/cam")
    folder = BagBuilder(tmp_path / "r2", "ros2", "mcap").image("/cam", frames(4), "rgb8").close()
    mcap = next(folder.glob("*.mcap"))
    mcap.write_bytes(mcap.read_bytes()[: mcap.stat().st_size // 2])
    with pytest.raises(InputFileError, match=r"r2: cannot read bag"):
        BagSource(folder, "/cam")
    with pytest.raises(InputFileError, match=r"missing\.bag: not found"):
        BagSource(tmp_path / "missing.bag", "/cam")


def test_a_broken_message_is_a_broken_frame(tmp_path: Path) -> None:
    path = BagBuilder(tmp_path / "b.bag", "ros1").compressed("/c", frames(4), broken=[2]).close()
    with BagSource(path, "/c") as src:
        got = list(src)
    assert [f.image is None for f in got] == [False, False, True, False]
    assert got[2].error == "compressed image data could not be decoded" and got[2].stamp_ns == stamp_ns(2)


@pytest.mark.parametrize(("family", "storage"), FAMILIES)
def test_sink_writes_a_readable_bag_atomically(tmp_path: Path, family: str, storage: str | None) -> None:
    out = _bag_path(tmp_path, family, storage, "out")
    sink = BagSink(out, family, storage)  # type: ignore[arg-type]
    assert not out.exists() and [p.name for p in tmp_path.iterdir() if p.name.startswith(TMP_PREFIX)]
    for i, rgb in enumerate(frames(2)):
        kw = {"stamp_ns": stamp_ns(i), "frame_id": "f", "log_time_ns": stamp_ns(i) + 1}
        sink.write_image("/a", rgb, msgtype=IMAGE_MSG, encoding="bgr8", **kw)
        sink.write_image("/g", rgb, msgtype=IMAGE_MSG, encoding="mono8", **kw)
        sink.write_depth("/d", np.full(rgb.shape[:2], 2.5, np.float32), **kw)
    assert sink.close() == out and out.exists()
    assert [p.name for p in tmp_path.iterdir()] == [out.name]
    assert topic_types(out) == {"/a": IMAGE_MSG, "/g": IMAGE_MSG, "/d": IMAGE_MSG}
    msgs = read_topic(out, "/a")
    assert [t for t, _ in msgs] == [stamp_ns(0) + 1, stamp_ns(1) + 1]
    assert msgs[1][1].encoding == "bgr8" and np.array_equal(decode_image_msg(msgs[1][1], IMAGE_MSG), frames(2)[1])
    grey = read_topic(out, "/g")[0][1]
    assert grey.encoding == "mono8" and grey.step == grey.width
    depth = read_topic(out, "/d")[0][1]
    assert depth.encoding == "32FC1" and np.all(np.frombuffer(bytes(depth.data), "<f4") == 2.5)
    if family == "ros2":
        names = sorted(p.name for p in out.iterdir())  # the storage file is named after the bag, not the temporary
        assert names[0] == "metadata.yaml" and names[1].startswith(f"{out.name}.") and len(names) == 2


def test_sink_abort_leaves_nothing(tmp_path: Path) -> None:
    sink = BagSink(tmp_path / "x.bag", "ros1")
    sink.write_image("/a", frames(1)[0], msgtype=IMAGE_MSG, encoding="rgb8", stamp_ns=1, frame_id="", log_time_ns=1)
    sink.abort()
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ValueError, match=r"needs the \.bag suffix"):
        BagSink(tmp_path / "x", "ros1")


@pytest.mark.parametrize(
    ("encoding", "written"),
    [("bgr8", "bgr8"), ("rgb8", "rgb8"), ("bgra8", "bgr8"), ("mono8", "mono8"), ("16UC1", "16UC1"),
     ("mono16", "mono16"), ("bayer_rggb8", "rgb8"), ("8UC3", "8UC3")],
)  # fmt: skip
def test_encodings_keep_their_family(encoding: str, written: str) -> None:
    from types import SimpleNamespace

    from murk.io.ros_image import encode_pixels, output_bits

    bits = output_bits(IMAGE_MSG, encoding)
    rgb = frames(1)[0].astype(np.uint16) * 257 if bits == 16 else frames(1)[0]
    enc, data, step = encode_pixels(rgb, IMAGE_MSG, encoding)
    assert enc == written and step * rgb.shape[0] == len(data)
    msg = SimpleNamespace(
        encoding=enc,
        height=rgb.shape[0],
        width=rgb.shape[1],
        step=step,
        is_bigendian=0,
        data=np.frombuffer(data, np.uint8),
    )
    back = decode_image_msg(msg, IMAGE_MSG)
    assert back.dtype == rgb.dtype
    if written.startswith("mono") or written == "16UC1":
        grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
        assert np.array_equal(back, np.repeat(grey[:, :, None], 3, axis=2))
    else:
        assert np.array_equal(back, rgb)


def test_big_endian_16bit_and_row_padding_decode() -> None:
    from types import SimpleNamespace

    grey = (np.arange(6 * 5, dtype=np.uint16).reshape(6, 5) * 2000).astype(">u2")
    padded = np.zeros((6, 12), np.uint8)  # step 12 bytes for 10 bytes of pixels per row
    padded[:, :10] = np.frombuffer(grey.tobytes(), np.uint8).reshape(6, 10)
    msg = SimpleNamespace(encoding="mono16", height=6, width=5, step=12, is_bigendian=1, data=padded.ravel())
    assert np.array_equal(decode_image_msg(msg, IMAGE_MSG)[:, :, 1], grey.astype(np.uint16))
    short = SimpleNamespace(encoding="rgb8", height=6, width=5, step=15, is_bigendian=0, data=np.zeros(50, np.uint8))
    with pytest.raises(ValueError, match=r"rgb8 5x6: 50 bytes of data with step 15"):
        decode_image_msg(short, IMAGE_MSG)
