"""Probe (issue 46, 2026-12-07; measured, not kept): ``desnow`` with the particles found on the input.

Snow floats near the camera and reaches it unattenuated; the scene's small bright details come through the water
dimmed until the restorer lifts them back. So the particles might be told apart better on the input than on the
restoration. ``base`` restores; the particles are found (``murk.snow.remove.find_particles``, ``desnow``'s rules and
``threshold`` / ``crowd`` / ``size``) on ``source``: ``input`` (raw), ``balanced`` (its 1 % / 1 % balance, what
``lite`` sees), ``output`` (the restoration: ``lite+desnow``), or ``both`` / ``bothraw`` (the output's particles that
also touch one found on the balanced / raw input); they are filled on the restoration as ``desnow`` fills them.

Run: PYTHONPATH=src python benchmarks/bench_arms.py --probe benchmarks/probes/desnow_input.py lite=lite
     "ld=desnow_input?source=output,crowd=0.05" "lb=desnow_input?source=both,crowd=0.05" --ref lite
     --real-pairs <pairs> --snow-pairs <snow pairs>
"""

from __future__ import annotations

import cv2
import numpy as np

from murk.enhance.restorer import Restored, Restorer, create, register
from murk.restore_ops.balance import color_balance
from murk.snow.remove import SnowRemoval, fill_particles, find_particles

SOURCES = ("input", "balanced", "output", "both", "bothraw")


class DesnowInput(Restorer):
    name = "desnow_input"

    def __init__(self, base: str, source: str, removal: SnowRemoval) -> None:
        if source not in SOURCES:
            raise ValueError(f"source: expected one of {', '.join(SOURCES)}, got {source!r}")
        self.base, self.source, self.removal = create(base), source, removal

    def restore(self, images: np.ndarray) -> Restored:
        images = np.asarray(images, np.float32)
        restored = self.base.restore(images).images
        return Restored(np.stack([self._one(x, y) for x, y in zip(images, restored, strict=True)]).astype(np.float32))

    def _one(self, image: np.ndarray, out: np.ndarray) -> np.ndarray:
        balanced = color_balance(image, 1.0, 1.0)
        found = {"input": image, "balanced": balanced, "output": out, "bothraw": image, "both": balanced}
        mask = find_particles(np.ascontiguousarray(found[self.source]), self.removal)
        if self.source in ("both", "bothraw"):
            on_output = find_particles(np.ascontiguousarray(out), self.removal)
            count, labels = cv2.connectedComponents(on_output.astype(np.uint8), connectivity=8)
            keep = np.zeros(count, bool)
            keep[np.unique(labels[mask & (labels > 0)])] = True
            keep[0] = False
            mask = keep[labels]
        return fill_particles(np.ascontiguousarray(out), mask, self.removal.size_px(*out.shape[:2]))


@register("desnow_input")
def make_desnow_input(
    *, base: str = "lite", source: str = "both", threshold: float = 0.1, crowd: float = 0.05, size: float = 0.03
) -> DesnowInput:
    """``base``'s restoration with the particles found on ``source`` filled."""
    return DesnowInput(base, source, SnowRemoval(threshold=threshold, crowd=crowd, size=size))
