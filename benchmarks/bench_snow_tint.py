"""Real marine snow without a snow-free twin: the particles a restorer leaves, and whether they keep their colour.

Run: PYTHONPATH=src python benchmarks/bench_snow_tint.py IMAGE_OR_DIR [...] [--methods colorbalance lite jointid]
     [--max-side 640]

For each real snowy image and method (the raw input is the baseline row):
- particles out/in: bright particles per megapixel of the output over the input's (murk.metrics.particle_count,
  the no-reference count; it also counts the scene's own small bright details, so read it with the images);
- tint: CIELAB a* at the input's bright particles minus a* in a 4-px ring around them
  (murk.metrics.particle_tint), in the output; rise = output minus input. Issue 46 asks a rise of at most 2.
Means over the images, and each image's rise.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import torch

from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.io.images import list_images
from murk.metrics import particle_count
from murk.metrics.particle_tint import particle_tint
from murk.report.compare import downscale_to


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("inputs", nargs="+", type=Path)
    ap.add_argument("--methods", nargs="+", default=["colorbalance", "lite", "jointid"])
    ap.add_argument("--max-side", type=int, default=640)
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    files = [f for p in args.inputs for f in (list_images(p) if p.is_dir() else [p])]
    restorers = {m: create(m) for m in args.methods}
    rows: dict[str, list[tuple[float, float, float]]] = {m: [] for m in ("raw", *args.methods)}
    for path in files:
        img = downscale_to(read_rgb(path), args.max_side)
        n_in = particle_count(img).bright_per_mp
        for m in rows:
            out = img if m == "raw" else np.clip(restorers[m].restore(img[None]).images[0], 0.0, 1.0)
            t = particle_tint(img, out)
            rows[m].append((particle_count(out).bright_per_mp / max(n_in, 1e-9), t.tint_out, t.rise))
        print(f"{path.name}: {particle_tint(img, img).sites} bright particles", flush=True)
    print(f"\n{len(files)} images")
    print("| method | particles out/in | tint (a* sites - ring) | rise over the input | rise per image |")
    print("|---|---|---|---|---|")
    for m, r in rows.items():
        a = np.array(r, np.float64)
        per = " ".join(f"{v:+.1f}" for v in a[:, 2])
        print(f"| {m} | {np.nanmean(a[:, 0]):.3f} | {np.nanmean(a[:, 1]):+.2f} | {np.nanmean(a[:, 2]):+.2f} | {per} |")


if __name__ == "__main__":
    main()
