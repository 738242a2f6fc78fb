"""What limits the ``water`` method after the affine fit: Joint-ID's distance map, or the water it estimates?

Run: PYTHONPATH=src python benchmarks/bench_water_distance.py [--config configs/train-lite-mild-scratch-cpu.yaml]
     [--heldout-scenes 64] [--strengths 0.25,0.5,1] [--no-oracle-water] [--threads 2]

The held-out scenes of ``bench_arms.py`` (seed 20261201, 320x240, photographic targets, ``--config``'s synthesis with
its three stages) are restored by ``water`` as it runs (``murk.enhance.water_restorer``: the base ``jointid`` gives
the colour and the distance, the shipped estimator the water, Eq. (1) is inverted and ``strength`` of the change is
taken; the row ``jointid distance, estimated water`` is that method, a test checks it) with one part swapped at a
time:

- the distance: Joint-ID's own (``jointid``), the same map scaled per scene by the median ratio of the true distance to
  it (``median-scaled``: Joint-ID's shape at the true scale), or the TRUE distance of the scene in its own metres
  (``true``: what Joint-ID learns to predict; open water at the scene's far plane). The paper's synthesis
  (``normalized`` mode) degrades the scene with that distance rescaled to a range drawn per variant
  (``murk.physics.medium.distance_map``; in these scenes it is shorter than the scene's); that map, ``Eq. (1)'s``,
  is used with the synthesis's own water;
- the water: the shipped estimator's, reading the image and that distance (``estimated``); the synthesis's own
  attenuation and veil ``B_inf`` with Eq. (1)'s distance (``synthesis``; not an exact inverse: forward scatter and snow
  come after Eq. (1)); or an oracle (``oracle``) chosen per scene and channel on a grid (attenuation 0.01-10 /m in 41
  log steps, veil 0-1.2 in 25 steps) for the least error against the TRUE clean scene after the affine fit at full
  strength (the fit made at half resolution, scored at full). With Joint-ID's distance two more rows hold one part of
  the estimate and search the other (``estimated veil and oracle attenuation``, ``oracle veil and estimated
  attenuation``): which part the estimator misses. Every water is taken at each of ``--strengths``.

Every row is scored as the issue-46 instruments score: the affine-fit PSNR against the true clean scene, gain over the
degraded input's own, and the paired difference to ``water`` as shipped at the same strength, each with its 95 %
interval over the scenes; the base ``jointid`` is printed first. The oracle rows read the truth: a grid-search estimate
of what an exact water allows, not a method. A second table sets the shipped estimator's water beside the synthesis's
(what ``murk water estimate`` reports): the veil's error over RGB and its CIEDE2000, and the visibility's ratio to the
true one in the scene's metres (and, with Eq. (1)'s distance, in that map's metres), median and quartiles over the
scenes, and the share of scenes within a factor of two.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from murk._config import load_yaml, merge
from murk.enhance.restorer import create
from murk.enhance.water_restorer import restore_with_water
from murk.metrics import affine_fit_psnr
from murk.metrics.reference import ciede2000
from murk.models.water import Water
from murk.physics.medium import distance_map
from murk.report.heldout import HeldoutSet, make_heldout
from murk.report.study import ci95_half_width
from murk.restore_ops.water import visibility_m
from murk.rng import derive_seed
from murk.synth.params import MediumParams
from murk.train.config import TrainConfig
from murk.train.data import OnlineDegrader

HELDOUT_SEED = 20261201
ATTENUATION_GRID_PER_M = np.geomspace(0.01, 10.0, 41)
VEIL_GRID = np.linspace(0.0, 1.2, 25)
T_MIN = 0.1
SHIPPED = "jointid distance, estimated water"
"""The row that is ``water`` as shipped (its label before the strength)."""


@dataclass(frozen=True)
class TrueWater:
    """What degraded one held-out scene: its distance in its own metres (open water at the far plane), the map Eq. (1)
    used (that distance rescaled by the variant), and the variant's water."""

    scene_dist_m: np.ndarray
    eq1_dist_m: np.ndarray
    medium: MediumParams

    @property
    def scene_peak_m(self) -> float:
        return float(self.scene_dist_m.max())


