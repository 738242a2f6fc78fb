"""Estimate the water of Eq. (1) in an image: the veil ``B_c`` (the colour far water takes, RGB in [0, 1.5]) and the
attenuation ``a_c`` (1/m) per channel, from the image and its distance map in metres (e.g. Joint-ID's).

A small multilayer perceptron (two hidden layers of :data:`HIDDEN`, tanh-GELU) reads
:func:`murk.restore_ops.water.water_features` (statistics of the image in eight distance bins) and gives six numbers;
:func:`water_from_outputs` maps them to the water (``B = 1.5 sigmoid(o[:3])``, ``a = exp(clip(o[3:], -8, 2))``).
It runs in numpy (no torch); training (:mod:`murk.train.water`) builds the same network in torch and learns it on
murk's synthetic water, where the clean scene is known: its loss is what is left of the clean scene's error after
Eq. (1) is inverted with the estimate and a global colour map is forgiven. The estimate is therefore the water that
restores best with that distance map, not a measurement of the true coefficients: Joint-ID's distance is off by a
scale that the attenuation absorbs.

Weights: an ``.npz`` file (``water.npz``, shipped; model card docs/models/water.md) holding the normalisation
(``mu``, ``sd``) and the layers (``w1``, ``b1``, ``w2``, ``b2``, ``w3``, ``b3``), plus ``meta`` (JSON text).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from murk.models.npz_weights import read_npz_weights, write_npz_weights
from murk.restore_ops.water import FEATURES, visibility_m, water_features

HIDDEN = 128
"""Width of the two hidden layers."""

VEIL_MAX = 1.5
"""The largest veil value per channel (the paper's ambient light 1.5 N^D reaches it in shallow water)."""

_LAYERS = ("w1", "b1", "w2", "b2", "w3", "b3")


@dataclass(frozen=True)
class Water:
    """The estimated water of one image: ``veil`` (RGB, the colour of water far away), ``attenuation_per_m``
    (RGB, 1/m) and ``visibility_m`` (where the clearest channel keeps 5 % of an object's contrast)."""

    veil: tuple[float, float, float]
    attenuation_per_m: tuple[float, float, float]
    visibility_m: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "veil_rgb": [round(v, 4) for v in self.veil],
            "attenuation_per_m": [round(v, 4) for v in self.attenuation_per_m],
            "visibility_m": round(self.visibility_m, 2),
        }


MEASURABLE_FACTOR = 3.0
"""A visibility more than this many times the farthest distance in view (95th percentile) is not measurable."""


@dataclass(frozen=True)
class WaterInView:
    """An image's estimated water with its distance map's median and 95th percentile (metres). ``measurable``: the
    visibility is within :data:`MEASURABLE_FACTOR` times the 95th-percentile distance; beyond, the haze in view is
    too faint to tell how far one could see, and the figure is only a lower bound."""

    water: Water
    median_distance_m: float
    far_distance_m: float

    @classmethod
    def of(cls, water: Water, distance_m: np.ndarray) -> WaterInView:
        """``water`` with the statistics of the distance map it was estimated with."""
        return cls(water, float(np.median(distance_m)), float(np.percentile(distance_m, 95)))

    @property
    def measurable(self) -> bool:
        return self.water.visibility_m <= MEASURABLE_FACTOR * self.far_distance_m

    def as_dict(self) -> dict[str, Any]:
        return {
            **self.water.as_dict(),
            "visibility_measurable": self.measurable,
            "median_distance_m": round(self.median_distance_m, 2),
            "far_distance_m": round(self.far_distance_m, 2),
        }


def _gelu_tanh(x: np.ndarray) -> np.ndarray:
    """torch's ``gelu(approximate="tanh")``."""
    return 0.5 * x * (1.0 + np.tanh(math.sqrt(2.0 / math.pi) * (x + 0.044715 * x**3)))


def water_from_outputs(outputs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The network's six outputs (..., 6) -> veil (..., 3) and attenuation in 1/m (..., 3)."""
    o = np.asarray(outputs, np.float64)
    veil = VEIL_MAX / (1.0 + np.exp(-o[..., :3]))
    attenuation = np.exp(np.clip(o[..., 3:], -8.0, 2.0))
    return veil, attenuation


@dataclass(frozen=True)
class WaterEstimator:
    """The estimator's weights (float32 arrays, see the module) and where they came from."""

    arrays: dict[str, np.ndarray]
    source: str = ""
    meta: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        missing = [k for k in ("mu", "sd", *_LAYERS) if k not in self.arrays]
        if missing:
            raise ValueError(f"arrays: the water estimator needs {', '.join(missing)}")
        if self.arrays["mu"].shape != (FEATURES,) or self.arrays["w3"].shape[-1] != 6:
            raise ValueError(
                f"arrays: expected {FEATURES} features in and 6 outputs, got mu {self.arrays['mu'].shape} and "
                f"w3 {self.arrays['w3'].shape}"
            )

    def outputs(self, features: np.ndarray) -> np.ndarray:
        """The network's six raw outputs for features (..., FEATURES)."""
        a = self.arrays
        x = (np.asarray(features, np.float64) - a["mu"]) / a["sd"]
        x = _gelu_tanh(x @ a["w1"] + a["b1"])
        x = _gelu_tanh(x @ a["w2"] + a["b2"])
        return x @ a["w3"] + a["b3"]

    def estimate(self, image: np.ndarray, distance_m: np.ndarray) -> Water:
        """The water of ``image`` (H, W, 3) in [0, 1] seen at ``distance_m`` (H, W).

        Raises:
            ShapeError: the shapes do not match (:func:`murk.restore_ops.water.water_features`).
        """
        veil, att = water_from_outputs(self.outputs(water_features(image, distance_m)))
        v = (float(veil[0]), float(veil[1]), float(veil[2]))
        at = (float(att[0]), float(att[1]), float(att[2]))
        return Water(v, at, visibility_m(att))

    def save(self, path: str | Path) -> None:
        """Write the ``.npz`` file (arrays as float32, ``meta`` as JSON text)."""
        write_npz_weights(path, self.arrays, self.meta)


def load_water_estimator(path: str | Path | None = None) -> WaterEstimator:
    """Read a water estimator (``.npz``); None: the one shipped with murk (``murk.data.shipped_water_weights()``).

    Raises:
        InputFileError: the file is missing, unreadable or not a water estimator.
    """
    if path is None:
        from murk.data import shipped_water_weights

        path = shipped_water_weights()
    source = str(Path(path))
    return read_npz_weights(
        path,
        "water estimator",
        ".npz with mu, sd, w1..b3",
        lambda arrays, meta: WaterEstimator({k: v.astype(np.float64) for k, v in arrays.items()}, source, meta),
    )
