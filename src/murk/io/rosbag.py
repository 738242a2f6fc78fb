"""ROS 1 and ROS 2 bags at the I/O edge: image topics in, image topics out (the optional ``ros`` extra).

Reading and writing use the pure-Python ``rosbags`` library (Apache-2.0; no ROS installation needed):
ROS 1 ``.bag`` files and ROS 2 bag folders (``metadata.yaml`` plus MCAP or SQLite3 storage).

- :func:`is_bag`, :func:`bag_family`, :func:`bag_storage`: what a path is.
- :func:`list_topics`, :func:`image_topics`: the topics of a bag (name, message type, message count).
- :class:`BagSource`: a :class:`murk.io.video.FrameSource` over one image topic (``sensor_msgs/Image`` or
  ``sensor_msgs/CompressedImage``), optionally every N-th message. Frames are :class:`BagFrame` objects: RGB
  uint8 (or uint16 for 16-bit encodings) plus the message's header stamp, frame id and bag log time. A message
  that cannot be decoded is yielded with ``image=None`` and an ``error`` (the caller records it and carries on).
- :class:`BagSink`: writes a new bag of the same family (ROS 1 -> ROS 1, ROS 2 -> ROS 2 with MCAP or SQLite3
  storage) atomically: everything goes to a ``.murk-tmp-`` name in the output's folder that :meth:`BagSink.close`
  renames onto the final name; :meth:`BagSink.abort` deletes it. A killed run leaves no bag under the final name.
- :func:`decode_image_msg` / :func:`encode_image_msg`: the encoding conversions. Raw ``Image`` encodings:
  ``rgb8``, ``bgr8``, ``rgba8``, ``bgra8``, ``mono8``, ``8UC1``, ``8UC3`` (BGR), ``mono16``, ``16UC1``,
  ``rgb16``, ``bgr16``, ``bayer_{rggb,bggr,gbrg,grbg}8`` (demosaiced). ``CompressedImage``: JPEG and PNG.
  A restored frame is written in the input's family: an ``Image`` stays an ``Image`` (colour stays in its channel
  order, grey stays grey, 16-bit stays 16-bit; Bayer becomes ``rgb8``), a ``CompressedImage`` stays compressed in
  the same format. Depth maps are written as ``32FC1`` images in metres.

Errors: a missing, corrupt or truncated bag, an unknown topic (the image topics are listed), a topic of another
message type, an encoding murk cannot convert (named), or a topic with no messages raise
:class:`murk.errors.InputFileError` naming the bag (and topic).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import uuid
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import cv2
import numpy as np

from murk.errors import InputFileError, OutputError
from murk.io.atomic import TMP_PREFIX, no_space_as_error
from murk.io.video import Frame, FrameSource

BagFamily = Literal["ros1", "ros2"]
Storage = Literal["mcap", "sqlite3"]
STORAGES: tuple[str, ...] = ("mcap", "sqlite3")
IMAGE_MSG = "sensor_msgs/msg/Image"
COMPRESSED_MSG = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO_MSG = "sensor_msgs/msg/CameraInfo"
IMAGE_MSGTYPES = (IMAGE_MSG, COMPRESSED_MSG)
INSTALL_HINT = "ROS bags need the optional 'ros' extra: pip install 'murk[ros]'"
ROS2_BAG_VERSION = 8
"""rosbag2 metadata version of written ROS 2 bags: the oldest one the rosbags writer offers (8 or 9), for the widest
compatibility with installed ROS 2 tools (not tested here against a ROS installation)."""

# raw Image encodings -> (channels, bytes per sample, how to make RGB)
_RAW: dict[str, tuple[int, int, str]] = {
    "rgb8": (3, 1, "rgb"),
    "bgr8": (3, 1, "bgr"),
    "8UC3": (3, 1, "bgr"),
    "rgba8": (4, 1, "rgba"),
    "bgra8": (4, 1, "bgra"),
    "8UC4": (4, 1, "bgra"),
    "mono8": (1, 1, "mono"),
    "8UC1": (1, 1, "mono"),
    "rgb16": (3, 2, "rgb"),
    "bgr16": (3, 2, "bgr"),
    "16UC3": (3, 2, "bgr"),
    "rgba16": (4, 2, "rgba"),
    "bgra16": (4, 2, "bgra"),
    "mono16": (1, 2, "mono"),
    "16UC1": (1, 2, "mono"),
    # ROS names the first 2x2 block; OpenCV names the second row's pattern (as cv_bridge maps them)
    "bayer_rggb8": (1, 1, "bayer_bg"),
    "bayer_bggr8": (1, 1, "bayer_rg"),
    "bayer_gbrg8": (1, 1, "bayer_gr"),
    "bayer_grbg8": (1, 1, "bayer_gb"),
}
_BAYER = {
    "bayer_bg": cv2.COLOR_BayerBG2RGB,
    "bayer_rg": cv2.COLOR_BayerRG2RGB,
    "bayer_gr": cv2.COLOR_BayerGR2RGB,
    "bayer_gb": cv2.COLOR_BayerGB2RGB,
}
# encoding of the restored frame for each input encoding
_OUT_ENCODING = {
    "rgba8": "rgb8",
    "bgra8": "bgr8",
    "8UC4": "bgr8",
    "rgba16": "rgb16",
    "bgra16": "bgr16",
    **{k: "rgb8" for k in _RAW if k.startswith("bayer_")},
}
SUPPORTED_ENCODINGS = tuple(_RAW)


def rosbags_available() -> bool:
    """True when the optional ``rosbags`` package is installed."""
    try:
        import rosbags  # noqa: F401
    except ImportError:
        return False
    return True


def _require() -> None:
    """Raises ValueError (a clean one-line CLI error) when ``rosbags`` is missing."""
    if not rosbags_available():
        raise ValueError(INSTALL_HINT)


# ----------------------------------------------------------------------------------------------------------
# What a path is
# ----------------------------------------------------------------------------------------------------------


def is_bag(path: str | Path) -> bool:
    """True for a ROS 1 bag (a ``.bag`` file) or a ROS 2 bag (a folder holding ``metadata.yaml``)."""
    p = Path(path)
    return (p.suffix.lower() == ".bag" and p.is_file()) or (p.is_dir() and (p / "metadata.yaml").is_file())


def bag_family(path: str | Path) -> BagFamily:
    """``ros1`` for a ``.bag`` file, ``ros2`` for a bag folder."""
    return "ros2" if Path(path).is_dir() else "ros1"


def bag_storage(path: str | Path) -> Storage | None:
    """The storage of a ROS 2 bag (``mcap`` or ``sqlite3``, from ``metadata.yaml``); None for ROS 1.

    Raises:
        InputFileError: ``metadata.yaml`` cannot be parsed or names another storage.
    """
    p = Path(path)
    if bag_family(p) == "ros1":
        return None
    import yaml

    try:
        meta = yaml.safe_load((p / "metadata.yaml").read_text(encoding="utf-8"))
        ident = str(meta["rosbag2_bagfile_information"]["storage_identifier"]).lower()
    except (OSError, yaml.YAMLError, KeyError, TypeError) as exc:
        raise InputFileError(p, f"cannot read metadata.yaml ({type(exc).__name__}: {exc})") from None
    if ident not in STORAGES:
        raise InputFileError(p, f"storage {ident!r} is not supported (expected one of {', '.join(STORAGES)})")
    return ident  # type: ignore[return-value]


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag."""

    name: str
    msgtype: str
    count: int