def true_waters(data: HeldoutSet, synthesis: Any) -> list[TrueWater]:
    """Per held-out scene, as :func:`make_heldout` rendered and degraded it (scene ``i`` of seed ``data.seed``, epoch
    0 of its :class:`OnlineDegrader`): the distance (NaN in ``data.dist_m`` where a ray hit nothing, there the scene's
    far plane), its map through :func:`distance_map` with the variant's mode, near and far distance, and the water."""
    from murk.scenes import sample_scene

    variants = OnlineDegrader(synthesis, seed=data.seed).params(0, range(len(data.dist_m)))
    out = []
    for i, (dist_m, variant) in enumerate(zip(data.dist_m, variants, strict=True)):
        far_plane_m = sample_scene(derive_seed(data.seed, "heldout", i)).far_m
        scene_m = np.where(np.isfinite(dist_m), dist_m, far_plane_m).astype(np.float32)
        m = variant.medium
        eq1_m = distance_map(scene_m, mode=m.distance_mode, near_m=m.near_m, far_m=m.far_m).astype(np.float32)
        out.append(TrueWater(scene_m, eq1_m, m))
    return out


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


def restorations(
    image: np.ndarray,
    restored: np.ndarray,
    dist_m: np.ndarray,
    veil: np.ndarray,
    attenuation_per_m: np.ndarray,
    strengths: list[float],
) -> list[tuple[float, np.ndarray]]:
    """``water``'s last steps (:func:`murk.enhance.water_restorer.restore_with_water`) with this distance and water,
    one output per strength."""
    return [(s, restore_with_water(image, restored, dist_m, veil, attenuation_per_m, s, T_MIN)) for s in strengths]


def _waters(
    image: np.ndarray, clean: np.ndarray, dname: str, dist_m: np.ndarray, estimate: Water, oracle: bool
) -> list[tuple[str, np.ndarray, np.ndarray]]:
    """The waters tried with one distance: (name, veil, attenuation per metre)."""
    est_veil, est_att = np.asarray(estimate.veil), np.asarray(estimate.attenuation_per_m)
    waters = [("estimated", est_veil, est_att)]
    if oracle:
        small = (_half(image), _half(dist_m), _half(clean))
        waters.append(("oracle", *oracle_water(*small)))
        if dname == "jointid":  # which part of the water the estimator misses
            waters.append(("estimated veil and oracle attenuation", est_veil, oracle_water(*small, veil=est_veil)[1]))
            waters.append(
                ("oracle veil and estimated attenuation", oracle_water(*small, attenuation_per_m=est_att)[0], est_att)
            )
    return waters


def score(
    data: HeldoutSet,
    synthesis: Any,
    strengths: list[float],
    oracle: bool,
    estimates: dict[str, list[float]] | None = None,
) -> dict[str, list[float]]:
    """Per row label, each scene's affine-fit PSNR gain over the input (dB). ``estimates``: a dict that receives, per
    distance given to the estimator (``jointid``, ``true``: in the scene's metres; ``Eq. (1)'s``: in that map's), each
    scene's :func:`estimate_error` as ``"<distance> <measure>"`` lists (one pass of the base serves both tables)."""
    truths = true_waters(data, synthesis)
    water = create("water")
    base, estimator = water.base, water.estimator  # type: ignore[attr-defined]
    gains: dict[str, list[float]] = {}
    for i in range(0, len(data.degraded), 8):
        r = base.restore(data.degraded[i : i + 8])
        for k in range(len(r.images)):
            image, clean, truth = data.degraded[i + k], data.clean[i + k], truths[i + k]
            restored = np.clip(r.images[k], 0.0, 1.0)
            input_fit_db = affine_fit_psnr(image, clean, data_range=1.0)

            def add(label: str, out: np.ndarray, fit_db: float = input_fit_db, ref: np.ndarray = clean) -> None:
                gains.setdefault(label, []).append(affine_fit_psnr(out, ref, data_range=1.0) - fit_db)

            add("jointid (the base)", restored)
            dists = {
                "jointid": r.depth_m[k],
                "median-scaled": median_scaled(r.depth_m[k], truth.scene_dist_m),
                "true": truth.scene_dist_m,
            }
            for dname, dist_m in dists.items():
                estimate = estimator.estimate(image, dist_m)
                if estimates is not None and dname != "median-scaled":
                    for key, value in estimate_error(estimate, truth, eq1_metres=False).items():
                        estimates.setdefault(f"{dname} {key}", []).append(value)
                for wname, veil, att in _waters(image, clean, dname, dist_m, estimate, oracle):
                    for s, out in restorations(image, restored, dist_m, veil, att, strengths):
                        add(f"{dname} distance, {wname} water, strength {s:g}", out)
            m = truth.medium
            synthesis_water = (np.asarray(m.b_inf), np.asarray(m.beta_per_m))
            for s, out in restorations(image, restored, truth.eq1_dist_m, *synthesis_water, strengths):
                add(f"Eq. (1)'s distance, synthesis water, strength {s:g}", out)
            if estimates is not None:
                estimate = estimator.estimate(image, truth.eq1_dist_m)
                for key, value in estimate_error(estimate, truth, eq1_metres=True).items():
                    estimates.setdefault(f"Eq. (1)'s {key}", []).append(value)
    return gains


