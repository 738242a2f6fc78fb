"""``murk live`` end to end: frames/s reaching the page and glass-to-page latency in a real headless Chromium,
beside ``murk enhance`` of the same clip to a file.

Run: PYTHONPATH=src python benchmarks/bench_live_view.py [--seconds 10] [--threads 2]
     [--methods lite,lite+post,post] [--sizes 640x480,1280x720]

Per size and method:

1. live: a 30 frames/s MJPEG clip of the shipped underwater samples (panning), played at its own rate and
   looped, through :class:`murk.live.restore_loop.LivePipeline` and :class:`murk.live.server.LiveServer` (what
   ``murk live`` runs), watched by Debian's headless Chromium on the same machine (driven over the DevTools
   protocol, testkit/chromium.py). Measured in the page over ``--seconds`` after a warm-up: frames drawn per
   second, the median glass-to-page latency (capture time -> frame decoded in the page), frames dropped before
   restoration and frames the page skipped;
2. file: ``enhance_frames`` (the function behind ``murk enhance``) of the same clip to an MJPEG ``.avi`` as fast
   as it goes: frames/s (the ceiling of the method on this machine, with nothing else to do).

Torch and OpenCV use ``--threads`` threads (default 2). Chromium runs on the same cores (as on a ship's laptop).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # testkit/chromium.py drives Chromium
import cv2
import torch
from _common import machine

from murk.enhance.api import OutputOptions, enhance_frames
from murk.enhance.restorer import create
from murk.io.video import CaptureSource
from murk.live.restore_loop import LivePipeline
from murk.live.server import LiveServer, method_table
from murk.live.source import PacedSource, open_live_source, reopener
from testkit.chromium import chromium
from testkit.video import underwater_clip


def live_run(page, clip: Path, method: str, seconds: float, out: Path) -> dict[str, float]:
    source = PacedSource(open_live_source(str(clip)), reopen=reopener(str(clip), None), loop=True)
    pipeline = LivePipeline(source, lambda s: create(s, shared={"device": "cpu", "batch": 1}), method, out)
    pipeline.start()
    server = LiveServer(pipeline, "127.0.0.1", 0, methods=method_table()).start()
    try:
        page.call("Page.navigate", url=server.url)
        page.wait_for("window.murkStats && murkStats.frames >= 30", timeout_s=120)
        time.sleep(1.0)
        f0, t0 = page.evaluate("murkStats.latencies = []; murkStats.skipped = 0; murkStats.frames"), time.perf_counter()
        r0, d0 = pipeline.restored, pipeline.dropped
        time.sleep(seconds)
        f1, t1 = page.evaluate("murkStats.frames"), time.perf_counter()
        latency = page.evaluate("murkStats.latencyMedianMs")
        skipped = page.evaluate("murkStats.skipped")
        r1, d1 = pipeline.restored, pipeline.dropped
    finally:
        page.call("Page.navigate", url="about:blank")
        server.stop()
        pipeline.stop()
    return {
        "page_fps": (f1 - f0) / (t1 - t0),
        "restored_fps": (r1 - r0) / (t1 - t0),
        "latency_ms": float(latency),
        "dropped": d1 - d0,
        "skipped": skipped,
        "captured": round((t1 - t0) * 30),
    }


def file_run(clip: Path, method: str, out: Path) -> float:
    restorer = create(method, shared={"device": "cpu", "batch": 1})
    with CaptureSource(clip) as source:
        report = enhance_frames(source, restorer, out, OutputOptions(overwrite=True))
    return report.fps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--methods", default="lite,lite+post,post")
    ap.add_argument("--sizes", default="640x480,1280x720")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    cv2.setNumThreads(args.threads)
    print(machine())
    print(f"threads {args.threads}; page measured over {args.seconds:g} s; source 30 frames/s MJPEG, looped")
    rows = []
    with tempfile.TemporaryDirectory() as tmp, chromium(Path(tmp) / "profile") as open_page:
        page = open_page("about:blank")
        for size in args.sizes.split(","):
            w, h = (int(v) for v in size.split("x"))
            clip = underwater_clip(Path(tmp) / f"clip_{size}.avi", n=300, w=w, h=h)
            for method in args.methods.split(","):
                live = live_run(page, clip, method, args.seconds, Path(tmp) / "live")
                fps_file = file_run(clip, method, Path(tmp) / f"out_{size}.avi")
                rows.append((size, method, live, fps_file))
                print(
                    f"{size} {method:10s} page {live['page_fps']:5.1f} f/s, restored {live['restored_fps']:5.1f} f/s, "
                    f"glass-to-page median {live['latency_ms']:6.1f} ms, dropped {live['dropped']} of "
                    f"~{live['captured']}, page skipped {live['skipped']} | murk enhance to a file {fps_file:5.1f} f/s "
                    f"(page / file {live['page_fps'] / fps_file:.2f})",
                    flush=True,
                )
    print(
        "\n| size | method | page, frames/s | restored, frames/s | glass-to-page median, ms | dropped / captured "
        "| page skipped | `murk enhance` to a file, frames/s |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for size, method, live, fps_file in rows:
        print(
            f"| {size} | `{method}` | {live['page_fps']:.1f} | {live['restored_fps']:.1f} | {live['latency_ms']:.0f} | "
            f"{live['dropped']} / ~{live['captured']} | {live['skipped']} | {fps_file:.1f} |"
        )


if __name__ == "__main__":
    main()