def _open_reader(path: Path) -> Any:
    """An opened ``AnyReader`` on ``path``; a missing, corrupt or truncated bag raises InputFileError."""
    _require()
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    if not is_bag(path):
        what = (
            "not found" if not path.exists() else "not a bag (a ROS 1 .bag file or a ROS 2 folder with metadata.yaml)"
        )
        raise InputFileError(path, what)
    store = get_typestore(Stores.ROS2_HUMBLE if bag_family(path) == "ros2" else Stores.ROS1_NOETIC)
    try:
        reader = AnyReader([path], default_typestore=store)
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError, IndexError, EOFError) as exc:
        raise InputFileError(path, f"cannot read bag (corrupt or truncated?): {exc}") from None
    return reader


def list_topics(path: str | Path) -> list[TopicInfo]:
    """Every topic of the bag with its message type and count, sorted by name."""
    reader = _open_reader(Path(path))
    try:
        counts: dict[tuple[str, str], int] = {}
        for conn in reader.connections:
            key = (conn.topic, conn.msgtype)
            counts[key] = counts.get(key, 0) + int(conn.msgcount)
        return [TopicInfo(t, m, n) for (t, m), n in sorted(counts.items())]
    finally:
        reader.close()


def image_topics(path: str | Path) -> list[TopicInfo]:
    """The ``sensor_msgs/Image`` and ``sensor_msgs/CompressedImage`` topics of the bag."""
    return [t for t in list_topics(path) if t.msgtype in IMAGE_MSGTYPES]


