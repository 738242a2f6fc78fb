"""Probe (issue 46, 2026-12-08; measured, not kept): ``water`` with Joint-ID's distance map refined by a guided
filter before the inversion.

bench_water_distance.py found that once the water is fitted only the distance's shape counts, and that the shape of
Joint-ID's distance costs 1.1-2.7 dB after the fit. The hypothesis: the map is smooth across object edges, so the
inversion leaves a halo of haze along near edges. A guided filter (He et al. 2013, the refinement that dark-channel
dehazing uses for its transmission) with the frame as the guide pulls a map towards the frame's edges and needs no
training. Measured: no change (docs/train.md, "Distance or water: what limits the inversion"); the map's error is
spread over the frame, not at the edges (``distance_error_where.py``).

``water_guided?radius=R,eps=E,guide=G,strength=S``: as ``water?strength=S``, with the distance map replaced by
``guided_filter(g, d, r, eps)`` before the estimator and the inversion; ``g`` is the luma (BT.601) of the input
(``guide=input``) or of the base's restoration (``guide=restored``); ``r`` is ``radius`` times the long side in
pixels; ``d`` is filtered as ``d / max(d)`` and scaled back, clipped to be positive. The depth map returned is the
refined one. ``radius=0`` is ``water`` itself.

Run:
     PYTHONPATH=src python benchmarks/bench_arms.py --probe benchmarks/probes/water_guided.py water=water
     "g=water_guided?radius=0.02,eps=0.001" --ref water --real-pairs <pairs> --snow-pairs <snow pairs>
"""

from __future__ import annotations

import numpy as np

from murk.enhance.equalize import luma
from murk.enhance.restorer import Restored, Restorer, create, register
from murk.enhance.water_restorer import WaterRestorer, restore_with_water
from murk.models.water import WaterInView
from murk.restore_ops.affine_transfer import guided_filter, transfer_radius_px


def refine_distance(guide_rgb: np.ndarray, distance_m: np.ndarray, radius: float, eps: float) -> np.ndarray:
    """The distance map (H, W) snapped to the edges of ``guide_rgb`` (H, W, 3) by a grey guided filter."""
    if radius <= 0:
        return distance_m
    h, w = distance_m.shape
    grey = luma(guide_rgb)
    peak = float(distance_m.max()) or 1.0
    out = guided_filter(grey, (distance_m / peak).astype(np.float32), transfer_radius_px(h, w, radius), eps)
    return np.maximum(out * peak, 1e-3).astype(np.float32)


class WaterGuided(Restorer):
    name = "water_guided"

    def __init__(self, radius: float, eps: float, guide: str, strength: float) -> None:
        if guide not in ("input", "restored"):
            raise ValueError(f"guide: expected input or restored, got {guide!r}")
        inner = create(f"water?strength={strength}")
        assert isinstance(inner, WaterRestorer)
        self.inner, self.radius, self.eps, self.guide = inner, float(radius), float(eps), guide

    def restore(self, images: np.ndarray) -> Restored:
        batch = np.asarray(images, np.float32)
        if batch.ndim == 3:
            batch = batch[None]
        base = self.inner.base.restore(batch)
        assert base.depth_m is not None
        outs, dists, facts = [], [], []
        for image, restored, dist in zip(batch, base.images, base.depth_m, strict=True):
            g = image if self.guide == "input" else np.clip(restored, 0, 1)
            d = refine_distance(g, dist, self.radius, self.eps)
            water = self.inner.estimator.estimate(image, d)
            veil, att = np.asarray(water.veil), np.asarray(water.attenuation_per_m)
            outs.append(restore_with_water(image, restored, d, veil, att, self.inner.strength, self.inner.t_min))
            dists.append(d)
            facts.append(WaterInView.of(water, d).as_dict())
        return Restored(np.stack(outs).astype(np.float32), np.stack(dists), tuple(facts))


@register("water_guided")
def make_water_guided(
    *, radius: float = 0.02, eps: float = 1e-3, guide: str = "input", strength: float = 0.25
) -> WaterGuided:
    """``water?strength=strength`` with Joint-ID's distance snapped to the frame's edges (a guided filter)."""
    return WaterGuided(radius, eps, guide, strength)
