"""What limits the ``water`` method after the affine fit: Joint-ID's distance map, or the water it estimates?

Run: PYTHONPATH=src python benchmarks/bench_water_distance.py [--config configs/train-lite-mild-scratch-cpu.yaml]
     [--heldout-scenes 64] [--strengths 0.25,0.5,1] [--no-oracle-water] [--threads 2]

The held-out scenes of ``bench_arms.py`` (seed 20261201, 320x240, photographic targets, ``--config``'s synthesis with
its three stages) are restored by ``water`` as it runs (``murk.enhance.water_restorer``: the base ``jointid`` gives
the colour and the distance, the shipped estimator the water, Eq. (1) is inverted and ``strength`` of the change is
taken) with one part swapped at a time:

- the distance: Joint-ID's own (``jointid``), the same map scaled per scene by the median ratio of the true distance to
  it (``median-scaled``: Joint-ID's shape at the true scale), or the TRUE distance (``true``: the very map Eq. (1)
  degraded the scene with, ``murk.physics.medium.distance_map`` of the scene's depth with the variant's near and far
  distance, open water at the scene's far plane; in the paper's ``normalized`` mode that is the scene's depth
  stretched to a far distance drawn per variant);
- the water: the shipped estimator's, reading the image and that distance (``estimated``); the synthesis's own
  attenuation and veil ``B_inf`` (``synthesis``; not an exact inverse: the light on the scene, forward scatter, snow
  and the camera stage come after or beside Eq. (1)); or an oracle (``oracle``) chosen per scene and channel on a grid
  (attenuation 0.01-10 /m in 41 log steps, veil 0-1.2 in 25 steps) for the least error against the TRUE clean scene
  after the affine fit at full strength (the fit made at half resolution, scored at full). With Joint-ID's distance
  two more rows hold one part of the estimate and search the other (``estimated veil and oracle attenuation``,
  ``oracle veil and estimated attenuation``): which part the estimator misses. Every water is taken at each of
  ``--strengths``.

Every row is scored as the issue-46 instruments score (the affine-fit PSNR against the true clean scene, gain over the
degraded input's own, paired over the scenes with the 95 % interval); the base ``jointid`` is printed first. The
oracle rows are bounds, not methods: they read the truth. A second table sets the shipped estimator's water beside the
synthesis's (what ``murk water estimate`` reports): the veil's error over RGB and its CIEDE2000, and the visibility's
ratio to the true one (in Eq. (1)'s metres and in the scene's), median and quartiles over the scenes.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np
import torch

from murk._config import load_yaml, merge
from murk.enhance.restorer import create
from murk.metrics import affine_fit_psnr
from murk.metrics.affine_psnr import affine_fit
from murk.metrics.reference import ciede2000
from murk.physics.medium import distance_map
from murk.report.heldout import HeldoutSet, make_heldout
from murk.report.study import ci95_half_width
from murk.restore_ops.water import invert_eq1, visibility_m
from murk.rng import derive_seed
from murk.train.config import TrainConfig
from murk.train.data import OnlineDegrader

HELDOUT_SEED = 20261201
ATTENUATION_GRID_PER_M = np.geomspace(0.01, 10.0, 41)
VEIL_GRID = np.linspace(0.0, 1.2, 25)
T_MIN = 0.1


def true_distances(data: HeldoutSet, synthesis: Any) -> tuple[list[np.ndarray], list[Any], list[float]]:
    """The distance map Eq. (1) degraded each held-out scene with, the variant's water (``MediumParams``) and the
    scene's farthest depth in metres: the scene's depth (open water, NaN in ``data.dist_m``, at the scene's far plane,
    as :func:`make_heldout` rendered it) through :func:`distance_map` with the variant's mode, near and far distance
    (epoch 0, scene ``i``, as :func:`make_heldout` degraded it)."""
    from murk.scenes import sample_scene

    variants = OnlineDegrader(synthesis, seed=data.seed).params(0, range(len(data.dist_m)))
    out, peaks = [], []
    for i, (d, v) in enumerate(zip(data.dist_m, variants, strict=True)):
        far_plane = sample_scene(derive_seed(data.seed, "heldout", i)).far_m
        depth = np.where(np.isfinite(d), d, far_plane).astype(np.float32)
        m = v.medium
        out.append(distance_map(depth, mode=m.distance_mode, near_m=m.near_m, far_m=m.far_m).astype(np.float32))
        peaks.append(float(depth.max()))
    return out, [v.medium for v in variants], peaks


def median_scaled(pred_m: np.ndarray, true_m: np.ndarray) -> np.ndarray:
    """``pred_m`` scaled by median(true) / median(pred) over the pixels both give."""
    ok = np.isfinite(true_m) & (true_m > 0) & np.isfinite(pred_m) & (pred_m > 0)
    if not ok.any():
        raise ValueError("median_scaled: no pixel where both distances are given")
    return (pred_m * (np.median(true_m[ok]) / np.median(pred_m[ok]))).astype(np.float32)


def oracle_water(
    image: np.ndarray,
    dist_m: np.ndarray,
    clean: np.ndarray,
    *,
    veil: np.ndarray | None = None,
    attenuation_per_m: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Per channel, the veil and attenuation of the grids whose inversion of Eq. (1) (transmission floored at
    :data:`T_MIN`, clipped to [0, 1]) leaves the least squared error against ``clean`` after the best gain and offset.
    ``veil`` or ``attenuation_per_m`` given: that part is held (three numbers) and only the other is searched.
    Returns (veil, attenuation_per_m), three numbers each."""
    found_veil, found_att = np.zeros(3), np.zeros(3)
    for c in range(3):
        x = image[..., c].astype(np.float64).ravel()
        y = clean[..., c].astype(np.float64).ravel()
        yc = y - y.mean()
        atts = ATTENUATION_GRID_PER_M if attenuation_per_m is None else [float(attenuation_per_m[c])]
        veils = VEIL_GRID if veil is None else [float(veil[c])]
        best = (math.inf, 0.0, 0.0)
        for a in atts:
            t = np.maximum(np.exp(-a * dist_m.astype(np.float64).ravel()), T_MIN)
            for b in veils:
                j = np.clip((x - b * (1.0 - t)) / t, 0.0, 1.0)
                jc = j - j.mean()
                var = float(jc @ jc)
                # the least-squares residual of y on (j, 1): sum(yc^2) - cov^2 / var
                err = float(yc @ yc) - (float(jc @ yc) ** 2 / var if var > 0 else 0.0)
                if err < best[0]:
                    best = (err, b, a)
        found_veil[c], found_att[c] = best[1], best[2]
    return found_veil, found_att


