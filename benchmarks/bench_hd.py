"""HD in real time (issue 48): ``murk enhance`` file to file and ``murk live`` at 1280x720 and 1920x1080, this tree
side by side with a previous one, and where the time of one frame goes.

Run: PYTHONPATH=src python benchmarks/bench_hd.py [--baseline OLD_SRC] [--tree SRC] [--sizes 1280x720,1920x1080]
     [--methods lite,lite+post] [--rounds 5] [--threads 2] [--stages] [--file] [--live] [--codecs] [--seconds 10]
     [--foxglove off,idle,subscribed]

``OLD_SRC`` is the ``src`` folder of the previous tree (``git archive COMMIT src | tar -x -C /tmp/old``). The
clips are made here: MJPEG ``.avi`` files at 30 frames/s that pan one pixel a frame over the real underwater
photographs shipped in ``src/murk/data/underwater`` (a new photograph every 60 frames), 160 frames each.

- ``--file``: ``enhance_frames`` (the function behind ``murk enhance CLIP --out OUT.avi --method M``) from the
  clip to an MJPEG ``.avi``, each run in a fresh process of the tree measured, frames/s = 140 / (t150 - t10) (the
  times at which the 10th and the 150th frame were handed to the writer: start-up excluded), trees alternating
  run by run (``--rounds`` each), medians. Every output is checked: 160 frames, and each frame of this tree's
  video nearest to the previous tree's frame of the same index (nothing lost or reordered; the mean absolute
  difference is printed).
- ``--live``: what ``murk live CLIP --loop --method M`` runs (the clip paced at its 30 frames/s, looped, the frame
  pipeline and the web server) with a client that pulls ``/api/frame?after=N`` as the page does, for
  ``--seconds`` after 2 s of warm-up: frames/s received, the median latency from capture to receipt and the median
  size of a frame's response (the page's JPEGs).
  Alternating trees as for ``--file``. ``--foxglove off,idle,subscribed`` also runs it with ``murk live
  --foxglove``'s publisher, with no client (idle) or a client subscribed to ``/murk/raw`` and ``/murk/restored``.
- ``--publish``: the CPU of ``murk live``'s publish thread per view of each size, in each tree (a fresh process,
  one OpenCV thread, trees alternating, ``--rounds`` each): the page's JPEGs, and with a Foxglove client subscribed
  to raw and restored also theirs (the JPEG calls the publish thread and the publisher make; median of 40 views of
  the clip's frames).
- ``--stages``: this process's tree, stage by stage on one frame of each size, wall and CPU milliseconds (median
  of 15, after a warm-up): the previous float32 path's steps and this tree's 8-bit path's.
- ``--codecs``: the writers ``murk enhance`` can write a video with (:class:`murk.io.video.VideoSink`: OpenCV's MJPEG
  ``.avi`` and ``mp4v`` ``.mp4``, PyAV's MJPEG ``.avi`` and H.264 ``.mp4``), 60 decoded frames of the clip each, on
  one thread as the write-behind thread runs them (OpenCV at 1 thread, as while frames restore two at a time): CPU
  ms per frame (all threads, encoder threads included), wall ms, kB per frame and the PSNR of the video read back
  against the frames written.

Torch and OpenCV use ``--threads`` threads; workers run with ``OMP_WAIT_POLICY=PASSIVE`` and glibc's allocator
tuned (:func:`murk._perf.tune_allocator`), as the ``murk`` command sets them (:mod:`murk._perf`). The script prints
the machine's load (``os.getloadavg``) before and after: on a busy machine figures are only comparable within one
run.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from pathlib import Path
from typing import Any

FRAMES = 160
FPS = 30.0
HERE = Path(__file__).resolve()
SRC = HERE.parents[1] / "src"


def make_clip(path: Path, w: int, h: int, n: int = FRAMES) -> Path:
    """An MJPEG clip panning one pixel a frame over the shipped underwater photographs (the live tests' clip)."""
    from testkit.video import underwater_clip

    return underwater_clip(path, n, fps=FPS, w=w, h=h)


# ---------------------------------------------------------------------------------------------------------------
# Workers: run in a fresh process with PYTHONPATH set to the tree measured (APIs common to both trees only).


def _threads(n: int) -> None:
    """Torch and OpenCV on ``n`` threads, and glibc's allocator tuned as the ``murk`` command tunes it (trees
    without :func:`murk._perf.tune_allocator` keep glibc's defaults)."""
    import cv2
    import torch

    torch.set_num_threads(n)
    cv2.setNumThreads(n)
    try:
        from murk._perf import tune_allocator
    except ImportError:
        return
    tune_allocator()


def worker_file(src: str, method: str, out: str, threads: int) -> dict[str, float]:
    _threads(threads)
    try:
        from murk.enhance.api import OutputOptions, enhance_frames
    except ModuleNotFoundError:  # a tree before the rename of 95081ef
        from murk.enhance.pipeline import OutputOptions, enhance_frames  # type: ignore[no-redef]
    from murk.enhance.restorer import create
    from murk.io.video import CaptureSource

    marks: dict[int, tuple[float, float]] = {}

    def progress(report: object) -> None:
        for n in (10, 150):
            if report.processed >= n and n not in marks:  # type: ignore[attr-defined]
                marks[n] = (time.perf_counter(), time.process_time())

    restorer = create(method)
    opts = OutputOptions(overwrite=True, video_backend="opencv")
    with CaptureSource(src) as source:
        report = enhance_frames(source, restorer, Path(out), opts, on_progress=progress)
    (t10, c10), (t150, c150) = marks[10], marks[150]
    return {"fps": 140.0 / (t150 - t10), "cpu_ms": 1e3 * (c150 - c10) / 140.0, "processed": report.processed}


def _foxglove(mode: str) -> tuple[Any, Any]:
    """``murk live --foxglove``'s publisher (``mode`` "idle": no client; "subscribed": a client subscribed to
    ``/murk/raw`` and ``/murk/restored``, its messages read and dropped on a thread), or (None, None) for "off"."""
    if mode == "off":
        return None, None
    from murk.live.foxglove_publisher import FoxglovePublisher

    publisher = FoxglovePublisher("127.0.0.1", 0)
    if mode == "idle":
        return publisher, None
    sys.path.insert(0, str(HERE.parents[1]))
    from testkit.ws import WebSocket

    ws = WebSocket(f"ws://127.0.0.1:{publisher.port}/", subprotocol="foxglove.sdk.v1", timeout_s=30)
    channels: dict[str, int] = {}
    while not {"/murk/raw", "/murk/restored"} <= set(channels):
        opcode, payload = ws.recv()
        if opcode == 1 and json.loads(payload).get("op") == "advertise":
            channels |= {ch["topic"]: ch["id"] for ch in json.loads(payload)["channels"]}
    subs = [{"id": i, "channelId": channels[t]} for i, t in enumerate(["/murk/raw", "/murk/restored"], 1)]
    ws.send_text(json.dumps({"op": "subscribe", "subscriptions": subs}))
    while len(publisher.subscribed()) < 2:
        time.sleep(0.01)

    def drain() -> None:
        with contextlib.suppress(OSError, ValueError):
            while True:
                ws.recv()

    threading.Thread(target=drain, daemon=True).start()
    return publisher, ws


def worker_live(src: str, method: str, seconds: float, threads: int, foxglove: str = "off") -> dict[str, float]:
    _threads(threads)
    from murk.enhance.restorer import create

    try:
        from murk.live.restore_loop import LivePipeline
    except ModuleNotFoundError:  # a tree before the rename of f08aabe
        from murk.live.pipeline import LivePipeline  # type: ignore[no-redef]
    from murk.live.server import LiveServer, method_table
    from murk.live.source import PacedSource, open_live_source, reopener

    source = PacedSource(open_live_source(src), reopen=reopener(src, None), loop=True)
    publisher, ws = _foxglove(foxglove)
    with tempfile.TemporaryDirectory() as tmp:
        make = lambda s: create(s, shared={"device": "cpu", "batch": 1})  # noqa: E731
        hooks = [publisher] if publisher is not None else []
        pipeline = LivePipeline(source, make, method, Path(tmp), hooks=hooks)
        pipeline.start()
        server = LiveServer(pipeline, "127.0.0.1", 0, methods=method_table()).start()
        received: list[tuple[float, float, int]] = []  # (receipt s, latency ms, bytes)
        stop = threading.Event()

        def client() -> None:
            after = -1
            while not stop.is_set():
                with urllib.request.urlopen(f"{server.url.rstrip('/')}/api/frame?after={after}", timeout=10) as r:
                    if r.status != 200:
                        continue
                    size = len(r.read())
                    now_ms = time.time_ns() / 1e6
                    after = int(r.headers["X-Murk-Frame"])
                    received.append((time.perf_counter(), now_ms - float(r.headers["X-Murk-Capture-Ms"]), size))

        thread = threading.Thread(target=client, daemon=True)
        thread.start()
        time.sleep(2.0)
        t0, d0 = time.perf_counter(), pipeline.dropped
        time.sleep(seconds)
        t1, d1 = time.perf_counter(), pipeline.dropped
        stop.set()
        thread.join(15)
        server.stop()
        pipeline.stop()
    if ws is not None:
        ws.close()
    if publisher is not None:
        publisher.close()
    window = [(lat, size) for t, lat, size in received if t0 <= t < t1]
    return {
        "fps": len(window) / (t1 - t0),
        "latency_ms": statistics.median(lat for lat, _ in window) if window else float("nan"),
        "dropped": d1 - d0,
        "kb": statistics.median(size for _, size in window) / 1e3 if window else float("nan"),
    }


def worker_publish(src: str, threads: int) -> dict[str, float]:
    """CPU ms per view of the publish thread's JPEGs, without and with a Foxglove client on raw and restored."""
    import cv2

    from murk.live.restore_loop import LiveView

    cv2.setNumThreads(1)
    capture, frames = cv2.VideoCapture(src), []
    while len(frames) < 40:
        ok, bgr = capture.read()
        if not ok:
            break
        frames.append(cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB))
    capture.release()
    shared = hasattr(LiveView, "page_jpegs")  # this tree: two page JPEGs, shared with Foxglove's

    def view_ms(i: int, subscribed: bool) -> float:
        view = LiveView(i, frames[i], frames[-1 - i], None, 0, 0, 0, "lite")
        full = ("raw", "restored") if subscribed else ()
        t = time.process_time()
        if shared:
            view.page_jpegs(full)  # type: ignore[attr-defined]
        else:
            view.jpeg("pair")
        for key in full:  # what the Foxglove publisher takes (already encoded where shared)
            view.jpeg(key, 85)
        return 1e3 * (time.process_time() - t)

    out = {}
    for subscribed in (False, True):
        view_ms(0, subscribed)  # warm-up
        out["subscribed" if subscribed else "off"] = statistics.median(view_ms(i, subscribed) for i in range(40))
    return out


