"""Probe (issue 46, 2026-12-07; measured, not kept): a per-image blend of ``colorbalance`` and ``lite`` set by the
input's colour cast.

``colorbalance + s (lite - colorbalance)`` with ``s = below`` when the input's cast (the chroma of its mean CIELAB
colour, measured on the raw input before any balance) is under ``cast``, else 1 (``lite``). The write-up's
threshold, drawn by eye on the development pairs it is scored on: ``cast_gate?cast=17,below=0.5`` (+0.16 dB on the
mean over sets, more than half of it from one image). ``below=1`` is ``lite``; ``below=0`` under a cast no image
reaches is ``colorbalance``.

Run: PYTHONPATH=src python benchmarks/bench_arms.py --probe benchmarks/probes/cast_gate.py lite=lite
     "g=cast_gate?cast=17,below=0.5" --ref lite --real-pairs <pairs> --heldout-scenes 0
"""

from __future__ import annotations

import cv2
import numpy as np

from murk.enhance.restorer import Restored, Restorer, create, register


def colour_cast(image: np.ndarray) -> float:
    """The chroma of the mean CIELAB colour of an RGB image (H, W, 3) in [0, 1]."""
    lab = cv2.cvtColor(np.ascontiguousarray(image, np.float32), cv2.COLOR_RGB2Lab)
    return float(np.hypot(lab[..., 1].mean(), lab[..., 2].mean()))


class CastGate(Restorer):
    name = "cast_gate"

    def __init__(self, cast: float, below: float) -> None:
        self.lite, self.balance = create("lite"), create("colorbalance")
        self.cast, self.below = cast, below

    def restore(self, images: np.ndarray) -> Restored:
        images = np.asarray(images, np.float32)
        a, b = self.balance.restore(images).images, self.lite.restore(images).images
        out = [lo + np.float32(self.below) * (hi - lo) if colour_cast(x) < self.cast else hi
               for x, lo, hi in zip(images, a, b, strict=True)]  # fmt: skip
        return Restored(np.clip(np.stack(out), 0.0, 1.0).astype(np.float32))


@register("cast_gate")
def make_cast_gate(*, cast: float = 17.0, below: float = 0.5) -> CastGate:
    """``lite``, blended toward ``colorbalance`` on images whose colour cast is under ``cast``."""
    return CastGate(cast, below)
