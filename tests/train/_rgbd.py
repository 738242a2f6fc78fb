"""A small clean RGB-D folder (``rgb/`` PNG + ``depth/`` 16-bit millimetre PNG) for the training tests."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np


def write_rgbd(root: Path, count: int = 4, hw: tuple[int, int] = (48, 64)) -> Path:
    """``count`` textured images with a planar depth ramp (0.8 m + 40 mm per column + 20 mm per row + 0.1 m per
    image) into ``root``; returns ``root``."""
    h, w = hw
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    g = np.random.default_rng(0)
    yy, xx = np.mgrid[0:h, 0:w]
    for i in range(count):
        base = (np.sin(xx / (3 + i)) * 0.5 + 0.5)[..., None] * np.array([0.9, 0.6, 0.3]) + g.random((h, w, 3)) * 0.1
        cv2.imwrite(str(root / "rgb" / f"s{i}.png"), (np.clip(base, 0, 1) * 255).astype(np.uint8))
        cv2.imwrite(str(root / "depth" / f"s{i}.png"), (800 + 40 * xx + 20 * yy + 100 * i).astype(np.uint16))
    return root
