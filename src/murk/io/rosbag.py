"""ROS 1 and ROS 2 bags at the I/O edge: image topics in, image topics out (the optional ``ros`` extra).

Reading and writing use the pure-Python ``rosbags`` library (Apache-2.0; no ROS installation needed):
ROS 1 ``.bag`` files and ROS 2 bag folders (``metadata.yaml`` plus MCAP or SQLite3 storage).

- :func:`is_bag`, :func:`bag_family`, :func:`bag_storage`: what a path is.
- :func:`list_topics`, :func:`image_topics`: the topics of a bag (name, message type, message count).
- :class:`BagSource`: a :class:`murk.io.video.FrameSource` over one image topic (``sensor_msgs/Image`` or
  ``sensor_msgs/CompressedImage``), optionally every N-th message. Frames are :class:`BagFrame` objects: RGB
  uint8 (or uint16 for 16-bit encodings) plus the message's header stamp, frame id and bag log time. A message
  that cannot be decoded is yielded with ``image=None`` and an ``error`` (the caller records it and carries on).
- :func:`iter_frames`, :func:`export_bag_frames`: bag frames as the image source of ``murk snow extract``,
  ``murk eval`` and ``murk compare``.

Writing bags: :mod:`murk.io.rosbag_writer`; the encoding conversions (``bgr8``, ``rgb8``, ``mono8``, Bayer,
16-bit, JPEG/PNG CompressedImage): :mod:`murk.io.ros_image`.

Errors: a missing, corrupt or truncated bag, an unknown topic (the image topics are listed), a topic of another
message type, an encoding murk cannot convert (named), or a topic with no messages raise
:class:`murk.errors.InputFileError` naming the bag (and topic).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from murk.errors import InputFileError
from murk.io.ros_image import (
    CAMERA_INFO_MSG,
    COMPRESSED_MSG,
    IMAGE_MSG,
    IMAGE_MSGTYPES,
    UnsupportedEncoding,
    check_encoding,
    decode_image_msg,
)
from murk.io.video import Frame, FrameSource

__all__ = [
    "CAMERA_INFO_MSG",
    "COMPRESSED_MSG",
    "IMAGE_MSG",
    "STORAGES",
    "BagFrame",
    "BagSource",
    "TopicInfo",
    "bag_family",
    "bag_storage",
    "export_bag_frames",
    "image_topics",
    "is_bag",
    "iter_frames",
    "list_topics",
    "rosbags_available",
]

BagFamily = Literal["ros1", "ros2"]
Storage = Literal["mcap", "sqlite3"]
STORAGES: tuple[str, ...] = ("mcap", "sqlite3")
INSTALL_HINT = "ROS bags need the optional 'ros' extra: pip install 'murk[ros]'"


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
    try:
        return (p.suffix.lower() == ".bag" and p.is_file()) or (p.is_dir() and (p / "metadata.yaml").is_file())
    except OSError:  # a folder that cannot be entered is no bag (its reader reports why it cannot be read)
        return False


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

    def __iter__(self) -> Iterator[BagFrame]:  # FrameSource's loop, typed with BagFrame
        while (frame := self.read()) is not None:
            yield frame

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


@contextlib.contextmanager
def bag_frames_as_files(paths: Sequence[Path], topic: str | None, *, every: int = 1) -> Iterator[ExportedFrames]:
    """:func:`export_bag_frames` for the duration of a ``with`` block (the temporary folders are deleted at its
    end); without a bag among ``paths`` nothing is exported and ``paths`` come back unchanged.

    Raises:
        ValueError: ``topic`` given but no bag among ``paths``.
    """
    paths = list(paths)
    if not any(is_bag(p) for p in paths):
        if topic is not None:
            raise ValueError(f"--topic {topic}: applies to ROS bags, and no input is one")
        yield ExportedFrames(paths, [], [], [])
        return
    frames = export_bag_frames(paths, topic, every=every)
    try:
        yield frames
    finally:
        frames.cleanup()
