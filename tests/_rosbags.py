"""Small ROS 1 / ROS 2 bags built with ``rosbags`` itself (independently of murk's writer) for the bag tests.

Import only after ``pytest.importorskip("rosbags")``.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

T0_NS = 1_700_000_000_123_456_789
"""Header stamp of the first frame; frame i is stamped T0_NS + i * 100 ms, recorded 5 ms later."""


def frames(n: int, h: int = 24, w: int = 32) -> list[np.ndarray]:
    """Smooth, distinct uint8 RGB frames (the red level encodes the index)."""
    yy, xx = np.mgrid[0:h, 0:w]
    return [
        np.stack([np.full_like(xx, 30 + 20 * i), 40 + 4 * xx, 60 + 5 * yy], axis=-1).astype(np.uint8) for i in range(n)
    ]


def stamp_ns(i: int) -> int:
    return T0_NS + i * 100_000_000


def _raw(rgb: np.ndarray, encoding: str) -> tuple[np.ndarray, int]:
    if encoding == "rgb8":
        px = rgb
    elif encoding == "bgr8":
        px = rgb[:, :, ::-1]
    elif encoding == "mono8":
        px = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    elif encoding in ("mono16", "16UC1"):
        px = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY).astype("<u2") * 257
    elif encoding == "bayer_rggb8":
        px = np.zeros(rgb.shape[:2], np.uint8)
        px[0::2, 0::2] = rgb[0::2, 0::2, 0]
        px[0::2, 1::2] = rgb[0::2, 1::2, 1]
        px[1::2, 0::2] = rgb[1::2, 0::2, 1]
        px[1::2, 1::2] = rgb[1::2, 1::2, 2]
    else:  # an encoding murk does not read, with plausible bytes
        px = rgb
    px = np.ascontiguousarray(px)
    return np.frombuffer(px.tobytes(), np.uint8), px.nbytes // rgb.shape[0]


class BagBuilder:
    """Write a bag of the given family/storage; call :meth:`image`, :meth:`compressed`, :meth:`camera_info`."""

    def __init__(self, path: Path, family: str = "ros1", storage: str = "mcap") -> None:
        self.path, self.family = path, family
        self.ts = get_typestore(Stores.ROS1_NOETIC if family == "ros1" else Stores.ROS2_HUMBLE)
        if family == "ros1":
            self.writer = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            self.writer = Writer2(path, version=8, storage_plugin=plugin)
        self.writer.open()
        self.conns: dict[str, object] = {}

    def _write(self, topic: str, msgtype: str, msg: object, t_ns: int) -> None:
        if topic not in self.conns:
            self.conns[topic] = self.writer.add_connection(topic, msgtype, typestore=self.ts)
        ser = self.ts.serialize_ros1 if self.family == "ros1" else self.ts.serialize_cdr
        self.writer.write(self.conns[topic], t_ns, ser(msg, msgtype))

    def header(self, i: int, frame_id: str) -> object:
        t = stamp_ns(i)
        stamp = self.ts.types["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9)
        if self.family == "ros1":
            return self.ts.types["std_msgs/msg/Header"](seq=i, stamp=stamp, frame_id=frame_id)
        return self.ts.types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def image(self, topic: str, images: Sequence[np.ndarray], encoding: str, frame_id: str = "cam") -> BagBuilder:
        Image = self.ts.types["sensor_msgs/msg/Image"]
        for i, rgb in enumerate(images):
            data, step = _raw(rgb, encoding)
            h, w = rgb.shape[:2]
            msg = Image(
                header=self.header(i, frame_id),
                height=h,
                width=w,
                encoding=encoding,
                is_bigendian=0,
                step=step,
                data=data,
            )
            self._write(topic, "sensor_msgs/msg/Image", msg, stamp_ns(i) + 5_000_000)
        return self

    def compressed(
        self,
        topic: str,
        images: Sequence[np.ndarray],
        fmt: str = "jpeg",
        frame_id: str = "cam",
        broken: Sequence[int] = (),
    ) -> BagBuilder:
        Compressed = self.ts.types["sensor_msgs/msg/CompressedImage"]
        for i, rgb in enumerate(images):
            ok, buf = cv2.imencode(".jpg" if fmt == "jpeg" else ".png", np.ascontiguousarray(rgb[:, :, ::-1]))
            assert ok
            data = np.frombuffer(buf.tobytes() if i not in broken else b"not an image", np.uint8)
            msg = Compressed(header=self.header(i, frame_id), format=fmt, data=data)
            self._write(topic, "sensor_msgs/msg/CompressedImage", msg, stamp_ns(i) + 5_000_000)
        return self

    def camera_info(self, topic: str, n: int, frame_id: str = "cam", h: int = 24, w: int = 32) -> BagBuilder:
        Info = self.ts.types["sensor_msgs/msg/CameraInfo"]
        Roi = self.ts.types["sensor_msgs/msg/RegionOfInterest"]
        f64 = np.float64
        for i in range(n):
            kw = dict(
                header=self.header(i, frame_id),
                height=h,
                width=w,
                distortion_model="plumb_bob",
                roi=Roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
                binning_x=0,
                binning_y=0,
            )
            if self.family == "ros1":
                kw.update(
                    D=np.zeros(5, f64),
                    K=np.eye(3, dtype=f64).ravel(),
                    R=np.eye(3, dtype=f64).ravel(),
                    P=np.zeros(12, f64),
                )
            else:
                kw.update(
                    d=np.zeros(5, f64),
                    k=np.eye(3, dtype=f64).ravel(),
                    r=np.eye(3, dtype=f64).ravel(),
                    p=np.zeros(12, f64),
                )
            self._write(topic, "sensor_msgs/msg/CameraInfo", Info(**kw), stamp_ns(i) + 6_000_000)
        return self

    def string(self, topic: str, n: int) -> BagBuilder:
        String = self.ts.types["std_msgs/msg/String"]
        for i in range(n):
            self._write(topic, "std_msgs/msg/String", String(data=f"m{i}"), stamp_ns(i))
        return self

    def empty(self, topic: str, msgtype: str = "sensor_msgs/msg/Image") -> BagBuilder:
        """A topic with a connection and no message."""
        self.conns[topic] = self.writer.add_connection(topic, msgtype, typestore=self.ts)
        return self

    def close(self) -> Path:
        self.writer.close()
        return self.path


def read_topic(path: Path, topic: str) -> list[tuple[int, object]]:
    """(log time, deserialised message) of every message on ``topic``, in bag order."""
    ts = get_typestore(Stores.ROS2_HUMBLE if path.is_dir() else Stores.ROS1_NOETIC)
    with AnyReader([path], default_typestore=ts) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [(t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages(connections=conns)]


def topic_types(path: Path) -> dict[str, str]:
    ts = get_typestore(Stores.ROS2_HUMBLE if path.is_dir() else Stores.ROS1_NOETIC)
    with AnyReader([path], default_typestore=ts) as reader:
        return {c.topic: c.msgtype for c in reader.connections}
