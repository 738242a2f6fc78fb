"""Probe (issue 46, item 4, 2026-12-07; measured, not kept): ``detail`` kept only where the input shows a bright speck.

Marine snow floats near the camera and reaches it unattenuated: in the input it stands out from its surroundings. A
small bright detail of the scene comes through the water dimmed and stands out only once the restorer lifts it. So
``base`` restores, ``detail`` runs after it, and each 8-connected part of the residual (its mean over the three
channels beyond ``threshold`` either way) is kept only where the input's CIELAB L* over the part exceeds that of a
ring around it (2-3 pixels out) by at least ``contrast``; the kept mask is dilated by one pixel and blurred (sigma
1 px). ``contrast=0`` keeps the parts that are brighter on the input at all. The probe runs ``base`` itself: name it
alone (``detail_contrast?contrast=12``), not after a restorer.

Run: PYTHONPATH=src python benchmarks/bench_arms.py --probe benchmarks/probes/detail_contrast.py lite=lite
     ld=lite+detail "c12=detail_contrast?contrast=12" --ref lite,ld --real-pairs <pairs> --snow-pairs <snow pairs>
"""

from __future__ import annotations

import cv2
import numpy as np

from murk.enhance.restorer import Restored, Restorer, create, register

RING = (np.ones((7, 7), np.uint8), np.ones((3, 3), np.uint8))


class DetailContrast(Restorer):
    name = "detail_contrast"

    def __init__(self, base: str, contrast: float, threshold: float) -> None:
        self.base, self.detail = create(base), create("detail")
        self.contrast, self.threshold = contrast, threshold

    def restore(self, images: np.ndarray) -> Restored:
        images = np.asarray(images, np.float32)
        restored = self.base.restore(images).images
        detailed = self.detail.restore(restored).images
        out = [self._kept(x, y, z) for x, y, z in zip(images, restored, detailed, strict=True)]
        return Restored(np.stack(out).astype(np.float32))

    def _kept(self, image: np.ndarray, restored: np.ndarray, detailed: np.ndarray) -> np.ndarray:
        residual = detailed - restored
        mask = (np.abs(residual.mean(-1)) > self.threshold).astype(np.uint8)
        count, labels = cv2.connectedComponents(mask, connectivity=8)
        lightness = cv2.cvtColor(np.ascontiguousarray(np.clip(image, 0, 1), np.float32), cv2.COLOR_RGB2Lab)[..., 0]
        keep = np.zeros(count, bool)
        for k in range(1, count):
            part = (labels == k).astype(np.uint8)
            ring = cv2.dilate(part, RING[0]).astype(bool) & ~cv2.dilate(part, RING[1]).astype(bool)
            if ring.any():
                keep[k] = float(lightness[part.astype(bool)].mean() - lightness[ring].mean()) >= self.contrast
        weight = cv2.GaussianBlur(cv2.dilate(keep[labels].astype(np.float32), RING[1]), (0, 0), 1.0)
        return np.clip(restored + residual * weight[..., None], 0.0, 1.0)


@register("detail_contrast")
def make_detail_contrast(*, base: str = "lite", contrast: float = 12.0, threshold: float = 0.02) -> DetailContrast:
    """``base`` then ``detail``, kept only on the parts that are bright specks on the input."""
    return DetailContrast(base, contrast, threshold)