def describe_topics(topics: Sequence[TopicInfo]) -> str:
    """``/cam/image_raw (sensor_msgs/msg/Image, 120 messages), ...`` or ``none``."""
    return ", ".join(f"{t.name} ({t.msgtype}, {t.count} messages)" for t in topics) or "none"


# ----------------------------------------------------------------------------------------------------------
# Encoding conversions
# ----------------------------------------------------------------------------------------------------------


class UnsupportedEncoding(ValueError):
    """A message's encoding (or compressed format) that murk cannot convert."""


def compressed_kind(fmt: str) -> Literal["jpeg", "png"]:
    """``jpeg`` or ``png`` from a CompressedImage ``format`` (``jpeg``, ``png``, ``bgr8; jpeg compressed bgr8``).

    Raises:
        UnsupportedEncoding: another format (``compressedDepth``, ``tiff``, ...).
    """
    f = fmt.lower()
    if "compresseddepth" in f:
        raise UnsupportedEncoding(f"compressed format {fmt!r} (compressedDepth) is not supported")
    if "jpeg" in f or "jpg" in f:
        return "jpeg"
    if "png" in f:
        return "png"
    raise UnsupportedEncoding(f"compressed format {fmt!r} is not supported (expected jpeg or png)")


def check_encoding(msg: Any, msgtype: str) -> str:
    """The message's encoding (Image) or format (CompressedImage), after checking murk can convert it.

    Raises:
        UnsupportedEncoding: naming the encoding.
    """
    if msgtype == COMPRESSED_MSG:
        compressed_kind(str(msg.format))
        return str(msg.format)
    enc = str(msg.encoding)
    if enc not in _RAW:
        raise UnsupportedEncoding(f"encoding {enc!r} is not supported (murk reads {', '.join(SUPPORTED_ENCODINGS)})")
    return enc


