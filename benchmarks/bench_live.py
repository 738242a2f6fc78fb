"""The live path end to end: decode -> restore -> encode at 640x480, as ``murk enhance`` runs it.

Run: PYTHONPATH=src python benchmarks/bench_live.py [--frames 300] [--threads 2] [--methods lite,lite+post,post]

Two measurements per method, both through :func:`murk.enhance.api.enhance_frames` (the function behind
``murk enhance``) with the shipped weights:

1. a 640x480 MJPEG ``.avi`` file -> ``.avi`` (as fast as possible): frames/s end to end, and the wall time per
   frame spent waiting for decoded input, restoring and encoding;
2. a live MJPEG-over-HTTP camera on localhost that sends 640x480 frames at 30 frames/s (``--camera-fps``) ->
   ``.avi``: frames restored, frames dropped (the camera outpacing restoration), and the achieved frames/s.

Torch and OpenCV use ``--threads`` threads (default 2, the robot's 2 cores); decoding runs in a read-ahead thread
and encoding in a write-behind thread.

``--overlap``: only file -> file with encoding, as ``murk enhance clip.avi --out out.avi`` runs it, frames/s =
140 / (t150 - t10), overlapped (read-ahead + write-behind) against the serial path, interleaved, best of 3, and
a check that both write the same bytes.
"""

from __future__ import annotations

import argparse
import contextlib
import http.server
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # testkit/video.py serves the MJPEG camera
import cv2
import numpy as np
import torch
from _common import machine

from murk.data import sample_underwater_images
from murk.enhance.api import EnhanceReport, OutputOptions, enhance_frames
from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.io.video import CaptureSource
from testkit.video import serve_http

W, H = 640, 480


