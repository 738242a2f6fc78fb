"""Particle statistics of snow banks beside the particles measured on real snowy images.

Run: PYTHONPATH=src python benchmarks/bench_snow_stats.py --banks BANK [BANK ...] [--pairs SNOWY_DIR CLEAN_DIR]

For each bank: particle count, area (px), largest bounding-box side (px), elongation (box long / short side)
and luma (Rec. 709, 0-255, mean over the particle's pixels), as median and 10th-90th percentiles. With
``--pairs`` (snowy and snow-free images of the same scenes, matched by file stem; murk ships none), the same
for the particle sites of :func:`murk.metrics.snow_pairs.snow_sites`, plus their brightness above the
snow-free background (``excess``, 0-255), so a bank can be compared with the snow it should look like.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from murk.io import read_rgb
from murk.io.images import list_images
from murk.metrics.snow_pairs import snow_sites
from murk.snow.bank import load_bank
from murk.snow.composite import particle_lumas

LUMA = np.array([0.2126, 0.7152, 0.0722])


def _row(name: str, values: dict[str, np.ndarray], n: int) -> str:
    cells = []
    for key, v in values.items():
        if v.size:
            lo, med, hi = np.percentile(v, [10, 50, 90])
            cells.append(f"{key} {med:.1f} ({lo:.1f}-{hi:.1f})")
        else:
            cells.append(f"{key} -")
    return f"| {name} | {n} | " + " | ".join(cells) + " |"


def bank_stats(path: Path) -> tuple[dict[str, np.ndarray], int]:
    bank = load_bank(path)
    per = particle_lumas(bank)
    hw = bank.bbox_hw.astype(np.float64)
    return {
        "area px": bank.areas_px.astype(np.float64),
        "size px": hw.max(1),
        "elongation": hw.max(1) / np.maximum(hw.min(1), 1),
        "luma": per,
        "excess": np.array([]),
    }, len(bank)


def site_stats(snowy_dir: Path, clean_dir: Path) -> tuple[dict[str, np.ndarray], int]:
    clean = {p.stem: p for p in list_images(clean_dir)}
    out: dict[str, list[float]] = {k: [] for k in ("area px", "size px", "elongation", "luma", "excess")}
    for p in list_images(snowy_dir):
        if p.stem not in clean:
            continue
        s, c = read_rgb(p), read_rgb(clean[p.stem])
        sites = snow_sites(s, c)
        y = (s.astype(np.float64) @ LUMA) * 255
        for k in range(1, sites.count + 1):
            m = sites.labels == k
            hh, ww = np.ptp(np.nonzero(m)[0]) + 1, np.ptp(np.nonzero(m)[1]) + 1
            out["area px"].append(float(m.sum()))
            out["size px"].append(float(max(hh, ww)))
            out["elongation"].append(max(hh, ww) / max(min(hh, ww), 1))
            out["luma"].append(float(y[m].mean()))
            out["excess"].append(float(sites.excess[m].max() * 255))
    return {k: np.asarray(v) for k, v in out.items()}, len(out["area px"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--banks", nargs="+", type=Path, required=True)
    ap.add_argument("--pairs", nargs=2, type=Path, metavar=("SNOWY_DIR", "CLEAN_DIR"))
    args = ap.parse_args()
    print("| source | particles | area px | size px | elongation | luma 0-255 | excess over background |")
    print("|---|---|---|---|---|---|---|")
    for b in args.banks:
        values, n = bank_stats(b)
        print(_row(f"bank {b.name}", values, n))
    if args.pairs:
        values, n = site_stats(*args.pairs)
        print(_row(f"sites of {args.pairs[0]}", values, n))


if __name__ == "__main__":
    main()
