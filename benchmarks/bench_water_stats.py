"""Does murk's synthetic water look like real water? The same statistics of real unpaired underwater images and of
synthetic training water, side by side (issue 46, item 2: "show that synthetic and real statistics overlap").

Run: PYTHONPATH=src python benchmarks/bench_water_stats.py --real DIR_OR_FILE [...] [--configs CFG.yaml ...]
     [--scenes 64] [--max-side 640] [--csv OUT.csv]

Per image, real or synthetic (each real image area-resampled to a long side of ``--max-side``; the synthetic ones are
what the config trains on: its procedural scenes with its scene options (``data.scene_water_background``,
``scene_saturation``, ``scene_contrast``, ``scene_balance_pct``, ``scene_scale``) in 240x320 windows, degraded online
with its ``data.synthesis`` as training does, seed 20261201):
- the veil colour the water estimator gives (``murk.models.water``, with Joint-ID's distance), as its red, green and
  blue, and its CIELAB hue angle and chroma;
- the attenuation of the clearest channel (1/m, Joint-ID's metres);
- the image's colour cast (CIELAB chroma of its mean colour), mean luma and luma contrast (std), as
  ``murk.metrics.colour_exposure``;
- how the haze grows with distance: the mean luma contrast of the far half of the image (beyond the median of
  Joint-ID's distance) over that of the near half.

For each quantity it prints the 10th, 50th and 90th percentile per source, and the share of the real images whose
value lies inside the synthetic source's 5-95 % range (1.0: the synthetic water covers every real image).

Never point ``--real`` at paired benchmark sets (UIEB, LSUI, EUVP, UFO-120, ...): murk does not tune its synthesis on
them.
"""

from __future__ import annotations

import argparse
import csv
import math
from pathlib import Path

import cv2
import numpy as np
import torch

from murk._config import load_yaml
from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.io.images import list_images
from murk.metrics import colour_exposure
from murk.models.water import load_water_estimator
from murk.report.compare import downscale_to
from murk.train.config import TrainConfig

HELDOUT_SEED = 20261201
QUANTITIES = (
    "veil_r", "veil_g", "veil_b", "veil_hue_deg", "veil_chroma", "attenuation_min_per_m",
    "cast", "luminance", "contrast", "far_near_contrast",
)  # fmt: skip


def _luma(img: np.ndarray) -> np.ndarray:
    return 0.2126 * img[..., 0] + 0.7152 * img[..., 1] + 0.0722 * img[..., 2]


def image_stats(img: np.ndarray, depth_net: object, estimator: object) -> dict[str, float]:
    dist = depth_net.restore(img[None]).depth_m[0]  # type: ignore[attr-defined]
    water = estimator.estimate(img, dist)  # type: ignore[attr-defined]
    veil = np.clip(np.asarray(water.veil, np.float32), 0.0, 1.0).reshape(1, 1, 3)
    lab = cv2.cvtColor(veil, cv2.COLOR_RGB2Lab)[0, 0]
    ce = colour_exposure(img)
    y = _luma(img)
    far = dist > np.median(dist)
    near_c, far_c = float(y[~far].std()), float(y[far].std())
    return {
        "veil_r": float(water.veil[0]),
        "veil_g": float(water.veil[1]),
        "veil_b": float(water.veil[2]),
        "veil_hue_deg": math.degrees(math.atan2(float(lab[2]), float(lab[1]))) % 360.0,
        "veil_chroma": math.hypot(float(lab[1]), float(lab[2])),
        "attenuation_min_per_m": float(min(water.attenuation_per_m)),
        "cast": ce.cast,
        "luminance": ce.luminance,
        "contrast": ce.contrast,
        "far_near_contrast": far_c / max(near_c, 1e-6),
    }


def training_images(cfg: TrainConfig, n: int) -> np.ndarray:
    """``n`` degraded training images of ``cfg``'s scene source (N, 240, 320, 3) in [0, 1]."""
    from murk.scenes import SceneConfig
    from murk.train.data import OnlineDegrader
    from murk.train.scenes_source import SceneDataset

    d = cfg.data
    scene_config = SceneConfig(water_background=d.scene_water_background) if d.scene_water_background else None
    scenes = SceneDataset(
        range(n), (240, 320), seed=HELDOUT_SEED, config=scene_config, scale=d.scene_scale,
        saturation=d.scene_saturation, contrast=d.scene_contrast, balance_pct=d.scene_balance_pct,
    )  # fmt: skip
    items = [scenes[i] for i in range(n)]
    clean = torch.stack([it["clean"] for it in items]).float()
    dist = torch.stack([it["depth_filled"] for it in items]).float()
    degraded = OnlineDegrader(d.synthesis, seed=HELDOUT_SEED)(clean, dist, 0, list(range(n)))
    return degraded.clamp(0.0, 1.0).permute(0, 2, 3, 1).numpy().astype(np.float32)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--real", nargs="+", type=Path, required=True)
    ap.add_argument("--configs", nargs="*", type=Path, default=[Path("configs/train-small-cpu.yaml")])
    ap.add_argument("--scenes", type=int, default=64)
    ap.add_argument("--max-side", type=int, default=640)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--csv", type=Path, default=None)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    depth_net, estimator = create("jointid_net"), load_water_estimator()
    rows: list[dict[str, float | str]] = []
    files = [f for p in args.real for f in (list_images(p, recursive=True) if p.is_dir() else [p])]
    for f in files:
        rows.append({"source": "real", "image": str(f), **image_stats(downscale_to(read_rgb(f), args.max_side),
                                                                      depth_net, estimator)})  # fmt: skip
    for cfg_path in args.configs:
        cfg = load_yaml(TrainConfig, cfg_path)
        for i, img in enumerate(training_images(cfg, args.scenes)):
            rows.append({"source": cfg_path.stem, "image": f"scene {i}", **image_stats(img, depth_net, estimator)})
    if args.csv:
        with args.csv.open("w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    sources = list(dict.fromkeys(str(r["source"]) for r in rows))
    print(f"{len(files)} real images; synthetic: " + ", ".join(f"{s} ({args.scenes})" for s in sources[1:]))
    print("| quantity | " + " | ".join(f"{s} p10 / p50 / p90" for s in sources)
          + " | " + " | ".join(f"real inside {s}'s 5-95 %" for s in sources[1:]) + " |")  # fmt: skip
    print("|---|" + "---|" * (2 * len(sources) - 1))
    for q in QUANTITIES:
        vals = {s: np.array([float(r[q]) for r in rows if r["source"] == s]) for s in sources}
        cells = [" / ".join(f"{v:.3g}" for v in np.percentile(vals[s], [10, 50, 90])) for s in sources]
        inside = []
        for s in sources[1:]:
            lo, hi = np.percentile(vals[s], [5, 95])
            inside.append(f"{np.mean((vals['real'] >= lo) & (vals['real'] <= hi)):.2f}")
        print(f"| {q} | " + " | ".join(cells) + " | " + " | ".join(inside) + " |")


if __name__ == "__main__":
    main()
