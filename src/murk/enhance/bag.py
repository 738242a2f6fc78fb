"""Restoring the images of a ROS bag topic into a new bag or into numbered images (``murk enhance dive.bag``).

Bag output (:func:`enhance_bag` with a bag ``out``): a bag of the input's family (ROS 1 -> ROS 1, ROS 2 ->
ROS 2, storage as the input unless ``storage``) with the restored frames on ``out_topic`` (default
``<topic>/restored``; for ``<base>/compressed`` topics ``<base>/restored/compressed`` so image_transport sees a
``compressed`` transport) in the input's message type and encoding family, with the ORIGINAL header stamps,
frame ids and bag record times; depth maps (methods that estimate depth) on ``depth_topic`` (default
``<base>/depth``) as ``32FC1`` metres; and, when asked, other topics copied unchanged (``camera_info``: every
``sensor_msgs/CameraInfo`` topic; ``all``: every topic).

Frames output (:func:`enhance_bag`): numbered images ``<bag>_<index:06d>.<format>`` written by
:func:`murk.enhance.api.enhance_frames` (same depth outputs, same per-frame resume) plus ``frames.jsonl``
(:func:`write_frames_index`: one line per written image: ``file_name``, ``index``, ``message``, ``stamp_ns``,
``frame_id``, ``log_time_ns``, ``topic``), rewritten atomically at the end of every run.

Resume: a bag is one file (or folder) written under a temporary name and renamed when complete, so a finished
output bag is skipped by a rerun (``overwrite`` redoes it) and a killed run leaves only a ``.murk-tmp-`` bag,
which the rerun deletes and redoes from the first frame (a partly written bag has no index and cannot be
appended to safely). Numbered frames resume frame by frame.

Errors: messages that fail to decode are recorded in ``errors.jsonl`` next to the output (stage ``decode``,
with the frame index) and left out of the output bag; a bag that cannot be read to its end is recorded (stage
``read``) and the frames read before are kept.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from murk.enhance.frame_job import enhance_frames
from murk.enhance.job_common import EnhanceReport, OutputOptions, ProgressFn, StopFn, read_frames, restore_batch
from murk.enhance.preview import side_by_side
from murk.enhance.restorer import Restorer
from murk.errors import InputFileError
from murk.io.atomic import make_output_folder
from murk.io.images import IMAGE_SUFFIXES, to_float, to_uint
from murk.io.jobs import ErrorLog, ErrorRecord
from murk.io.jsonl import write_jsonl
from murk.io.listing import real_path
from murk.io.ros_image import CAMERA_INFO_MSG, COMPRESSED_MSG, output_bits
from murk.io.rosbag import STORAGES, BagFrame, BagSource, Storage
from murk.io.rosbag_writer import BagSink, remove_stale_bags
from murk.io.video import VIDEO_SUFFIXES

FRAMES_FILE = "frames.jsonl"


@dataclass(frozen=True)
class BagOptions:
    """ROS bag input and output choices (``murk enhance dive.bag --topic ...``): the input topic and frame step,
    and for a bag output the topics, the ROS 2 storage and the topics to copy (see the module docstring)."""

    topic: str | None = None
    every: int = 1
    out_topic: str | None = None
    depth_topic: str | None = None
    storage: Storage | None = None
    copy_topics: tuple[str, ...] = ()

    def output_flags(self) -> list[str]:
        """The command-line names of the bag-output choices that are set."""
        pairs = (
            ("--out-topic", self.out_topic),
            ("--depth-topic", self.depth_topic),
            ("--storage", self.storage),
            ("--copy-topics", self.copy_topics),
        )
        return [name for name, value in pairs if value]


_RESTORE_ERRORS = (ValueError, RuntimeError, MemoryError)


def default_topics(topic: str, msgtype: str) -> tuple[str, str]:
    """(restored topic, depth topic) for an input topic: ``<topic>/restored`` and ``<topic>/depth``, or for a
    compressed ``<base>/compressed`` topic ``<base>/restored/compressed`` and ``<base>/depth``."""
    base = topic.rstrip("/")
    if msgtype == COMPRESSED_MSG and base.endswith("/compressed"):
        base = base[: -len("/compressed")]
        return f"{base}/restored/compressed", f"{base}/depth"
    return f"{base}/restored", f"{base}/depth"


def writes_bag(out: Path, family: str, image_format: str | None) -> bool:
    """Whether ``--out`` names an output bag (else a folder of numbered frames).

    ROS 1: a ``.bag`` name is a bag, anything else a folder. ROS 2: a folder that does not exist yet or holds a
    ``metadata.yaml`` is a bag, unless ``--format`` is given (frames); an existing folder without
    ``metadata.yaml`` gets frames.

    Raises:
        ValueError: a video or image file name, or ``--format`` with a ``.bag`` name.
    """
    suffix = out.suffix.lower()
    if suffix in VIDEO_SUFFIXES or suffix in IMAGE_SUFFIXES:
        raise ValueError(
            f"--out {out}: a bag is written to a bag ({'.bag' if family == 'ros1' else 'a folder'}) "
            "or to a folder of numbered images, not a video or image file"
        )
    if suffix == ".bag":
        if family == "ros2":
            raise ValueError(f"--out {out}: a ROS 2 input gives a ROS 2 bag, a folder; name it without .bag")
        if image_format is not None:
            raise ValueError(f"--out {out}: --format {image_format} writes numbered images; name a folder")
        return True
    if family == "ros1" or image_format is not None:
        return False
    return not out.exists() or (out / "metadata.yaml").is_file()


def resolve_copy_topics(source: BagSource, copy_topics: Sequence[str], skip: Sequence[str]) -> list[str]:
    """Topic names to copy: names as given, ``camera_info`` for every CameraInfo topic of the bag, ``all`` for
    every topic (the input image topic included; never the output topics).

    Raises:
        InputFileError: a named topic is not in the bag.
    """
    topics = source.topics()
    names = {t.name for t in topics}
    chosen: list[str] = []
    for spec in copy_topics:
        if spec == "all":
            found = [t.name for t in topics]
        elif spec == "camera_info":
            found = [t.name for t in topics if t.msgtype == CAMERA_INFO_MSG]
            if not found:
                raise InputFileError(
                    source.path, "--copy-topics camera_info: the bag has no sensor_msgs/CameraInfo topic"
                )
        elif spec in names:
            found = [spec]
        else:
            listing = ", ".join(sorted(names)) or "none"
            raise InputFileError(source.path, f"--copy-topics {spec}: no such topic; topics: {listing}")
        chosen += [t for t in found if t not in chosen and t not in skip]
    return chosen


def _enhance_to_bag(
    source: BagSource,
    restorer: Restorer,
    out: Path,
    options: OutputOptions,
    bag: BagOptions,
    batch: int,
    max_frames: int | None,
    on_progress: ProgressFn | None,
    should_stop: StopFn | None,
) -> EnhanceReport:
    """:func:`enhance_bag` into a new bag at ``out`` (see the module docstring); ``bag`` gives the output topics,
    storage and topics to copy (its ``topic`` and ``every`` were used to open ``source``)."""
    storage = bag.storage
    if batch < 1:
        raise ValueError(f"batch: expected >= 1, got {batch}")
    if max_frames is not None and max_frames < 1:
        raise ValueError(f"max_frames: expected >= 1, got {max_frames}")
    if storage is not None and source.family == "ros1":
        raise ValueError("--storage applies to ROS 2 bags; a ROS 1 input gives a ROS 1 bag: leave --storage out")
    if storage is not None and storage not in STORAGES:
        raise ValueError(f"--storage: expected one of {', '.join(STORAGES)}, got {storage!r}")
    d_out, d_depth = default_topics(source.topic, source.msgtype)
    out_topic = bag.out_topic or d_out
    depth_topic = bag.depth_topic or d_depth
    if source.topic in (out_topic, depth_topic) or out_topic == depth_topic:
        raise ValueError(
            f"output topics {out_topic}, {depth_topic} must differ from each other and from {source.topic}; "
            "name them with --out-topic and --depth-topic"
        )
    if real_path(out) == real_path(source.path):
        raise ValueError(f"--out {out}: is the input bag; choose another --out (the input is never overwritten)")
    copies = resolve_copy_topics(source, bag.copy_topics, skip=(out_topic, depth_topic))
    report = EnhanceReport(
        total=source.frame_count if max_frames is None else min(source.frame_count or max_frames, max_frames)
    )
    errors = ErrorLog(out.parent, summary=report)
    if out.exists() and not options.overwrite:
        report.skipped = 1
        report.note(f"{out} exists; skipped (use --overwrite to redo it)")
        return report
    make_output_folder(out.parent)
    remove_stale_bags(out)
    errors.start()
    sink = BagSink(out, source.family, storage or source.storage, overwrite=options.overwrite)
    label = source.label
    pending: list[BagFrame] = []

    def record(stage: str, error: str, frame: int | None = None) -> None:
        errors.add(ErrorRecord(label, stage, error, frame=frame))  # counted in report (failed, errors_path)

    def flush() -> None:
        t0 = time.perf_counter()
        try:
            result = restore_batch(restorer, np.stack([to_float(f.image) for f in pending]))  # type: ignore[arg-type]
        except _RESTORE_ERRORS as exc:
            for f in pending:
                record("restore", f"{type(exc).__name__}: {exc}", f.index)
            pending.clear()
            return
        finally:
            report.restore_s += time.perf_counter() - t0
        t0 = time.perf_counter()
        for j, f in enumerate(pending):
            image = side_by_side(to_float(f.image), result.images[j]) if options.side_by_side else result.images[j]  # type: ignore[arg-type]
            bits = output_bits(source.msgtype, f.encoding)
            sink.write_image(
                out_topic,
                to_uint(image, bits),
                msgtype=source.msgtype,
                encoding=f.encoding,
                stamp_ns=f.stamp_ns,
                frame_id=f.frame_id,
                log_time_ns=f.log_time_ns,
                jpeg_quality=options.jpeg_quality,
            )
            if result.depth_m is not None and options.depth:
                sink.write_depth(
                    depth_topic, result.depth_m[j], stamp_ns=f.stamp_ns, frame_id=f.frame_id, log_time_ns=f.log_time_ns
                )
            report.processed += 1
        report.write_s += time.perf_counter() - t0
        pending.clear()
        report.tick()
        if on_progress:
            on_progress(report)

    complete = False
    try:
        for frame in read_frames(source, report, should_stop, max_frames):
            if frame.image is None:
                record("decode", frame.error or "message could not be decoded", frame.index)
                continue
            if pending and pending[0].image.shape != frame.image.shape:  # type: ignore[union-attr]
                flush()
            pending.append(frame)  # type: ignore[arg-type]
            if len(pending) >= batch:
                flush()
        if pending and not report.stopped:
            flush()
        if source.end_reason not in (None, "end") and not report.stopped:
            record("read", source.end_reason)  # type: ignore[arg-type]
        if copies and not report.stopped:
            t0 = time.perf_counter()
            for conn, log_time_ns, data in source.raw_messages(copies):
                sink.copy(conn, log_time_ns, data)
            report.write_s += time.perf_counter() - t0
        complete = not report.stopped
    finally:
        if complete:
            sink.close()
        else:
            sink.abort()
        report.tick()
    if complete:
        report.outputs.append(out)
    else:
        report.note(f"interrupted: the partial bag was discarded; rerun to write {out}")
    return report


def write_frames_index(source: BagSource, out: Path, options: OutputOptions | None, report: EnhanceReport) -> None:
    """Write ``frames.jsonl`` into the frames folder ``out``: one line per numbered image of ``source`` that is
    there (file name, the message's index, stamps and frame id, the topic)."""
    ext = f".{(options.format if options else None) or 'jpg'}"
    rows = []
    for row in source.history:
        name = f"{source.name}_{row['index']:06d}{ext}"
        if (out / name).is_file():
            rows.append({"file_name": name, **row, "topic": source.topic})
    if rows:
        write_jsonl(out / FRAMES_FILE, rows)
        report.outputs.append(out / FRAMES_FILE)


def enhance_bag(
    source: BagSource,
    restorer: Restorer,
    out: Path,
    options: OutputOptions | None = None,
    *,
    bag: BagOptions | None = None,
    batch: int = 1,
    max_frames: int | None = None,
    on_progress: ProgressFn | None = None,
    should_stop: StopFn | None = None,
) -> EnhanceReport:
    """Restore a bag topic into a bag or into numbered frames, as ``out`` says (:func:`writes_bag`).

    Raises:
        ValueError: bag-output choices (``out_topic``, ``depth_topic``, ``storage``, ``copy_topics``) with a
            frames output; a bad option of a bag output (``storage`` for a ROS 1 bag, an output topic equal to the
            input topic, ...).
        InputFileError: a ``copy_topics`` entry is not in the bag.
        OutputError: no space left on the device; the temporary bag is deleted.
    """
    options = options or OutputOptions()
    bag = bag or BagOptions()
    if writes_bag(out, source.family, options.format):
        with restorer.sequence():  # the topic's frames are one video (enhance_frames enters it for frames)
            return _enhance_to_bag(source, restorer, out, options, bag, batch, max_frames, on_progress, should_stop)
    if bag.output_flags():
        raise ValueError(f"{', '.join(bag.output_flags())}: apply to a bag output; --out {out} writes numbered images")
    report = enhance_frames(
        source, restorer, out, options, batch=batch, max_frames=max_frames, on_progress=on_progress,
        should_stop=should_stop,
    )  # fmt: skip
    write_frames_index(source, out, options, report)
    return report
