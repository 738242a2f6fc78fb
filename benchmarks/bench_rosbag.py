"""Frames per second of ``murk enhance`` bag -> ``post`` -> bag against the same frames read from and written to files.

Run: PYTHONPATH=src python benchmarks/bench_rosbag.py [--frames 100] [--rounds 3]

Needs the ``ros`` extra (rosbags). CPU, ONE core (cv2.setNumThreads(1), torch.set_num_threads(1)). The same
``--frames`` 640x480 frames are stored four ways: a ROS 1 bag and a ROS 2 MCAP bag of raw ``bgr8`` Images, a
ROS 2 MCAP bag of JPEG CompressedImages, and (the baselines) a folder of PNG files (lossless, like raw Images) and
a folder of JPEG files (like CompressedImages). Each is restored end to end with the ``post`` method by the
library function ``murk enhance`` calls (:func:`murk.enhance.bag.enhance_bag`,
:func:`murk.enhance.api.enhance_images`), output in the same form (bag -> bag, files -> files), in
alternating rounds; the figure is the median frames/s over the rounds, the ratio bag / files of the same
encoding.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cv2
import numpy as np
from _common import machine, pin_one_core

from murk.data import sample_underwater_images
from murk.enhance.api import OutputOptions, enhance_images, plan_images, resolve_input
from murk.enhance.bag import enhance_bag
from murk.enhance.post import PostRestorer
from murk.io.images import read_rgb, to_uint


def make_frames(n: int, h: int = 480, w: int = 640) -> list[np.ndarray]:
    """``n`` distinct uint8 RGB frames: a sample underwater image at 640x480, shifted a few pixels per frame."""
    base = to_uint(cv2.resize(read_rgb(sample_underwater_images()[0]), (w + 64, h + 64)), 8)
    return [np.ascontiguousarray(base[(i % 64) : (i % 64) + h, (3 * i % 64) : (3 * i % 64) + w]) for i in range(n)]


def write_bag(path: Path, frames: list[np.ndarray], family: str, compressed: bool) -> Path:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if family == "ros1" else Stores.ROS2_HUMBLE)
    writer = Writer1(path) if family == "ros1" else Writer2(path, version=8, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    msgtype = "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image"
    conn = writer.add_connection("/cam/image_raw" + ("/compressed" if compressed else ""), msgtype, typestore=ts)
    ser = ts.serialize_ros1 if family == "ros1" else ts.serialize_cdr
    for i, rgb in enumerate(frames):
        t = 1_700_000_000_000_000_000 + i * 100_000_000
        stamp = ts.types["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9)
        kw = {"seq": i} if family == "ros1" else {}
        header = ts.types["std_msgs/msg/Header"](stamp=stamp, frame_id="cam", **kw)
        bgr = np.ascontiguousarray(rgb[:, :, ::-1])
        if compressed:
            data = np.frombuffer(cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes(), np.uint8)
            msg = ts.types[msgtype](header=header, format="jpeg", data=data)
        else:
            h, w = rgb.shape[:2]
            msg = ts.types[msgtype](
                header=header, height=h, width=w, encoding="bgr8", is_bigendian=0, step=3 * w,
                data=np.frombuffer(bgr.tobytes(), np.uint8),
            )  # fmt: skip
        writer.write(conn, t, ser(msg, msgtype))
    writer.close()
    return path


def write_files(folder: Path, frames: list[np.ndarray], suffix: str) -> Path:
    folder.mkdir()
    params = [cv2.IMWRITE_JPEG_QUALITY, 95] if suffix == ".jpg" else []
    for i, rgb in enumerate(frames):
        cv2.imwrite(str(folder / f"f{i:06d}{suffix}"), np.ascontiguousarray(rgb[:, :, ::-1]), params)
    return folder


def run_bag(bag: Path, topic: str, out: Path) -> Callable[[], float]:
    from murk.io.rosbag import BagSource

    def go() -> float:
        shutil.rmtree(out, ignore_errors=True)
        out.unlink(missing_ok=True) if out.is_file() else None
        with BagSource(bag, topic) as src:
            report = enhance_bag(src, PostRestorer(), out, OutputOptions(overwrite=True))
        return report.processed / report.wall_s

    return go


def run_files(folder: Path, out: Path) -> Callable[[], float]:
    def go() -> float:
        shutil.rmtree(out, ignore_errors=True)
        t0 = time.perf_counter()
        jobs, out_dir = plan_images(resolve_input(str(folder)), out)
        report = enhance_images(jobs, PostRestorer(), out_dir, OutputOptions(overwrite=True))
        return report.processed / (time.perf_counter() - t0)

    return go


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    pin_one_core()
    print(machine())
    frames = make_frames(args.frames)
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        raw, jpeg = "/cam/image_raw", "/cam/image_raw/compressed"
        cases = {
            "PNG files -> PNG files (baseline, raw)": run_files(write_files(d / "png", frames, ".png"), d / "o_png"),
            "ROS 1 bag bgr8 -> bag": run_bag(write_bag(d / "r1.bag", frames, "ros1", False), raw, d / "o1.bag"),
            "ROS 2 MCAP bgr8 -> bag": run_bag(write_bag(d / "r2", frames, "ros2", False), raw, d / "o2"),
            "JPEG files -> JPEG files (baseline, compressed)": run_files(
                write_files(d / "jpg", frames, ".jpg"), d / "o_jpg"
            ),
            "ROS 2 MCAP JPEG -> bag": run_bag(write_bag(d / "r2c", frames, "ros2", True), jpeg, d / "o2c"),
        }
        fps: dict[str, list[float]] = {k: [] for k in cases}
        for _ in range(args.rounds):
            for k, fn in cases.items():
                fps[k].append(fn())
    med = {k: statistics.median(v) for k, v in fps.items()}
    png, jpg = med["PNG files -> PNG files (baseline, raw)"], med["JPEG files -> JPEG files (baseline, compressed)"]
    print(f"{args.frames} frames 640x480, method post, one core, median of {args.rounds} rounds")
    print(f"{'case':<50} {'frames/s':>9} {'vs files':>9}")
    for k, v in med.items():
        base = jpg if "JPEG" in k else png
        print(f"{k:<50} {v:>9.1f} {v / base:>9.2f}")


if __name__ == "__main__":
    main()