def _half(a: np.ndarray) -> np.ndarray:
    h, w = a.shape[0] // 2 * 2, a.shape[1] // 2 * 2
    a = a[:h, :w]
    return a.reshape(h // 2, 2, w // 2, 2, *a.shape[2:]).mean(axis=(1, 3))


def score(
    data: HeldoutSet,
    synthesis: Any,
    strengths: list[float],
    oracle: bool,
    estimates: dict[str, list[float]] | None = None,
) -> dict[str, list[float]]:
    """Per row label, each scene's affine-fit PSNR gain over the input (dB). ``estimates``: a dict that receives, per
    distance (``jointid``, ``true``), each scene's :func:`estimate_error` as ``"<distance> <measure>"`` lists."""
    truths, media, peaks = true_distances(data, synthesis)
    water = create("water")
    base, estimator = water.base, water.estimator  # type: ignore[attr-defined]
    gains: dict[str, list[float]] = {}
    n = len(data.degraded)
    for i in range(0, n, 8):
        r = base.restore(data.degraded[i : i + 8])
        for k in range(len(r.images)):
            image, clean = data.degraded[i + k], data.clean[i + k]
            restored = np.clip(r.images[k], 0.0, 1.0)
            floor = affine_fit_psnr(image, clean, data_range=1.0)
            gains.setdefault("jointid (the base)", []).append(affine_fit_psnr(restored, clean, data_range=1.0) - floor)
            truth, medium = truths[i + k], media[i + k]
            dists = {"jointid": r.depth_m[k], "median-scaled": median_scaled(r.depth_m[k], truth), "true": truth}
            for dname, d in dists.items():
                w = estimator.estimate(image, d)
                if estimates is not None and dname != "median-scaled":
                    for key, value in estimate_error(w, medium, peaks[i + k]).items():
                        estimates.setdefault(f"{dname} {key}", []).append(value)
                waters = [("estimated", np.asarray(w.veil), np.asarray(w.attenuation_per_m), strengths)]
                if dname == "true":
                    waters.append(("synthesis", np.asarray(medium.b_inf), np.asarray(medium.beta_per_m), strengths))
                if oracle:
                    small = (_half(image), _half(d), _half(clean))
                    veil, att = oracle_water(*small)
                    waters.append(("oracle", veil, att, strengths))
                    if dname == "jointid":  # which part of the water the estimator misses
                        est_veil, est_att = np.asarray(w.veil), np.asarray(w.attenuation_per_m)
                        _, att = oracle_water(*small, veil=est_veil)
                        waters.append(("estimated veil and oracle attenuation", est_veil, att, strengths))
                        veil, _ = oracle_water(*small, attenuation_per_m=est_att)
                        waters.append(("oracle veil and estimated attenuation", veil, est_att, strengths))
                for wname, veil, att, ss in waters:
                    inverted = invert_eq1(image, d, veil, att, T_MIN)
                    for s in ss:
                        out = np.clip(affine_fit(image + np.float32(s) * (inverted - image), restored), 0.0, 1.0)
                        label = f"{dname} distance, {wname} water, strength {s:g}"
                        gains.setdefault(label, []).append(affine_fit_psnr(out, clean, data_range=1.0) - floor)
    return gains


def estimate_error(water: Any, medium: Any, scene_peak_m: float) -> dict[str, float]:
    """The estimate against the water that degraded the scene: the veil's mean absolute error over RGB and its
    CIEDE2000 (both colours clipped to [0, 1]), and the visibility's ratio to the true one (``ln 20 / min beta``) in
    the metres of Eq. (1)'s distance and in the scene's own metres (the two differ in the paper's ``normalized``
    mode, where the scene's depth, farthest ``scene_peak_m``, is stretched from ``near_m`` to ``far_m``; Joint-ID
    learns the scene's)."""
    est = np.asarray(water.veil, np.float64)
    true = np.asarray(medium.b_inf, np.float64)
    a, b = (np.clip(v, 0.0, 1.0).reshape(1, 1, 3) for v in (est, true))
    seen_eq1 = visibility_m(np.asarray(medium.beta_per_m))
    seen_scene = seen_eq1
    if medium.distance_mode == "normalized":
        seen_scene = max(seen_eq1 - medium.near_m, 1e-6) * scene_peak_m / (medium.far_m - medium.near_m)
    return {
        "veil_abs_error": float(np.mean(np.abs(est - true))),
        "veil_ciede2000": ciede2000(a, b, data_range=1.0),
        "visibility_ratio": float(water.visibility_m / seen_eq1),
        "visibility_ratio_scene": float(water.visibility_m / seen_scene),
    }


def estimates_table(estimates: dict[str, list[float]]) -> str:
    lines = [
        "| distance given to the estimator | veil, mean abs error (RGB) | veil, CIEDE2000 | visibility / true, "
        "Eq. (1)'s metres | visibility / true, the scene's metres |",
        "|---|---|---|---|---|",
    ]
    for dname in ("jointid", "true"):
        cells = []
        for key in ("veil_abs_error", "veil_ciede2000", "visibility_ratio", "visibility_ratio_scene"):
            q = np.percentile(estimates[f"{dname} {key}"], [25, 50, 75])
            cells.append(f"{q[1]:.3g} ({q[0]:.3g} to {q[2]:.3g})")
        lines.append(f"| {dname} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def table(gains: dict[str, list[float]]) -> str:
    lines = ["| arm | gain over the input after the fit, dB (95 %) |", "|---|---|"]
    for label, g in gains.items():
        a = np.asarray(g)
        h = ci95_half_width(float(a.std(ddof=1)), len(a))
        lines.append(f"| {label} | {a.mean():+.2f} ({a.mean() - h:+.2f} to {a.mean() + h:+.2f}) |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=Path("configs/train-lite-mild-scratch-cpu.yaml"))
    ap.add_argument("--heldout-scenes", type=int, default=64)
    ap.add_argument("--strengths", default="0.25,0.5,1")
    ap.add_argument("--no-oracle-water", action="store_true", help="leave out the oracle rows (the slow part)")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args()
    if args.heldout_scenes < 2:
        ap.error("--heldout-scenes: at least 2 (the interval needs them)")
    strengths = [float(s) for s in args.strengths.split(",")]
    if not all(0.0 <= s <= 1.0 for s in strengths):
        ap.error(f"--strengths: each in [0, 1], got {args.strengths}")
    torch.set_num_threads(args.threads)
    synthesis = merge(
        load_yaml(TrainConfig, args.config).data.synthesis, {"stages": ["basic", "forward_scatter", "marine_snow"]}
    )
    data = make_heldout(
        args.heldout_scenes, seed=HELDOUT_SEED, size_hw=(240, 320), synthesis=synthesis, balance_pct=0.5
    )
    floor = np.mean([affine_fit_psnr(a, b, data_range=1.0) for a, b in zip(data.degraded, data.clean, strict=True)])
    print(f"{args.config}: {args.heldout_scenes} held-out scenes, the input after the fit {floor:.2f} dB")
    estimates: dict[str, list[float]] = {}
    print(table(score(data, synthesis, strengths, not args.no_oracle_water, estimates)))
    print("\nThe estimate against the synthesis's water, median (quartiles) over the scenes:")
    print(estimates_table(estimates))


if __name__ == "__main__":
    main()