def estimate_error(estimate: Water, truth: TrueWater, *, eq1_metres: bool) -> dict[str, float]:
    """The estimate against the water that degraded the scene: the veil's mean absolute error over RGB and its
    CIEDE2000 (both colours clipped to [0, 1]), and the visibility's ratio to the true one (``ln 20 / min beta`` in
    Eq. (1)'s metres), in the metres of the distance the estimator was given: Eq. (1)'s (``eq1_metres``) or the
    scene's own, which Joint-ID learns. In the paper's ``normalized`` mode Eq. (1) sees the scene's distance ``z``
    as ``near + z / peak * (far - near)``, so a visibility ``V`` there is ``(V - near) * peak / (far - near)`` of the
    scene's metres."""
    m = truth.medium
    est = np.asarray(estimate.veil, np.float64)
    true = np.asarray(m.b_inf, np.float64)
    a, b = (np.clip(v, 0.0, 1.0).reshape(1, 1, 3) for v in (est, true))
    visibility_true_m = visibility_m(np.asarray(m.beta_per_m))
    if not eq1_metres and m.distance_mode == "normalized":
        visibility_true_m = max(visibility_true_m - m.near_m, 1e-6) * truth.scene_peak_m / (m.far_m - m.near_m)
    return {
        "veil_abs_error": float(np.mean(np.abs(est - true))),
        "veil_ciede2000": ciede2000(a, b, data_range=1.0),
        "visibility_ratio": float(estimate.visibility_m / visibility_true_m),
    }


def estimates_table(estimates: dict[str, list[float]]) -> str:
    lines = [
        "| distance given to the estimator | veil, mean abs error (RGB) | veil, CIEDE2000 | visibility / true, in "
        "that distance's metres | visibility within 2x |",
        "|---|---|---|---|---|",
    ]
    for dname in ("jointid", "true", "Eq. (1)'s"):
        cells = []
        for key in ("veil_abs_error", "veil_ciede2000", "visibility_ratio"):
            q = np.percentile(estimates[f"{dname} {key}"], [25, 50, 75])
            cells.append(f"{q[1]:.3g} ({q[0]:.3g} to {q[2]:.3g})")
        ratio = np.asarray(estimates[f"{dname} visibility_ratio"])
        cells.append(f"{np.mean((ratio >= 0.5) & (ratio <= 2.0)):.0%}")
        lines.append(f"| {dname} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def table(gains: dict[str, list[float]]) -> str:
    def interval(d: np.ndarray) -> str:
        h = ci95_half_width(float(d.std(ddof=1)), len(d))
        return f"{d.mean():+.2f} ({d.mean() - h:+.2f} to {d.mean() + h:+.2f})"

    lines = [
        "| arm | gain over the input after the fit, dB (95 %) | against `water` as shipped, same strength |",
        "|---|---|---|",
    ]
    for label, g in gains.items():
        a = np.asarray(g)
        strength = label.rpartition(", strength ")[2]
        shipped = gains.get(f"{SHIPPED}, strength {strength}")
        against = "" if shipped is None or label.startswith(SHIPPED) else interval(a - np.asarray(shipped))
        lines.append(f"| {label} | {interval(a)} | {against} |")
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
    fits = [affine_fit_psnr(a, b, data_range=1.0) for a, b in zip(data.degraded, data.clean, strict=True)]
    print(f"{args.config}: {args.heldout_scenes} held-out scenes, the input after the fit {np.mean(fits):.2f} dB")
    estimates: dict[str, list[float]] = {}
    print(table(score(data, synthesis, strengths, not args.no_oracle_water, estimates)))
    print("\nThe estimate against the synthesis's water, median (quartiles) over the scenes:")
    print(estimates_table(estimates))


if __name__ == "__main__":
    main()