def decode_image_msg(msg: Any, msgtype: str) -> np.ndarray:
    """An Image or CompressedImage message as an RGB array (H, W, 3) of uint8, or uint16 for 16-bit encodings.

    Raises:
        UnsupportedEncoding: an encoding murk cannot convert.
        ValueError: the data does not decode or does not match the declared size.
    """
    if msgtype == COMPRESSED_MSG:
        compressed_kind(str(msg.format))
        data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
        bgr = cv2.imdecode(data, cv2.IMREAD_COLOR | cv2.IMREAD_ANYDEPTH) if data.size else None  # as read_image
        if bgr is None:
            raise ValueError("compressed image data could not be decoded")
        return np.ascontiguousarray(bgr[:, :, ::-1])
    if msgtype != IMAGE_MSG:
        raise UnsupportedEncoding(f"message type {msgtype} is not an image")
    enc = check_encoding(msg, msgtype)
    channels, size, order = _RAW[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    data = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    row = w * channels * size
    if h <= 0 or w <= 0:
        raise ValueError(f"empty image ({w}x{h})")
    if step < row or data.size < step * (h - 1) + row:
        raise ValueError(f"{enc} {w}x{h}: {data.size} bytes of data with step {step} (expected {row} per row)")
    rows = np.lib.stride_tricks.as_strided(data, shape=(h, row), strides=(step, 1))
    dtype = np.dtype(np.uint8) if size == 1 else np.dtype(">u2" if msg.is_bigendian else "<u2")
    img = np.ascontiguousarray(rows).view(dtype).reshape(h, w, channels).astype(dtype.newbyteorder("="))
    if order.startswith("bayer_"):
        return cv2.cvtColor(img[:, :, 0], _BAYER[order])
    if order == "mono":
        return np.repeat(img, 3, axis=2)
    if order in ("bgr", "bgra"):
        img = img[:, :, 2::-1]
    return np.ascontiguousarray(img[:, :, :3])


def output_encoding(encoding: str) -> str:
    """The encoding a restored frame is written in, for a raw Image of ``encoding``."""
    return _OUT_ENCODING.get(encoding, encoding)


def output_bits(msgtype: str, encoding: str) -> Literal[8, 16]:
    """Bits per sample of the restored frame written for a message of this type/encoding."""
    if msgtype == COMPRESSED_MSG:
        return 8
    return 16 if _RAW.get(output_encoding(encoding), (0, 1, ""))[1] == 2 else 8


def encode_pixels(rgb: np.ndarray, msgtype: str, encoding: str, *, jpeg_quality: int = 95) -> tuple[str, bytes, int]:
    """Encode an RGB uint8/uint16 array for a message like the input's: returns (encoding or format, data, step).

    Image: the output encoding of :func:`output_encoding` (grey is the luma of the restored RGB).
    CompressedImage: JPEG (quality ``jpeg_quality``) or PNG, as the input's format.
    """
    if msgtype == COMPRESSED_MSG:
        kind = compressed_kind(encoding)
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
        if kind == "jpeg":
            ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        else:
            ok, buf = cv2.imencode(".png", bgr, [cv2.IMWRITE_PNG_COMPRESSION, 3])
        if not ok:
            raise ValueError(f"OpenCV could not encode a {kind} image ({rgb.dtype}, {rgb.shape})")
        return f"rgb8; {kind} compressed bgr8", buf.tobytes(), 0
    enc = output_encoding(encoding)
    channels, size, order = _RAW[enc]
    if order == "mono":
        px = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)[:, :, None]
    elif order == "bgr":
        px = rgb[:, :, ::-1]
    else:
        px = rgb
    px = np.ascontiguousarray(px.astype("<u2" if size == 2 else np.uint8))
    return enc, px.tobytes(), int(rgb.shape[1]) * channels * size


# ----------------------------------------------------------------------------------------------------------
# Reading
# ----------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BagFrame(Frame):
    """A frame of a bag topic: :class:`murk.io.video.Frame` plus the message's header and bag time.

    Attributes:
        stamp_ns: header stamp (nanoseconds since the epoch).
        frame_id: header frame id.
        log_time_ns: the bag's record time of the message.
        message: position of the message in the topic (``index`` counts yielded frames, after ``every``).
    """

    stamp_ns: int = 0
    frame_id: str = ""
    log_time_ns: int = 0
    message: int = 0
    encoding: str = ""


