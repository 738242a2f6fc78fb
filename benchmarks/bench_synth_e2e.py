"""``murk synth`` end to end, PNG written, against a plain float64 numpy + ``cv2.imwrite`` script (issue 29).

Both are whole commands started from the shell on the same 640x480 RGB-D folder (the shipped Redwood pair,
copied ``--images`` times), one worker, OpenCV and BLAS at one thread, ``--variants`` variants per image; the
time is the command's wall time (interpreter start included) divided by the variants written. The plain script
is what a user would write: Eq. (1) in float64 (Eqs. (5)-(6) with ``cv2.GaussianBlur`` for ``forward_scatter``;
marine snow: each particle alpha-blended in a loop), ``cv2.imwrite`` with OpenCV's default PNG settings for the
degraded image of every variant and the clean image and depth map once per image, as murk writes them.
Runs alternate (murk, plain, murk, plain, ...) and the best of ``--repeats`` is kept.

Also: the time from the command's start until a 2-worker ``murk synth`` has written its first variant.

Run: PYTHONPATH=src python benchmarks/bench_synth_e2e.py [--images 8 --variants 8 --repeats 3] [--src OTHER/src]
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ONE_THREAD = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "OPENCV_FOR_THREADS_NUM": "1",
}

PLAIN = textwrap.dedent(
    '''
    """The plain script: float64 numpy, cv2.imwrite (OpenCV's default PNG settings)."""
    import sys
    from pathlib import Path

    import cv2
    import numpy as np

    cv2.setNumThreads(1)
    src, out, variants, stages = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3]), sys.argv[4].split(",")
    bank = np.load(sys.argv[5]) if "marine_snow" in stages else None
    for sub in ("degraded", "clean", "depth"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    for rgb_path in sorted((src / "rgb").iterdir()):
        j8 = cv2.imread(str(rgb_path))
        d16 = cv2.imread(str(src / "depth" / f"{rgb_path.stem}.png"), cv2.IMREAD_UNCHANGED)
        cv2.imwrite(str(out / "clean" / f"{rgb_path.stem}.png"), j8)
        cv2.imwrite(str(out / "depth" / f"{rgb_path.stem}.png"), d16)
        j = j8.astype(np.float64) / 255.0
        d = d16.astype(np.float64) / 1000.0
        for k in range(variants):
            beta = rng.uniform(0.05, 0.6, 3)
            b_inf = rng.uniform(0.05, 0.5, 3)
            dist = 0.3 + d / d.max() * (rng.uniform(2, 12) - 0.3)
            t = np.exp(-beta[None, None, :] * dist[:, :, None])
            img = j * t + b_inf[None, None, :] * (1.0 - t)
            if "forward_scatter" in stages:
                blurred = cv2.GaussianBlur(img, (0, 0), 1.0 + 0.5 * dist.max())
                a = (1.0 - np.exp(-0.2 * dist))[:, :, None]
                img = (1.0 - a) * img + a * blurred
            if bank is not None:
                pix, offs, hw = bank["pixels"], bank["offsets"], bank["sizes"]
                for i in rng.integers(0, len(hw), 300):
                    h, w = hw[i]
                    p = pix[offs[i] : offs[i] + h * w].reshape(h, w, 4).astype(np.float64) / 255.0
                    y, x = rng.integers(0, img.shape[0] - h), rng.integers(0, img.shape[1] - w)
                    alpha = 0.8 * p[:, :, 3:]
                    img[y : y + h, x : x + w] = alpha * p[:, :, :3] + (1 - alpha) * img[y : y + h, x : x + w]
            out8 = (np.clip(img, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
            cv2.imwrite(str(out / "degraded" / f"{rgb_path.stem}_v{k}.png"), out8)
    '''
)


def make_input(root: Path, images: int) -> Path:
    from murk.data import sample_rgbd_dir
    from murk.io import discover

    sources, _ = discover(sample_rgbd_dir())
    src = next(s for s in sources if s.stem.startswith("redwood"))  # 640x480
    for sub in ("rgb", "depth"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    for i in range(images):
        shutil.copy(src.rgb_path, root / "rgb" / f"img{i:03d}{Path(src.rgb_path).suffix}")
        shutil.copy(src.depth_path, root / "depth" / f"img{i:03d}.png")
    return root


def plain_bank(path: Path) -> Path:
    """The default particle bank as plain arrays for the plain script: per particle an RGB patch (uint8) and its
    mask, flattened, with offsets and sizes."""
    import numpy as np

    from murk.snow.bank import load_bank

    bank = load_bank("builtin:snow")
    pixels, offsets, sizes, pos = [], [], [], 0
    for i in range(len(bank.offsets) - 1):
        sl = slice(int(bank.offsets[i]), int(bank.offsets[i + 1]))
        yx = np.rint(bank.pixel_yx[sl] - bank.pixel_yx[sl].min(axis=0)).astype(int)
        h, w = yx.max(axis=0) + 1
        patch = np.zeros((h, w, 4), np.uint8)
        patch[yx[:, 0], yx[:, 1], :3] = bank.pixel_rgb[sl]
        patch[yx[:, 0], yx[:, 1], 3] = 255
        pixels.append(patch.reshape(-1, 4))
        offsets.append(pos)
        sizes.append((h, w))
        pos += h * w
    np.savez(path, pixels=np.concatenate(pixels), offsets=np.array(offsets), sizes=np.array(sizes))
    return path


def run(cmd: list[str], env: dict[str, str]) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    return time.perf_counter() - t0


def first_variant_s(inp: Path, out: Path, env: dict[str, str], workers: int) -> float:
    """Seconds from the command's start until its first degraded image exists."""
    cmd = [sys.executable, "-m", "murk", "synth", str(inp), str(out), "--workers", str(workers), "-q"]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    first = None
    while proc.poll() is None and first is None:
        if (out / "degraded").is_dir() and any(p.suffix == ".png" for p in (out / "degraded").iterdir()):
            first = time.perf_counter() - t0
        time.sleep(0.005)
    proc.wait()
    return first if first is not None else time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=4)
    ap.add_argument("--variants", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--src", default=str(Path(__file__).resolve().parents[1] / "src"), help="the murk tree to run")
    args = ap.parse_args()
    env = {**os.environ, **ONE_THREAD}
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # modules' bytecode cached, as on a user's machine (dev shells set it)
    src_dir = args.src
    env["PYTHONPATH"] = src_dir + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    n = args.images * args.variants
    print(f"# bench_synth_e2e  {time.strftime('%Y-%m-%d %H:%M')}  {os.cpu_count()} cpus  640x480, {n} variants")
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        inp = make_input(root / "in", args.images)
        script = root / "plain.py"
        script.write_text(PLAIN)
        bank = plain_bank(root / "bank.npz")
        for stages in ("basic", "basic,forward_scatter,marine_snow"):
            times: dict[str, list[float]] = {"murk": [], "plain": []}
            for r in range(args.repeats):
                for who in ("murk", "plain"):
                    out = root / f"out-{who}-{r}"
                    if who == "murk":
                        cmd = [sys.executable, "-m", "murk", "synth", str(inp), str(out), "--stages", stages]
                        cmd += ["--variants", str(args.variants), "--workers", "1", "-q"]
                    else:
                        cmd = [sys.executable, str(script), str(inp), str(out), str(args.variants), stages, str(bank)]
                    times[who].append(run(cmd, env))
                    shutil.rmtree(out)
            m, p = min(times["murk"]) / n * 1e3, min(times["plain"]) / n * 1e3
            print(f"{stages:34s} murk {m:6.1f} ms/variant   plain {p:6.1f} ms/variant   ratio x{p / m:.2f}")
        for workers in (1, 2):
            firsts = [first_variant_s(inp, root / f"first-{workers}-{r}", env, workers) for r in range(args.repeats)]
            print(f"first variant written, --workers {workers}: {min(firsts):.2f} s after the command's start (best)")


if __name__ == "__main__":
    main()
