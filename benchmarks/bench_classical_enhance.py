"""What ``murk enhance DIR --method colorbalance`` costs beyond reading and writing the images (issue 47): a
classical method (numpy and OpenCV) should neither import torch nor book torch's start-up in its restore step.

Each round runs, one after the other (so that the load of other processes hits all of them alike):

- the command ``python -m murk enhance DIR --out OUT --method METHOD -q`` (fresh OUT), for the tree under test and,
  with ``--before-src``, an earlier tree;
- the baseline: a fresh interpreter that reads every image with murk's reader and writes it with murk's PNG writer
  (``murk.io.images.read_image`` + ``write_uint``: the codec and the atomic write of ``murk enhance``), nothing else.

Printed: medians over the rounds of the wall and CPU seconds (user + sys, the closer estimate of idle wall time on
a busy machine) of each, the command's own "restore N ms" per image, the command's excess over the baseline, and
whether the outputs of the two trees are the same bytes. Targets: restore at most 5 ms per 640x480 image, the
command at most 1.5 s longer than the baseline.

The images: DIR given with ``--images-dir``, or ``--images`` 640x480 PNGs made from murk's shipped sample images
(each scaled to cover 640x480, a little larger on each pass over the samples, and centre-cropped).

Run:  PYTHONPATH=src python benchmarks/bench_classical_enhance.py [--images 100] [--rounds 5]
      [--method colorbalance] [--before-src DIR]

``--before-src DIR``: the src/ folder of an earlier murk, e.g. ``git worktree add /tmp/before REV`` then
``--before-src /tmp/before/src``.
"""

from __future__ import annotations

import argparse
import filecmp
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _common import tree_envs

_PLAIN = (
    "import sys\n"
    "from pathlib import Path\n"
    "from murk.io.images import read_image, write_uint\n"
    "src, dst = Path(sys.argv[1]), Path(sys.argv[2])\n"
    "dst.mkdir(parents=True)\n"
    "for path in sorted(src.glob('*.png')):\n"
    "    raw, _ = read_image(path)\n"
    "    write_uint(dst / path.name, raw)\n"
)


def make_images(folder: Path, n: int, size: tuple[int, int] = (640, 480)) -> None:
    """``n`` PNGs of ``size`` (width, height) made from the shipped sample images."""
    import cv2

    from murk.data import sample_underwater_images

    samples = sample_underwater_images()
    folder.mkdir(parents=True, exist_ok=True)
    w, h = size
    for i in range(n):
        image = cv2.imread(str(samples[i % len(samples)]), cv2.IMREAD_COLOR)
        scale = max(w / image.shape[1], h / image.shape[0]) * (1.0 + 0.05 * (i // len(samples)))
        big = (max(w, round(image.shape[1] * scale)), max(h, round(image.shape[0] * scale)))
        image = cv2.resize(image, big, interpolation=cv2.INTER_AREA)
        y, x = (image.shape[0] - h) // 2, (image.shape[1] - w) // 2
        cv2.imwrite(str(folder / f"img{i:03d}.png"), image[y : y + h, x : x + w])


def _children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def timed(cmd: list[str], env: dict[str, str]) -> tuple[float, float, str]:
    """Wall seconds, CPU seconds (user + sys) and stdout + stderr of one process."""
    cpu0 = _children_cpu_s()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stdout}{proc.stderr}")
    return wall, _children_cpu_s() - cpu0, proc.stdout + proc.stderr


def same_bytes(a: Path, b: Path) -> bool:
    names = sorted(p.name for p in a.iterdir())
    if names != sorted(p.name for p in b.iterdir()):
        return False
    _, mismatch, errors = filecmp.cmpfiles(a, b, names, shallow=False)
    return not mismatch and not errors


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--images", type=int, default=100, help="How many 640x480 images to make.")
    ap.add_argument("--images-dir", type=Path, default=None, help="Use these PNG images instead.")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--method", default="colorbalance")
    ap.add_argument("--before-src", type=Path, default=None, help="The src/ folder of an earlier murk.")
    args = ap.parse_args()
    trees = tree_envs(
        args.before_src, warm="murk.cli.main, murk.enhance.run"
    )  # .pyc files compiled first: no round pays for it
    env = trees["now"]
    with tempfile.TemporaryDirectory() as tmp_dir:
        tmp = Path(tmp_dir)
        images = args.images_dir
        if images is None:
            images = tmp / "in"
            make_images(images, args.images)
        n = len(list(images.glob("*.png")))
        wall: dict[str, list[float]] = {k: [] for k in [*trees, "read+write"]}
        cpu: dict[str, list[float]] = {k: [] for k in wall}
        restore_ms: dict[str, list[float]] = {k: [] for k in trees}
        for _ in range(args.rounds):
            for name, tree_env in trees.items():
                out = tmp / f"out-{name}"
                shutil.rmtree(out, ignore_errors=True)
                cmd = [sys.executable, "-m", "murk", "enhance", str(images), "--out", str(out), "-m", args.method]
                w, c, text = timed([*cmd, "-q"], tree_env)
                found = re.search(r"restore ([0-9.]+) ms", text)
                if found is None:
                    raise SystemExit(f"no restore time in the output of {' '.join(cmd)}:\n{text}")
                wall[name].append(w)
                cpu[name].append(c)
                restore_ms[name].append(float(found.group(1)))
            plain = tmp / "out-plain"
            shutil.rmtree(plain, ignore_errors=True)
            w, c, _ = timed([sys.executable, "-c", _PLAIN, str(images), str(plain)], env)
            wall["read+write"].append(w)
            cpu["read+write"].append(c)
        base = statistics.median(wall["read+write"])
        print(f"{n} images, method {args.method}, {args.rounds} rounds (medians; CPU = user + sys)")
        base_cpu = statistics.median(cpu["read+write"])
        print(f"read+write (murk.io, fresh interpreter): wall {base:.2f} s, CPU {base_cpu:.2f} s")
        for name in trees:
            w, c, r = (statistics.median(x[name]) for x in (wall, cpu, restore_ms))
            ok = "met" if r <= 5.0 and w - base <= 1.5 else "MISSED"
            print(
                f"murk enhance ({name}): wall {w:.2f} s, CPU {c:.2f} s, restore {r:.1f} ms per image "
                f"(rounds: {', '.join(f'{v:.1f}' for v in restore_ms[name])}); "
                f"{w - base:+.2f} s over read+write; targets (<= 5 ms, <= +1.5 s) {ok}"
            )
        if len(trees) == 2:
            same = same_bytes(tmp / "out-before", tmp / "out-now")
            print(f"outputs of before and now: {'the same bytes' if same else 'DIFFERENT'}")


if __name__ == "__main__":
    main()
