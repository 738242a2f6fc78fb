"""Particle statistics of snow banks beside the particles measured on real snowy images.

Run: PYTHONPATH=src python benchmarks/bench_snow_stats.py --banks BANK [BANK ...] [--pairs SNOWY_DIR CLEAN_DIR]
     [--synth CONFIG.yaml [CONFIG.yaml ...]] [--variants 4]

For each bank: particle count, area (px), largest bounding-box side (px), elongation (box long / short side)
and luma (Rec. 709, 0-255, mean over the particle's pixels), as median and 10th-90th percentiles. With
``--pairs`` (snowy and snow-free images of the same scenes, matched by file stem; murk ships none), the same
for the particle sites of :func:`murk.metrics.snow_pairs.snow_sites`, plus their brightness above the
snow-free background (``excess``, 0-255), so a bank can be compared with the snow it should look like.

``--synth``: the same site statistics for murk's own synthetic snow, measured exactly as on the real pairs:
each synthesis config (its ``stages`` must include ``marine_snow``) renders ``--variants`` variants of each
shipped RGB-D pair twice, with and without the marine-snow stage (the same draws otherwise), and the sites of
each pair are found by :func:`murk.metrics.snow_pairs.snow_sites`. ``sites/Mpx`` is the number of sites per
megapixel of image.
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


KEYS = ("area px", "size px", "elongation", "luma", "excess")


def _add_sites(s: np.ndarray, c: np.ndarray, out: dict[str, list[float]]) -> None:
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


def site_stats(snowy_dir: Path, clean_dir: Path) -> tuple[dict[str, np.ndarray], int, float]:
    """Site statistics of real pairs, their count and the megapixels they were found in."""
    clean = {p.stem: p for p in list_images(clean_dir)}
    out: dict[str, list[float]] = {k: [] for k in KEYS}
    mpx = 0.0
    for p in list_images(snowy_dir):
        if p.stem not in clean:
            continue
        s, c = read_rgb(p), read_rgb(clean[p.stem])
        _add_sites(s, c, out)
        mpx += s.shape[0] * s.shape[1] / 1e6
    return {k: np.asarray(v) for k, v in out.items()}, len(out["area px"]), mpx


def synth_site_stats(config_path: Path, variants: int) -> tuple[dict[str, np.ndarray], int, float]:
    """Site statistics of murk's synthetic snow (module docstring)."""
    import dataclasses

    from murk._config import load_yaml
    from murk.data import sample_rgbd_dir
    from murk.io.depth import read_depth, resolve_invalid
    from murk.rng import derive_seed
    from murk.snow.bank import load_bank
    from murk.synth.config import SynthConfig
    from murk.synth.params import sample_variant, snow_sampler_for
    from murk.synth.render import render

    cfg = load_yaml(SynthConfig, config_path)
    if "marine_snow" not in cfg.stages:
        raise SystemExit(f"{config_path}: stages must include marine_snow")
    bank = load_bank(cfg.marine_snow.bank or "builtin:snow")
    sampler = snow_sampler_for(cfg, bank)
    root = sample_rgbd_dir()
    out: dict[str, list[float]] = {k: [] for k in KEYS}
    mpx = 0.0
    for i, rgb_path in enumerate(list_images(root / "rgb")):
        clean = read_rgb(rgb_path)
        depth = read_depth(root / "depth" / f"{rgb_path.stem}.png")
        depth, _ = resolve_invalid(depth, "fill")
        for v in range(variants):
            params = sample_variant(np.random.default_rng(derive_seed(0, "snow-look", i, v)), cfg, snow_sampler=sampler)
            snowy = render(clean, depth, params, bank=bank).degraded
            plain = render(clean, depth, dataclasses.replace(params, snow=None, camera=None), bank=bank).degraded
            if params.camera is not None:
                raise SystemExit(f"{config_path}: leave the camera stage out (it adds noise to both images)")
            _add_sites(snowy, plain, out)
            mpx += snowy.shape[0] * snowy.shape[1] / 1e6
    return {k: np.asarray(v) for k, v in out.items()}, len(out["area px"]), mpx


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--banks", nargs="+", type=Path, required=True)
    ap.add_argument("--pairs", nargs=2, type=Path, metavar=("SNOWY_DIR", "CLEAN_DIR"))
    ap.add_argument("--synth", nargs="+", type=Path, default=[], metavar="CONFIG")
    ap.add_argument("--variants", type=int, default=4)
    args = ap.parse_args()
    print("| source | particles | area px | size px | elongation | luma 0-255 | excess over background |")
    print("|---|---|---|---|---|---|---|")
    for b in args.banks:
        values, n = bank_stats(b)
        print(_row(f"bank {b.name}", values, n))
    if args.pairs:
        values, n, mpx = site_stats(*args.pairs)
        print(_row(f"sites of {args.pairs[0]} ({n / mpx:.0f} sites/Mpx)", values, n))
    for c in args.synth:
        values, n, mpx = synth_site_stats(c, args.variants)
        print(_row(f"sites of murk's snow, {c.name} ({n / mpx:.0f} sites/Mpx)", values, n))


if __name__ == "__main__":
    main()
