"""A folder of real photos of mixed sizes through ``murk enhance DIR --method jointid``, side by side with today's
OpenMP setting and with one size repeated (issue 29, part 4).

Run: PYTHONPATH=src python benchmarks/bench_mixed_sizes.py [--images 100] [--rounds 2] [--paths today,new]

The folders are built at run time from murk's shipped underwater photos (``src/murk/data/underwater``):

- ``mixed``: ``--images`` crops of random sizes, long side 64-256 px, aspect 1:1 to 2:1, either orientation
  (seed 0; JPEG quality 95): 100 images have 100 different sizes, which pad to 30 different network shapes
  (multiples of 32);
- ``repeated``: as many crops of one size, the median-area shape of ``mixed`` (the same per-shape work paid once).

Each is restored by the command line as a user runs it (a fresh ``python -m murk enhance DIR --out OUT --method
jointid`` process, the shipped weights, 2 threads: torch's default on 2 cores), so s/image includes the start of
the command and the first call of every shape. Paths (``--paths``):

- ``today``: the OpenMP wait setting before this change (GNU OpenMP's default for an unset ``OMP_WAIT_POLICY``:
  idle threads spin for about 3 ms; reproduced exactly with ``GOMP_SPINCOUNT=300000``, which murk leaves alone);
- ``new``: murk's default now, ``OMP_WAIT_POLICY=PASSIVE`` (``murk/_perf.py``);
- ``one-thread``: ``OMP_NUM_THREADS=1`` (for reference).

Paths and folders run interleaved, ``--rounds`` times; the best and the worst round are printed with the load
average (the development machine is shared: read the figures with it). The outputs of every path are compared with
the first path's, byte for byte (the wait policy changes timing only; one thread may round differently).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cv2
import numpy as np
from _common import machine

from murk.data import sample_underwater_images

ROOT = Path(__file__).resolve().parents[1]
PATHS = {
    "today": {"GOMP_SPINCOUNT": "300000"},
    "new": {},
    "one-thread": {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"},
}
WAIT_VARIABLES = ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "KMP_BLOCKTIME", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def _photos() -> list[np.ndarray]:
    return [cv2.imread(str(p), cv2.IMREAD_COLOR) for p in sample_underwater_images()]


def _crop(img: np.ndarray, h: int, w: int, rng: np.random.Generator) -> np.ndarray:
    """A random ``h`` x ``w`` crop of ``img`` shrunk (area interpolation) just enough to cover the crop."""
    s = max(h / img.shape[0], w / img.shape[1])
    size = (max(w, int(np.ceil(img.shape[1] * s))), max(h, int(np.ceil(img.shape[0] * s))))
    r = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
    y, x = int(rng.integers(0, r.shape[0] - h + 1)), int(rng.integers(0, r.shape[1] - w + 1))
    return r[y : y + h, x : x + w]


def build_folders(root: Path, n: int, seed: int = 0) -> tuple[Path, Path, list[tuple[int, int]]]:
    """``root/mixed`` (random sizes, long side 64-256 px) and ``root/repeated`` (the median-area size ``n``
    times); returns both folders and the mixed sizes."""
    rng = np.random.default_rng(seed)
    photos = _photos()
    sizes = []
    for _ in range(n):
        long = int(rng.integers(64, 257))
        short = max(32, round(long * rng.uniform(0.5, 1.0)))
        sizes.append((long, short) if rng.random() < 0.3 else (short, long))
    mixed, repeated = root / "mixed", root / "repeated"
    mixed.mkdir()
    repeated.mkdir()
    median = sorted(sizes, key=lambda hw: hw[0] * hw[1])[n // 2]
    for i, (h, w) in enumerate(sizes):
        photo = photos[i % len(photos)]
        cv2.imwrite(str(mixed / f"img_{i:03d}.jpg"), _crop(photo, h, w, rng), [cv2.IMWRITE_JPEG_QUALITY, 95])
        cv2.imwrite(str(repeated / f"img_{i:03d}.jpg"), _crop(photo, *median, rng), [cv2.IMWRITE_JPEG_QUALITY, 95])
    return mixed, repeated, sizes


def run_cli(src: Path, out: Path, extra_env: dict[str, str]) -> tuple[float, float]:
    """``python -m murk enhance src --out out --method jointid`` in a fresh process; returns (wall seconds,
    restore milliseconds per image as the command reports them)."""
    env = {k: v for k, v in os.environ.items() if k not in WAIT_VARIABLES}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")]))
    env.update(extra_env)
    cmd = [sys.executable, "-m", "murk", "enhance", str(src), "--out", str(out), "--method", "jointid", "--overwrite"]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited with {proc.returncode}:\n{proc.stdout}\n{proc.stderr}")
    m = re.search(r"per image:.*restore ([\d.,]+) ms", proc.stdout + proc.stderr)
    return wall, float(m[1].replace(",", "")) if m else float("nan")


def compare_outputs(a: Path, b: Path) -> str:
    """``identical`` when the two output folders hold the same files byte for byte, else the largest difference
    of the decoded restored images (depth maps and previews aside) in 1/255 steps."""
    fa = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file() and p.suffix in (".jpg", ".png"))
    fb = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file() and p.suffix in (".jpg", ".png"))
    if fa != fb:
        return "different files"
    if all((a / f).read_bytes() == (b / f).read_bytes() for f in fa):
        return "identical"
    diff = max(
        int(np.abs(cv2.imread(str(a / f)).astype(int) - cv2.imread(str(b / f)).astype(int)).max())
        for f in fa
        if len(f.parts) == 1
    )
    return f"not byte-identical; restored images decoded: max |diff| {diff}/255"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=100)
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--paths", default="today,new", help=f"comma list of {', '.join(PATHS)}")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    paths = [p.strip() for p in args.paths.split(",")]
    unknown = [p for p in paths if p not in PATHS]
    if unknown:
        ap.error(f"--paths: unknown {unknown}; known: {', '.join(PATHS)}")
    print(f"{machine()}; load average {os.getloadavg()[0]:.2f} at the start")
    with tempfile.TemporaryDirectory(prefix="bench-mixed-") as tmp:
        root = Path(tmp)
        mixed, repeated, sizes = build_folders(root, args.images, args.seed)
        shapes = {(-(-h // 32) * 32, -(-w // 32) * 32) for h, w in sizes}
        px_mixed = sum(h * w for h, w in sizes)
        med = cv2.imread(str(next(repeated.iterdir()))).shape[:2]
        print(
            f"mixed: {args.images} images, {len({*sizes})} sizes ({len(shapes)} padded network shapes), "
            f"{px_mixed / args.images / 1e3:.1f} kpx per image; repeated: {args.images} x {med[0]}x{med[1]} "
            f"({med[0] * med[1] / 1e3:.1f} kpx)"
        )
        folders = {"mixed": (mixed, px_mixed), "repeated": (repeated, args.images * med[0] * med[1])}
        runs: dict[tuple[str, str], list[tuple[float, float, float]]] = {}
        for r in range(args.rounds):
            for path in paths:
                for name, (src, _) in folders.items():
                    load = os.getloadavg()[0]
                    wall, restore_ms = run_cli(src, root / f"out-{path}-{name}", PATHS[path])
                    runs.setdefault((path, name), []).append((wall, restore_ms, load))
                    print(
                        f"round {r + 1} {path:10s} {name:8s}: {wall / args.images:.3f} s/image "
                        f"(restore {restore_ms:.0f} ms/image), load {load:.2f}",
                        flush=True,
                    )
        print()
        print("| path | folder | s/image, best round (worst) | restore ms/image, best | ms per megapixel, best |")
        print("|---|---|---|---|---|")
        for (path, name), rs in runs.items():
            best, worst = min(rs), max(rs)
            mpx = folders[name][1] / 1e6
            print(
                f"| {path} | {name} | {best[0] / args.images:.3f} ({worst[0] / args.images:.3f}) | {best[1]:.0f} | "
                f"{best[0] * 1e3 / mpx:.0f} |"
            )
        for name in folders:
            for p in paths[1:]:
                verdict = compare_outputs(root / f"out-{paths[0]}-{name}", root / f"out-{p}-{name}")
                print(f"{name}: outputs of {p} against {paths[0]}: {verdict}")
        print(f"load average {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