class BagSource(FrameSource):
    """The frames of one image topic of a bag, in bag order, every ``every``-th message.

    Attributes:
        path, topic, msgtype: the bag, the topic and its message type.
        family, storage: ``ros1``/``ros2`` and, for ROS 2, ``mcap``/``sqlite3``.
        encoding: the first message's encoding (Image) or format (CompressedImage).
        label: ``<bag>:<topic>``, the ``input`` of error records.

    Raises:
        InputFileError: the bag cannot be read; ``topic`` is None or not in the bag (the image topics are
            listed), is not an image topic, holds no messages, or its first message's encoding cannot be
            converted.
    """

    def __init__(self, path: str | Path, topic: str | None, *, every: int = 1) -> None:
        if every < 1:
            raise ValueError(f"every: expected >= 1, got {every}")
        self.path = Path(path)
        self.every = every
        self.history: list[dict[str, Any]] = []
        """One row per frame read so far (index, message, stamp_ns, frame_id, log_time_ns; no pixels)."""
        self._reader = _open_reader(self.path)
        try:
            self._init(topic)
        except BaseException:
            self._reader.close()
            raise

    def _init(self, topic: str | None) -> None:
        reader = self._reader
        conns = [c for c in reader.connections if c.topic == topic]
        images = [
            TopicInfo(t, m, n)
            for (t, m), n in _count(reader.connections).items()
            if m in IMAGE_MSGTYPES  # (sorted below)
        ]
        listing = describe_topics(sorted(images, key=lambda t: t.name))
        if topic is None:
            raise InputFileError(self.path, f"choose an image topic with --topic; image topics: {listing}")
        if not conns:
            raise InputFileError(self.path, f"topic {topic!r} not found; image topics: {listing}")
        types = {c.msgtype for c in conns}
        if len(types) != 1 or next(iter(types)) not in IMAGE_MSGTYPES:
            raise InputFileError(
                self.path,
                f"topic {topic}: message type {', '.join(sorted(types))} is not sensor_msgs/Image or "
                f"sensor_msgs/CompressedImage; image topics: {listing}",
            )
        self.topic = topic
        self.msgtype = next(iter(types))
        self.family: BagFamily = bag_family(self.path)
        self.storage: Storage | None = bag_storage(self.path)
        self._conns = conns
        total = sum(int(c.msgcount) for c in conns)
        if total == 0:
            raise InputFileError(self.path, f"topic {topic} holds no messages")
        self.message_count = total
        self.frame_count = (total + self.every - 1) // self.every
        self.label = f"{self.path}:{topic}"
        self.name = _safe_name(self.path.stem if self.family == "ros1" else self.path.name)
        self._it = self._messages()
        self._index = 0
        self._message = 0
        self._first: tuple[Any, int, bytes] | None = None
        first = self._next_raw()
        if first is None:
            raise InputFileError(self.path, f"topic {topic} holds no messages")
        self._first = first
        try:
            msg = reader.deserialize(first[2], self.msgtype)
        except Exception as exc:
            raise InputFileError(self.path, f"topic {topic}: the first message does not decode ({exc})") from None
        try:
            self.encoding = check_encoding(msg, self.msgtype)
        except UnsupportedEncoding as exc:
            raise InputFileError(self.path, f"topic {topic}: {exc}") from None
        self.fps = _rate(total, reader)

    def _messages(self) -> Iterator[tuple[Any, int, bytes]]:
        yield from self._reader.messages(connections=self._conns)

    def _next_raw(self) -> tuple[Any, int, bytes] | None:
        if self._first is not None:
            first, self._first = self._first, None
            return first
        return next(self._it, None)

    def read(self) -> BagFrame | None:
        frame = self._read()
        if frame is not None:
            self.history.append(
                {
                    "index": frame.index,
                    "message": frame.message,
                    "stamp_ns": frame.stamp_ns,
                    "frame_id": frame.frame_id,
                    "log_time_ns": frame.log_time_ns,
                }
            )
        return frame

    def _read(self) -> BagFrame | None:
        if self.end_reason is not None:
            return None
        while True:
            try:
                raw = self._next_raw()
            except Exception as exc:  # a truncated or corrupt chunk: the topic ends here
                self.end_reason = (
                    f"the bag could not be read after message {self._message} ({type(exc).__name__}: {exc})"
                )
                return None
            if raw is None:
                self.end_reason = "end"
                return None
            position = self._message
            self._message += 1
            if position % self.every == 0:
                break
        _, log_time_ns, data = raw
        index = self._index
        self._index += 1
        try:
            msg = self._reader.deserialize(data, self.msgtype)
        except Exception as exc:
            return BagFrame(index, None, f"message does not deserialize: {exc}", 0, "", log_time_ns, position)
        stamp_ns = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        frame_id = str(msg.header.frame_id)
        try:
            image = decode_image_msg(msg, self.msgtype)
            encoding = check_encoding(msg, self.msgtype)
        except ValueError as exc:  # UnsupportedEncoding too: this message is recorded, the topic goes on
            return BagFrame(index, None, str(exc), stamp_ns, frame_id, log_time_ns, position)
        return BagFrame(index, image, None, stamp_ns, frame_id, log_time_ns, position, encoding)

    def raw_messages(self, topics: Sequence[str]) -> Iterator[tuple[Any, int, bytes]]:
        """(connection, log time, serialized bytes) of every message on ``topics`` (for copying them)."""
        conns = [c for c in self._reader.connections if c.topic in set(topics)]
        if conns:
            yield from self._reader.messages(connections=conns)

    def topics(self) -> list[TopicInfo]:
        """Every topic of the bag."""
        return [TopicInfo(t, m, n) for (t, m), n in sorted(_count(self._reader.connections).items())]

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._reader.close()


