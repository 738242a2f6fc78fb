"""Writing ROS bags atomically (the optional ``ros`` extra): :class:`BagSink`.

A new bag of a family (ROS 1 ``.bag``; ROS 2 folder with MCAP or SQLite3 storage) is written under a temporary
``.murk-tmp-<hex>-<name>`` name in the output's folder and renamed onto the final name by :meth:`BagSink.close`;
:meth:`BagSink.abort` deletes it, and :func:`remove_stale_bags` deletes what a killed run left. A killed run
never leaves a half-written bag under the final name. Images are encoded by :func:`murk.io.ros_image.encode_pixels`;
depth maps are ``32FC1`` Images in metres; messages of another bag of the same family are copied as they are.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import uuid
from pathlib import Path
from typing import Any, Literal

import numpy as np

from murk.errors import OutputError
from murk.io.atomic import TMP_PREFIX, make_output_folder, no_space_as_error
from murk.io.ros_image import COMPRESSED_MSG, IMAGE_MSG, encode_pixels
from murk.io.rosbag import STORAGES, BagFamily, Storage, _require

ROS2_BAG_VERSION: Literal[8, 9] = 8
"""rosbag2 metadata version of written ROS 2 bags: the oldest one the rosbags writer offers (8 or 9), for the widest
compatibility with installed ROS 2 tools (not tested here against a ROS installation)."""


def temporary_bag_path(path: Path) -> Path:
    """A fresh temporary name for ``path`` in its folder (``.murk-tmp-<hex>-<name>``)."""
    return path.with_name(f"{TMP_PREFIX}{uuid.uuid4().hex[:12]}-{path.name}")


def remove_stale_bags(path: Path) -> int:
    """Delete temporary bags (files or folders) a killed run left for ``path``; return how many."""
    count = 0
    if not path.parent.is_dir():
        return 0
    for stale in path.parent.glob(f"{TMP_PREFIX}*-{path.name}"):
        _remove(stale)
        count += 1
    return count


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


class BagSink:
    """A new bag at ``path``, written under a temporary name and renamed there by :meth:`close`.

    ROS 1: ``path`` is a ``.bag`` file. ROS 2: ``path`` is a folder; ``storage`` is ``mcap`` or ``sqlite3``.
    The temporary bag of a ROS 2 output is ``<tmp folder>/<name>/`` so its storage file already has its final
    name (``<name>.mcap``); the inner folder is renamed onto ``path``.

    With ``overwrite``, an existing bag at ``path`` is replaced when the new one is complete.

    Raises:
        ValueError: ``path`` exists (without ``overwrite``), or a ROS 1 output without the ``.bag`` suffix.
    """

    def __init__(
        self, path: str | Path, family: BagFamily, storage: Storage | None = None, *, overwrite: bool = False
    ) -> None:
        _require()
        from rosbags.typesys import Stores, get_typestore

        self.path = Path(path)
        self.family = family
        self.overwrite = overwrite
        if self.path.exists() and not overwrite:
            raise ValueError(f"{self.path}: exists; pass --overwrite to replace it")
        if family == "ros1" and self.path.suffix != ".bag":
            raise ValueError(f"--out {self.path}: a ROS 1 bag needs the .bag suffix")
        if family == "ros2" and storage not in STORAGES:
            raise ValueError(f"storage: expected one of {', '.join(STORAGES)}, got {storage!r}")
        self.storage = storage if family == "ros2" else None
        self.typestore = get_typestore(Stores.ROS2_HUMBLE if family == "ros2" else Stores.ROS1_NOETIC)
        self._tmp = temporary_bag_path(self.path)
        self._connections: dict[str, Any] = {}
        self._seq: dict[str, int] = {}
        self.closed = False
        make_output_folder(self.path.parent)
        with no_space_as_error(self.path):
            if family == "ros1":
                from rosbags.rosbag1 import Writer as Writer1

                self._bag_path = self._tmp
                self._writer: Any = Writer1(self._bag_path)
            else:
                from rosbags.rosbag2 import StoragePlugin
                from rosbags.rosbag2 import Writer as Writer2

                self._tmp.mkdir()
                self._bag_path = self._tmp / self.path.name
                plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
                self._writer = Writer2(self._bag_path, version=ROS2_BAG_VERSION, storage_plugin=plugin)
            self._writer.open()

    def _connection(self, topic: str, msgtype: str) -> Any:
        conn = self._connections.get(topic)
        if conn is None:
            conn = self._writer.add_connection(topic, msgtype, typestore=self.typestore)
            self._connections[topic] = conn
        return conn

    def _serialize(self, msg: Any, msgtype: str) -> bytes:
        if self.family == "ros1":
            return bytes(self.typestore.serialize_ros1(msg, msgtype))
        return bytes(self.typestore.serialize_cdr(msg, msgtype))

    def _header(self, topic: str, stamp_ns: int, frame_id: str) -> Any:
        types = self.typestore.types
        stamp = types["builtin_interfaces/msg/Time"](sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000)
        if self.family == "ros1":
            seq = self._seq.get(topic, 0)
            self._seq[topic] = seq + 1
            return types["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame_id)
        return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def write_image(
        self,
        topic: str,
        rgb: np.ndarray,
        *,
        msgtype: str,
        encoding: str,
        stamp_ns: int,
        frame_id: str,
        log_time_ns: int,
        jpeg_quality: int = 95,
    ) -> None:
        """Write an RGB uint8/uint16 frame as a message like the input's (see :func:`encode_pixels`)."""
        enc, data, step = encode_pixels(rgb, msgtype, encoding, jpeg_quality=jpeg_quality)
        header = self._header(topic, stamp_ns, frame_id)
        types = self.typestore.types
        payload = np.frombuffer(data, dtype=np.uint8)
        if msgtype == COMPRESSED_MSG:
            msg = types[COMPRESSED_MSG](header=header, format=enc, data=payload)
        else:
            h, w = rgb.shape[:2]
            msg = types[IMAGE_MSG](
                header=header, height=h, width=w, encoding=enc, is_bigendian=0, step=step, data=payload
            )
        self.write_message(topic, msgtype, msg, log_time_ns)

    def write_depth(self, topic: str, depth_m: np.ndarray, *, stamp_ns: int, frame_id: str, log_time_ns: int) -> None:
        """Write a depth map as a ``32FC1`` Image in metres."""
        depth = np.ascontiguousarray(depth_m, dtype="<f4")
        h, w = depth.shape
        msg = self.typestore.types[IMAGE_MSG](
            header=self._header(topic, stamp_ns, frame_id),
            height=h,
            width=w,
            encoding="32FC1",
            is_bigendian=0,
            step=4 * w,
            data=np.frombuffer(depth.tobytes(), dtype=np.uint8),
        )
        self.write_message(topic, IMAGE_MSG, msg, log_time_ns)

    def write_message(self, topic: str, msgtype: str, msg: Any, log_time_ns: int) -> None:
        data = self._serialize(msg, msgtype)
        with no_space_as_error(self.path):
            self._writer.write(self._connection(topic, msgtype), int(log_time_ns), data)

    def copy(self, conn: Any, log_time_ns: int, data: bytes) -> None:
        """Copy a serialized message of another bag of the same family (its topic and type are kept)."""
        out = self._connections.get(conn.topic)
        if out is None:
            out = self._add_like(conn)
            self._connections[conn.topic] = out
        with no_space_as_error(self.path):
            self._writer.write(out, int(log_time_ns), data)

    def _add_like(self, conn: Any) -> Any:
        msgdef = getattr(getattr(conn, "msgdef", None), "data", None) or None
        digest = getattr(conn, "digest", None) or None
        if self.family == "ros1":
            callerid = getattr(getattr(conn, "ext", None), "callerid", None)
            if msgdef and digest:
                return self._writer.add_connection(
                    conn.topic, conn.msgtype, msgdef=msgdef, md5sum=digest, callerid=callerid
                )
            return self._writer.add_connection(conn.topic, conn.msgtype, typestore=self.typestore, callerid=callerid)
        qos = list(getattr(getattr(conn, "ext", None), "offered_qos_profiles", []) or [])
        if msgdef and digest:
            return self._writer.add_connection(
                conn.topic, conn.msgtype, msgdef=msgdef, rihs01=digest, offered_qos_profiles=qos
            )
        return self._writer.add_connection(conn.topic, conn.msgtype, typestore=self.typestore, offered_qos_profiles=qos)

    def close(self) -> Path:
        """Finish the bag and rename it onto its final name; returns the path.

        Raises:
            OutputError: no space left on the device (the temporary bag is deleted).
        """
        if self.closed:
            return self.path
        try:
            with no_space_as_error(self.path):
                self._writer.close()
                if self.path.exists() and self.overwrite:
                    _remove(self.path)
                if self.path.exists():
                    raise OutputError(17, "appeared while the bag was written; not replaced", str(self.path))
                os.replace(self._bag_path, self.path)
        except BaseException:
            self.abort()
            raise
        if self.family == "ros2":
            shutil.rmtree(self._tmp, ignore_errors=True)
        self.closed = True
        return self.path

    def abort(self) -> None:
        """Discard the temporary bag (nothing appears under the final name)."""
        with contextlib.suppress(Exception):
            self._writer.close()
        _remove(self._tmp)
        self.closed = True
