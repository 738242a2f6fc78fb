"""Probe (issue 46, 2026-12-07; measured, not kept): ``detail`` keeping only the larger parts of its residual.

``detail`` costs about 0.25 dB on the development pairs because it also fades small bright details of the scene. If
those were smaller than marine snow, dropping the residual's small connected parts would keep the snow removal and
lose the cost. Stage to chain after a restorer: ``lite+detail_area?area=16``. The residual's luma is thresholded at
``threshold``; its 8-connected parts of fewer than ``area`` pixels are zeroed (the kept mask dilated by one pixel and
blurred with sigma 1 px so that the edges stay soft). ``area=0`` is ``detail`` itself. "Luma" here is the mean over
the three channels.

Run: PYTHONPATH=src python benchmarks/bench_arms.py --probe benchmarks/probes/detail_area.py lite=lite
     ld=lite+detail a4=lite+detail_area?area=4 a16=lite+detail_area?area=16 --ref lite --real-pairs <pairs>
     --snow-pairs <snow pairs>
"""

from __future__ import annotations

import cv2
import numpy as np

from murk.enhance.restorer import Restored, Restorer, create, register


class DetailArea(Restorer):
    name = "detail_area"

    def __init__(self, area: int, threshold: float) -> None:
        self.detail = create("detail")
        self.area, self.threshold = area, threshold

    def restore(self, images: np.ndarray) -> Restored:
        images = np.asarray(images, np.float32)
        detailed = self.detail.restore(images).images
        return Restored(np.stack([self._kept(x, y) for x, y in zip(images, detailed, strict=True)]))

    def _kept(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        residual = y - x
        if self.area <= 0:
            return y
        mask = (np.abs(residual.mean(-1)) > self.threshold).astype(np.uint8)
        _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        keep = stats[:, cv2.CC_STAT_AREA] >= self.area
        keep[0] = False
        weight = cv2.dilate(keep[labels].astype(np.float32), np.ones((3, 3), np.uint8))
        weight = cv2.GaussianBlur(weight, (0, 0), 1.0)
        return np.clip(x + residual * weight[..., None], 0.0, 1.0).astype(np.float32)


@register("detail_area")
def make_detail_area(*, area: int = 16, threshold: float = 0.02) -> DetailArea:
    """``detail`` with its residual's parts smaller than ``area`` pixels dropped."""
    return DetailArea(area, threshold)