def _count(connections: Sequence[Any]) -> dict[tuple[str, str], int]:
    counts: dict[tuple[str, str], int] = {}
    for conn in connections:
        key = (conn.topic, conn.msgtype)
        counts[key] = counts.get(key, 0) + int(conn.msgcount)
    return counts


def _rate(count: int, reader: Any) -> float | None:
    try:
        duration_s = reader.duration / 1e9
    except Exception:
        return None
    return (count - 1) / duration_s if count > 1 and duration_s > 0 else None


def _safe_name(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in text) or "bag"


# ----------------------------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------------------------


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
        self.path.parent.mkdir(parents=True, exist_ok=True)
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


# ----------------------------------------------------------------------------------------------------------
# Bag frames as an image source for snow extract, eval and compare
# ----------------------------------------------------------------------------------------------------------


def iter_frames(path: str | Path, topic: str | None, *, every: int = 1) -> Iterator[BagFrame]:
    """Every ``every``-th frame of ``topic`` (broken frames included, with ``image=None`` and ``error``).

    Raises:
        InputFileError: see :class:`BagSource`.
    """
    with BagSource(path, topic, every=every) as source:
        yield from source
        if source.end_reason not in (None, "end"):
            yield BagFrame(source._index, None, source.end_reason, message=source._message)


def frame_name(path: str | Path, index: int) -> str:
    """``<bag>_<index:06d>``: the stem of a bag frame exported as a file."""
    p = Path(path)
    return f"{_safe_name(p.stem if p.suffix.lower() == '.bag' else p.name)}_{index:06d}"


@dataclass
class ExportedFrames:
    """Bag frames written as lossless PNG files (16-bit encodings stay 16-bit) for commands that read files.

    The temporary folders are deleted by :meth:`cleanup`, or when this object is garbage-collected (keep a
    reference while the files are used).

    Attributes:
        paths: the inputs with every bag replaced by the folder of its frames (other inputs unchanged).
        errors: one record per frame that could not be decoded (``input`` = ``<bag>:<topic>``, ``frame``).
        rows: ``frames.jsonl`` rows (file_name, index, message, stamp_ns, frame_id, log_time_ns, topic).
    """

    paths: list[Path]
    errors: list[Any]
    rows: list[dict[str, Any]]
    _tmp: list[Any]

    def cleanup(self) -> None:
        """Delete the temporary folders."""
        for tmp in self._tmp:
            tmp.cleanup()
        self._tmp.clear()


def export_bag_frames(paths: Sequence[Path], topic: str | None, *, every: int = 1) -> ExportedFrames:
    """Replace each bag among ``paths`` by a temporary folder holding its sampled frames as PNG files
    (``<bag>_<index:06d>.png``) and ``frames.jsonl``; call :meth:`ExportedFrames.cleanup` when done.

    Raises:
        InputFileError: a bag cannot be read or ``topic`` is missing/wrong (see :class:`BagSource`).
    """
    import tempfile

    from murk.io.images import write_uint
    from murk.io.jobs import ErrorRecord
    from murk.io.jsonl import write_jsonl

    out = ExportedFrames([], [], [], [])
    try:
        for p in paths:
            if not is_bag(p):
                out.paths.append(p)
                continue
            tmp = tempfile.TemporaryDirectory(prefix="murk-bag-")
            out._tmp.append(tmp)
            folder = Path(tmp.name) / frame_name(p, 0)[:-7]
            folder.mkdir()
            rows = []
            label = f"{p}:{topic}"
            for frame in iter_frames(p, topic, every=every):
                if frame.image is None:
                    out.errors.append(ErrorRecord(label, "decode", frame.error or "not decoded", frame=frame.index))
                    continue
                name = f"{frame_name(p, frame.index)}.png"
                write_uint(folder / name, frame.image)
                rows.append(
                    {
                        "file_name": name,
                        "index": frame.index,
                        "message": frame.message,
                        "stamp_ns": frame.stamp_ns,
                        "frame_id": frame.frame_id,
                        "log_time_ns": frame.log_time_ns,
                        "topic": topic,
                    }
                )
            write_jsonl(folder / "frames.jsonl", rows)
            out.rows += rows
            out.paths.append(folder)
    except BaseException:
        out.cleanup()
        raise
    return out