def make_frames(n: int) -> list[np.ndarray]:
    """``n`` 640x480 BGR uint8 frames: the shipped underwater samples panning slowly (real image content)."""
    base = [
        cv2.resize((read_rgb(p) * 255 + 0.5).astype(np.uint8)[:, :, ::-1], (W + 64, H), interpolation=cv2.INTER_AREA)
        for p in sample_underwater_images()[:3]
    ]
    return [np.ascontiguousarray(base[(i // 100) % len(base)][:, (i % 64) : (i % 64) + W]) for i in range(n)]


def write_avi(path: Path, frames: list[np.ndarray], fps: float = 30.0) -> None:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, (W, H))
    for f in frames:
        writer.write(f)
    writer.release()


class _Camera(http.server.BaseHTTPRequestHandler):
    jpegs: ClassVar[list[bytes]] = []
    fps: ClassVar[float] = 30.0

    def do_GET(self) -> None:
        self.send_response(200)
        self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
        self.end_headers()
        start = time.perf_counter()
        try:
            for i, b in enumerate(self.jpegs):
                delay = start + i / self.fps - time.perf_counter()  # paced like a camera: frame i at i / fps
                if delay > 0:
                    time.sleep(delay)
                head = b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n" % len(b)
                self.wfile.write(head + b + b"\r\n")
                self.wfile.flush()
        except (BrokenPipeError, ConnectionResetError):
            pass

    def log_message(self, *args: object) -> None:
        pass


@contextlib.contextmanager
def camera(frames: list[np.ndarray], fps: float) -> Iterator[str]:
    jpegs = [cv2.imencode(".jpg", f, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes() for f in frames]
    handler = type("Cam", (_Camera,), {"jpegs": jpegs, "fps": fps})
    with serve_http(handler) as url:
        yield url


def line(label: str, report: EnhanceReport) -> str:
    ms = report.stage_ms()
    return (
        f"{label:<28} {report.processed:>5} restored {report.dropped:>4} dropped {report.fps:7.1f} frames/s"
        f"   per frame: wait for input {ms['read']:5.1f} ms, restore {ms['restore']:5.1f} ms,"
        f" encode {ms['write']:5.1f} ms"
    )


def file_to_file(restorer, src: Path, out: Path, opts: OutputOptions, overlap: bool) -> tuple[float, EnhanceReport]:  # type: ignore[no-untyped-def]
    """Frames/s of one file -> file run as the issue measures it: 140 / (t150 - t10), the times at which the
    10th and the 150th frame were handed to the encoder (start-up and the first calls excluded). ``overlap``:
    decode, restore and encode overlap (read-ahead and write-behind threads); without it the serial path."""
    marks: dict[int, float] = {}

    def progress(report: EnhanceReport) -> None:
        for n in (10, 150):
            if report.processed >= n and n not in marks:
                marks[n] = time.perf_counter()

    with CaptureSource(src) as source:
        report = enhance_frames(source, restorer, out, opts, on_progress=progress, read_ahead=overlap)
    if 150 not in marks or 10 not in marks:
        return report.fps, report
    return 140.0 / (marks[150] - marks[10]), report


def overlap_figures(methods: list[str], src: Path, tmp: Path, opts: OutputOptions, rounds: int = 3) -> None:
    """File -> file with encoding, overlapped against the serial path, interleaved, best of ``rounds``; the two
    videos must be identical byte for byte."""
    for method in methods:
        restorer = create(method)
        with CaptureSource(src) as source:  # warm-up
            enhance_frames(source, restorer, tmp / "warm.avi", opts, max_frames=10)
        best = {True: 0.0, False: 0.0}
        for _ in range(rounds):
            for overlap in (True, False):
                fps, _ = file_to_file(restorer, src, tmp / f"o{int(overlap)}.avi", opts, overlap)
                best[overlap] = max(best[overlap], fps)
        same = (tmp / "o1.avi").read_bytes() == (tmp / "o0.avi").read_bytes()
        print(
            f"{method + ': file -> file, encoded':<34} overlapped {best[True]:6.1f} frames/s   serial "
            f"{best[False]:6.1f} frames/s   x{best[True] / best[False]:.2f}   bytes identical: {same}"
        )


def cli_figures(methods: list[str], src: Path, tmp: Path, rounds: int = 3) -> None:
    """``murk enhance clip.avi --out out.avi --method M`` as a user runs it, frames/s = 140 / (t150 - t10) from
    the wall times of the command with ``--max-frames 10`` and ``150`` (start-up cancels out), best of
    ``rounds`` interleaved runs."""
    import subprocess

    def wall(method: str, n: int) -> float:
        cmd = [sys.executable, "-m", "murk", "enhance", str(src), "--out", str(tmp / f"cli{n}.avi")]
        cmd += ["--method", method, "--max-frames", str(n), "--overwrite", "-q"]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True)
        return time.perf_counter() - t0

    for method in methods:
        best = 0.0
        for _ in range(rounds):
            t10, t150 = wall(method, 10), wall(method, 150)
            best = max(best, 140.0 / (t150 - t10))
        label = f"{method}: murk enhance (command line)"
        print(f"{label:<40} {best:6.1f} frames/s  (140 / (t150 - t10), best of {rounds})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--camera-fps", type=float, default=30.0)
    parser.add_argument("--methods", default="lite,lite+post,post")
    parser.add_argument(
        "--overlap", action="store_true", help="only: file -> file, overlapped vs serial (issue 29), best of 3"
    )
    parser.add_argument("--cli", action="store_true", help="only: the murk enhance command, file -> file (issue 29)")
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    print(machine())
    print(f"torch threads {torch.get_num_threads()}, OpenCV threads {cv2.getNumThreads()}, {W}x{H}")
    frames = make_frames(args.frames)
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "in.avi"
        write_avi(src, frames)
        opts = OutputOptions(overwrite=True, video_backend="opencv")
        if args.overlap:
            overlap_figures(args.methods.split(","), src, Path(tmp), opts)
            return
        if args.cli:
            cli_figures(args.methods.split(","), src, Path(tmp))
            return
        for method in args.methods.split(","):
            restorer = create(method)
            with CaptureSource(src) as source:  # warm-up: first calls allocate
                enhance_frames(source, restorer, Path(tmp) / "warm.avi", opts, max_frames=10)
            with CaptureSource(src) as source:
                report = enhance_frames(source, restorer, Path(tmp) / "out.avi", opts)
            print(line(f"{method}: file -> file", report))
            with camera(frames, args.camera_fps) as url, CaptureSource(url) as source:
                report = enhance_frames(source, restorer, Path(tmp) / "live.avi", opts)
            print(line(f"{method}: {args.camera_fps:g} fps camera", report))


if __name__ == "__main__":
    main()
