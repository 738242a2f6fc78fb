"""``murk water estimate`` as a library call: the water of each image (veil colour, attenuation per channel,
visibility in metres), estimated from the image and Joint-ID's distance map (:mod:`murk.models.water`).

An image that cannot be read is one error record (the :mod:`murk.io.jobs` schema); the others are estimated.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from murk.io.jobs import ErrorRecord
from murk.models.water import Water

MEASURABLE_FACTOR = 3.0
"""A visibility more than this many times the farthest distance in view (95th percentile) is not measurable."""


@dataclass(frozen=True)
class WaterOfImage:
    """One image's estimate and its distance map's median and 95th percentile (metres). ``measurable``: the
    visibility is within :data:`MEASURABLE_FACTOR` times the 95th-percentile distance; beyond, the haze in view is
    too faint to tell how far one could see, and the figure is only a lower bound."""

    path: Path
    water: Water
    median_distance_m: float
    far_distance_m: float

    @property
    def measurable(self) -> bool:
        return self.water.visibility_m <= MEASURABLE_FACTOR * self.far_distance_m

    def as_dict(self) -> dict[str, object]:
        return {
            "image": str(self.path),
            **self.water.as_dict(),
            "visibility_measurable": self.measurable,
            "median_distance_m": round(self.median_distance_m, 2),
            "far_distance_m": round(self.far_distance_m, 2),
        }


def estimate_water(
    paths: Sequence[Path],
    *,
    depth_method: str = "jointid_net",
    estimator: Path | None = None,
    on_image: Callable[[WaterOfImage | ErrorRecord], None] | None = None,
) -> list[WaterOfImage | ErrorRecord]:
    """Estimate the water of every image of ``paths`` (files, or folders of images), in order.

    Raises:
        InputFileError: the estimator file cannot be read.
        ValueError: ``depth_method`` gives no distance map.
    """
    import numpy as np

    from murk.enhance.restorer import create
    from murk.io.images import list_images, read_rgb
    from murk.models.water import load_water_estimator

    model = load_water_estimator(estimator)
    depth_net = create(depth_method)
    files: list[Path] = []
    results: list[WaterOfImage | ErrorRecord] = []
    for p in paths:
        if p.is_dir():
            found = list_images(p, recursive=True)
            files.extend(found)
            if not found:
                results.append(ErrorRecord(str(p), "list", f"{p}: folder holds no images"))
        else:
            files.append(p)
    for path in files:
        result: WaterOfImage | ErrorRecord
        try:
            image = read_rgb(path)
        except (OSError, ValueError) as exc:
            result = ErrorRecord(str(path), "read", str(exc))
        else:
            dist = depth_net.restore(image[None]).depth_m
            if dist is None:
                raise ValueError(f"depth_method: {depth_method!r} gives no distance map; use jointid_net")
            d = dist[0]
            result = WaterOfImage(path, model.estimate(image, d), float(np.median(d)), float(np.percentile(d, 95)))
        results.append(result)
        if on_image is not None:
            on_image(result)
    return results
