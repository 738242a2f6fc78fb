"""Where a restorer wins or loses against the classical colour balance on real pairs, and whether it is global.

Run: PYTHONPATH=src python benchmarks/bench_realpairs_breakdown.py --pairs DIR [--max-side 256]
     [--methods jointid lite] [--csv OUT.csv]

DIR holds ``input/`` and ``reference/`` (matched by stem) or subfolders that each do (the development set
``realpairs_dev/{uieb18,uimnet9}``). Each pair is shrunk to a long side of ``--max-side`` (area resampling, as
``murk compare --max-side``). For every method and for ``colorbalance`` (the simplest colour balance, 1 % / 1 %):

- PSNR against the reference, and the paired difference to ``colorbalance`` (dPSNR);
- the affine-fit PSNR (:func:`murk.metrics.affine_fit_psnr`: the output after the best gain and offset per
  channel onto the reference): a method whose dPSNR vanishes after the fit differs from the balance only in global
  colour; one that keeps it differs locally;
- dPSNR on the near half and on the far half of each image (split at the median of ``jointid``'s own distance
  map): haze grows with distance, so a method that removes haze should gain more on the far half.

The images are then grouped by what they look like, each feature split at its median over all pairs: the input's
colour cast (CIELAB chroma of its mean colour), its brightness (mean Rec. 709 luma), its haze (the input's
luma contrast, low = hazy) and its content (the share of flat pixels in the reference, open water and
background, where the local standard deviation of luma over 7x7 is below 0.02). The table prints the mean
dPSNR of each method in each group with the number of images and how many of them the method wins.
"""

from __future__ import annotations

import argparse
import csv
from pathlib import Path

import cv2
import numpy as np
import torch

from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.io.images import list_images
from murk.metrics import affine_fit_psnr, colour_exposure, psnr
from murk.report.compare import downscale_to
from murk.report.study import pair_sets


def _region_psnr(out: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> float:
    mse = float(np.mean((out[mask].astype(np.float64) - ref[mask].astype(np.float64)) ** 2))
    return 10.0 * np.log10(1.0 / max(mse, 1e-12))


def _flat_share(ref: np.ndarray) -> float:
    y = (0.2126 * ref[..., 0] + 0.7152 * ref[..., 1] + 0.0722 * ref[..., 2]).astype(np.float32)
    mean = cv2.blur(y, (7, 7))
    sq = cv2.blur(y * y, (7, 7))
    return float(np.mean(np.sqrt(np.maximum(sq - mean * mean, 0.0)) < 0.02))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", required=True, type=Path)
    ap.add_argument("--methods", nargs="+", default=["jointid", "lite"])
    ap.add_argument("--max-side", type=int, default=256)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--csv", type=Path, default=None, help="also write the per-image rows here")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    restorers = {m: create(m) for m in ("colorbalance", *args.methods)}
    depth_net = create("jointid?refine=0,lite_blend=0")
    rows: list[dict[str, float | str]] = []
    for set_name, folder in pair_sets(args.pairs).items():
        refs = {p.stem: p for p in list_images(folder / "reference")}
        for path in list_images(folder / "input"):
            img = downscale_to(read_rgb(path), args.max_side)
            ref = downscale_to(read_rgb(refs[path.stem]), args.max_side)
            depth = depth_net.restore(img[None]).depth_m[0]
            far = depth > np.median(depth)
            ce = colour_exposure(img)
            row: dict[str, float | str] = {
                "set": set_name,
                "image": path.stem,
                "cast": ce.cast,
                "brightness": ce.luminance,
                "contrast": ce.contrast,
                "flat_share": _flat_share(ref),
            }
            for name, rest in restorers.items():
                out = np.clip(rest.restore(img[None]).images[0], 0.0, 1.0)
                row[f"{name}_psnr"] = psnr(out, ref, data_range=1.0)
                row[f"{name}_fit"] = affine_fit_psnr(out, ref, data_range=1.0)
                row[f"{name}_near"] = _region_psnr(out, ref, ~far)
                row[f"{name}_far"] = _region_psnr(out, ref, far)
            rows.append(row)
            print(f"{set_name}/{path.name}", flush=True)
    if args.csv:
        with args.csv.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    _print_tables(rows, args.methods)


def _print_tables(rows: list[dict[str, float | str]], methods: list[str]) -> None:
    def col(key: str) -> np.ndarray:
        return np.array([float(r[key]) for r in rows])

    print(f"\n{len(rows)} pairs. dPSNR = method - colorbalance, dB, mean (wins / images)\n")
    print("| | " + " | ".join(f"{m} dPSNR | after affine fit | near half | far half" for m in methods) + " |")
    print("|---|" + "---|" * (4 * len(methods)))
    groups: list[tuple[str, np.ndarray]] = [("all images", np.ones(len(rows), bool))]
    for key, low, high in (
        ("cast", "weak colour cast", "strong colour cast"),
        ("brightness", "dark", "bright"),
        ("contrast", "hazy (low contrast)", "clear (high contrast)"),
        ("flat_share", "textured content", "open water / flat background"),
    ):
        v = col(key)
        med = float(np.median(v))
        groups += [(f"{low} ({key} <= {med:.3g})", v <= med), (f"{high} ({key} > {med:.3g})", v > med)]
    for label, mask in groups:
        cells = []
        for m in methods:
            for suffix in ("psnr", "fit", "near", "far"):
                d = col(f"{m}_{suffix}")[mask] - col(f"colorbalance_{suffix}")[mask]
                cells.append(f"{d.mean():+.2f} ({int((d > 0).sum())}/{d.size})")
        print(f"| {label} | " + " | ".join(cells) + " |")
    print(
        "\nmean PSNR / after affine fit: "
        + ", ".join(
            f"{m} {col(f'{m}_psnr').mean():.2f} / {col(f'{m}_fit').mean():.2f}" for m in ["colorbalance", *methods]
        )
    )


if __name__ == "__main__":
    main()