def run_worker(tree: Path, kind: str, threads: int, **kw: object) -> dict[str, float]:
    env = dict(os.environ, PYTHONPATH=str(tree), OMP_WAIT_POLICY="PASSIVE")  # as the murk command sets it
    cmd = [sys.executable, str(HERE), "--worker", kind, "--threads", str(threads), "--args", json.dumps(kw)]
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    if done.returncode:
        raise RuntimeError(f"{kind} worker failed in {tree}:\n{done.stderr[-3000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


# ---------------------------------------------------------------------------------------------------------------
# Checks of the outputs


def read_frames(path: Path) -> list:
    from testkit.video import read_video

    return read_video(path)


def order_check(new: Path, old: Path) -> tuple[int, float, bool]:
    """(frames in ``new``, the largest mean absolute difference of a frame to the old frame of the same index,
    whether every new frame is nearest to the old frame of its own index among indices i - 2 .. i + 2)."""
    import numpy as np

    a, b = read_frames(new), read_frames(old)
    worst, ordered = 0.0, len(a) == len(b)
    for i, f in enumerate(a[: len(b)]):
        near = {j: float(np.mean(np.abs(f.astype(np.int16) - b[j]))) for j in range(max(0, i - 2), min(len(b), i + 3))}
        worst = max(worst, near[i])
        ordered &= min(near, key=near.get) == i  # type: ignore[arg-type]
    return len(a), worst, ordered


# ---------------------------------------------------------------------------------------------------------------
# Stages


def stages(sizes: list[tuple[int, int]], threads: int, tmp: Path) -> None:
    import cv2
    import numpy as np
    import torch

    _threads(threads)
    torch.set_grad_enabled(False)
    from murk.enhance import lite_restorer as lr
    from murk.enhance import lite_u8
    from murk.enhance.frames_u8 import restore_frames, to_u8
    from murk.enhance.restorer import create
    from murk.io.images import swap_red_blue, to_float, to_uint
    from murk.io.video import VideoSink
    from murk.live.restore_loop import encode_jpeg, page_pair
    from murk.models.lite.network import work_image, work_size
    from murk.restore_ops.balance import apply_levels, balance_levels

    lite, post, chain = create("lite"), create("post"), create("lite+post")
    pct = lite.input_balance_pct
    print("\nstage by stage, one frame: wall ms / CPU ms (median of 15; CPU = all threads of this process)")
    print("| stage | " + " | ".join(f"{w}x{h}" for w, h in sizes) + " |")
    print("|---|" + "---|" * len(sizes))
    rows: dict[str, list[str]] = {}
    for w, h in sizes:
        clip = make_clip(tmp / f"stage_{w}x{h}.avi", w, h, n=20)
        cap = cv2.VideoCapture(str(clip))
        _, bgr = cap.read()
        cap.release()
        rgb = swap_red_blue(bgr)
        f32 = to_float(rgb)
        levels = balance_levels(f32, pct, pct)
        bal = apply_levels(f32, levels)
        x = torch.from_numpy(bal).permute(2, 0, 1)[None]
        work = work_image(x, lite.work_area_px)
        out_f = lite.restore(f32[None]).images[0]
        out_u8 = to_uint(out_f, 8)
        table = lite_u8.balance_table(levels)
        size = work_size(h, w, lite.work_area_px)
        sink = VideoSink(tmp / f"sink_{w}x{h}.avi", FPS, (w, h), backend="opencv")
        caps = [cv2.VideoCapture(str(clip))]

        def decode(caps: list = caps, clip: Path = clip) -> None:
            ok, _ = caps[0].read()
            if not ok:
                caps[0].release()
                caps[0] = cv2.VideoCapture(str(clip))
                caps[0].read()

        steps = {
            "read + decode (OpenCV, MJPEG)": decode,
            "BGR -> RGB, numpy copy (before)": lambda bgr=bgr: np.ascontiguousarray(bgr[:, :, 2::-1]),
            "BGR -> RGB, cvtColor (after)": lambda bgr=bgr: swap_red_blue(bgr),
            "before: to float32": lambda rgb=rgb: to_float(rgb),
            "before: balance levels": lambda f=f32: balance_levels(f, pct, pct),
            "before: apply levels": lambda f=f32, lv=levels: apply_levels(f, lv),
            "before: working image (torch area)": lambda x=x: work_image(x, lite.work_area_px),
            "network (maps of the working image)": lambda work=work: lite.model.maps(work),
            "before: full-resolution apply": lambda x=x, work=work: lr._forward_cpu(lite.model, x, work),
            "before: to uint8": lambda o=out_f: to_uint(o, 8),
            "before: lite, all steps": lambda f=f32: to_uint(lite.restore(f[None]).images[0], 8),
            "after: balance levels (8-bit sample)": lambda rgb=rgb: lite_u8.frame_levels(rgb, pct),
            "after: pass 1 (table + working image)": lambda rgb=rgb, t=table, s=size: lite_u8.area_pool(rgb, t, s),
            "after: lite, all steps": lambda rgb=rgb: restore_frames(lite, rgb[None]),
            "post (float32 frame)": lambda o=out_f: post.restore(o[None]),
            "after: lite+post, all steps": lambda rgb=rgb: restore_frames(chain, rgb[None]),
            "after: to uint8": lambda o=out_f: to_u8(o),
            "encode + write (OpenCV MJPG .avi)": lambda u=out_u8, s=sink: s.write(u),
            "page JPEG, raw + restored at full size, q85 (before)": lambda r=rgb, u=out_u8: encode_jpeg(
                np.concatenate([r, u], 1), 85
            ),
            "page JPEG, the pair at most 1920 px wide, q85 (after)": lambda r=rgb, u=out_u8: encode_jpeg(
                page_pair(r, u), 85
            ),
        }
        for label, fn in steps.items():
            fn()
            wall, cpu = [], []
            for _ in range(15):
                c0, t0 = time.process_time(), time.perf_counter()
                fn()
                wall.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
            rows.setdefault(label, []).append(
                f"{1e3 * statistics.median(wall):.1f} / {1e3 * statistics.median(cpu):.1f}"
            )
        sink.abort()
        caps[0].release()
    for label, cells in rows.items():
        print(f"| {label} | " + " | ".join(cells) + " |")


# ---------------------------------------------------------------------------------------------------------------
# Encoders


def codecs(clips: dict[tuple[int, int], Path], tmp: Path) -> None:
    import cv2

    cv2.setNumThreads(1)
    from murk.io.video import CaptureSource, VideoSink, av_available

    writers = [("OpenCV MJPG .avi (murk's default for .avi)", "opencv", ".avi")]
    writers.append(("OpenCV mp4v .mp4 (murk's default for .mp4)", "opencv", ".mp4"))
    if av_available():
        writers += [("PyAV mjpeg q:v 3 .avi", "av", ".avi"), ("PyAV libx264 veryfast crf 18 .mp4", "av", ".mp4")]
    print("\nencoders: 60 frames of the clip through VideoSink (OpenCV at 1 thread)")
    print("| writer | size | CPU ms/frame | wall ms/frame | kB/frame | PSNR dB |")
    print("|---|---|---|---|---|---|")
    for (w, h), clip in clips.items():
        with CaptureSource(clip) as source:
            frames = [f.image for f, _ in zip(source, range(60), strict=False)]
        for label, backend, suffix in writers:
            path = tmp / f"codec_{w}x{h}_{backend}{suffix}"
            sink = VideoSink(path, FPS, (w, h), backend=backend)  # type: ignore[arg-type]
            sink.write(frames[0])  # the encoder's start-up
            c0, t0 = time.process_time(), time.perf_counter()
            for frame in frames[1:]:
                sink.write(frame)
            cpu, wall = time.process_time() - c0, time.perf_counter() - t0
            sink.close()
            back = read_frames(path)
            assert len(back) == len(frames), f"{label}: {len(back)} frames read back of {len(frames)}"
            psnr = statistics.mean(float(cv2.PSNR(a, b)) for a, b in zip(frames, back, strict=True))
            n = len(frames) - 1
            kb = path.stat().st_size / len(frames) / 1e3
            print(
                f"| {label} | {w}x{h} | {1e3 * cpu / n:.1f} | {1e3 * wall / n:.1f} | {kb:.0f} | {psnr:.1f} |",
                flush=True,
            )
            del back


# ---------------------------------------------------------------------------------------------------------------


def load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min)"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--worker", choices=["file", "live", "publish"])
    ap.add_argument("--args", default="{}")
    ap.add_argument("--baseline", type=Path, help="src folder of the previous tree")
    ap.add_argument("--tree", type=Path, default=SRC, help="src folder of the tree measured (default: this one)")
    ap.add_argument("--sizes", default="1280x720,1920x1080")
    ap.add_argument("--methods", default="lite,lite+post")
    ap.add_argument("--live-methods", default="lite")
    ap.add_argument(
        "--foxglove",
        default="off",
        help="--live with murk live --foxglove: comma-separated modes off, idle (no client), subscribed (raw+restored)",
    )
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--stages", action="store_true")
    ap.add_argument("--file", action="store_true")
    ap.add_argument("--live", action="store_true")
    ap.add_argument("--codecs", action="store_true")
    ap.add_argument("--publish", action="store_true")
    args = ap.parse_args()
    if args.worker:
        kw = json.loads(args.args)
        fn = {"file": worker_file, "live": worker_live, "publish": worker_publish}[args.worker]
        print(json.dumps(fn(threads=args.threads, **kw)))
        return
    sys.path.insert(0, str(HERE.parent))
    sys.path.insert(0, str(HERE.parent.parent))  # tests/live/_live.py makes the clips, as for bench_live_view
    from _common import machine

    sizes = [tuple(int(v) for v in s.split("x")) for s in args.sizes.split(",")]
    trees = {"this tree": args.tree.resolve()} | ({"previous tree": args.baseline.resolve()} if args.baseline else {})
    print(machine())
    print(f"threads {args.threads}; {load()}; trees: " + ", ".join(f"{k} = {v}" for k, v in trees.items()))
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        clips = {(w, h): make_clip(tmp / f"clip_{w}x{h}.avi", w, h) for w, h in sizes}
        if args.stages:
            stages(sizes, args.threads, tmp)  # type: ignore[arg-type]
        if args.codecs:
            codecs(clips, tmp)
        if args.publish:
            cpu: dict[tuple, list[dict[str, float]]] = {}
            for r in range(args.rounds):
                for (w, h), clip in clips.items():
                    for tree, path in trees.items() if r % 2 == 0 else reversed(trees.items()):
                        cpu.setdefault((w, h, tree), []).append(run_worker(path, "publish", 1, src=str(clip)))
            print("\nmurk live's publish thread, CPU ms per view (median of the rounds; every round in brackets)")
            for (w, h, tree), runs in cpu.items():
                cells = [
                    f"{mode} {statistics.median(x[mode] for x in runs):.2f} ms ("
                    + ", ".join(f"{x[mode]:.2f}" for x in runs)
                    + ")"
                    for mode in ("off", "subscribed")
                ]
                print(f"{w}x{h} {tree:14s} " + "; Foxglove ".join(cells))
        if args.file:
            figures: dict[tuple, list[float]] = {}
            for r in range(args.rounds):
                for (w, h), clip in clips.items():
                    for method in args.methods.split(","):
                        for tree, path in trees.items() if r % 2 == 0 else reversed(trees.items()):
                            out = tmp / f"out_{tree[0]}_{w}x{h}_{method}.avi"
                            res = run_worker(path, "file", args.threads, src=str(clip), method=method, out=str(out))
                            figures.setdefault((w, h, method, tree), []).append(res["fps"])
                            figures.setdefault((w, h, method, tree, "cpu"), []).append(res["cpu_ms"])
                print(f"round {r + 1}/{args.rounds} done; {load()}", flush=True)
            print(
                "\nfile to file, frames/s = 140 / (t150 - t10), median of the rounds (all figures), and the CPU time "
                "per frame (all threads) over the same frames"
            )
            for (w, h), _ in clips.items():
                for method in args.methods.split(","):
                    cells = []
                    for tree in trees:
                        v = figures[(w, h, method, tree)]
                        cpu = statistics.median(figures[(w, h, method, tree, "cpu")])
                        cells.append(
                            f"{tree} {statistics.median(v):6.1f} f/s ({', '.join(f'{x:.1f}' for x in v)}), "
                            f"CPU {cpu:.1f} ms/frame"
                        )
                    check = ""
                    if len(trees) == 2:
                        n, worst, ordered = order_check(
                            tmp / f"out_t_{w}x{h}_{method}.avi", tmp / f"out_p_{w}x{h}_{method}.avi"
                        )
                        check = f" | frames {n}, same order {ordered}, worst mean |diff| {worst:.2f}"
                    print(f"{w}x{h} {method:10s} " + " | ".join(cells) + check)
        if args.live:
            figures_live: dict[tuple, list[dict[str, float]]] = {}
            for r in range(max(1, args.rounds // 2)):
                for (w, h), clip in clips.items():
                    for method in args.live_methods.split(","):
                        for fox in args.foxglove.split(","):
                            for tree, path in trees.items() if r % 2 == 0 else reversed(trees.items()):
                                kw: dict[str, object] = {"src": str(clip), "method": method, "seconds": args.seconds}
                                if fox != "off":
                                    kw["foxglove"] = fox
                                res = run_worker(path, "live", args.threads, **kw)
                                label = method if fox == "off" else f"{method} foxglove {fox}"
                                figures_live.setdefault((w, h, label, tree), []).append(res)
                print(f"live round {r + 1} done; {load()}", flush=True)
            print(f"\nmurk live, a client pulling /api/frame?after=N for {args.seconds:g} s (median of the rounds)")
            for (w, h, method, tree), runs in figures_live.items():
                fps = statistics.median(x["fps"] for x in runs)
                lat = statistics.median(x["latency_ms"] for x in runs)
                drops = statistics.median(x["dropped"] for x in runs)
                kb = statistics.median(x["kb"] for x in runs)
                every = ", ".join(f"{x['fps']:.1f} f/s {x['latency_ms']:.0f} ms" for x in runs)
                print(
                    f"{w}x{h} {method:6s} {tree:14s} {fps:5.1f} frames/s, median latency {lat:5.0f} ms, "
                    f"dropped {drops:.0f}, {kb:.0f} kB a frame ({every})"
                )
    print(f"\nend: {load()}")


if __name__ == "__main__":
    main()
