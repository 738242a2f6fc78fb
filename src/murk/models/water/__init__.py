"""The water estimator: the veil colour and the attenuation per channel of the water in an image, from the image and
its distance map (:mod:`murk.models.water.estimator`; trained by :mod:`murk.train.water`)."""

from murk.models.water.estimator import (
    HIDDEN,
    MEASURABLE_FACTOR,
    Water,
    WaterEstimator,
    WaterInView,
    load_water_estimator,
    water_from_outputs,
)

__all__ = [
    "HIDDEN",
    "MEASURABLE_FACTOR",
    "Water",
    "WaterEstimator",
    "WaterInView",
    "load_water_estimator",
    "water_from_outputs",
]
