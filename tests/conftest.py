"""Shared fixtures. Test data lives in tests/data (fixtures) and in the package (murk/data, shipped samples)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

TESTS_DATA = Path(__file__).resolve().parent / "data"


@pytest.fixture(scope="session")
def tests_data() -> Path:
    return TESTS_DATA


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.fixture
def small_rgbd(tmp_path: Path) -> Path:
    """A tiny synthetic RGB-D folder (rgb/, depth/ in mm) with two pairs, 48x64."""
    import cv2

    root = tmp_path / "rgbd"
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    g = np.random.default_rng(0)
    for i, stem in enumerate(("a", "b")):
        rgb = (g.random((48, 64, 3)) * 255).astype(np.uint8)
        yy, xx = np.mgrid[0:48, 0:64]
        depth_mm = (500 + 100 * xx + 50 * yy + 300 * i).astype(np.uint16)
        cv2.imwrite(str(root / "rgb" / f"{stem}.png"), rgb)
        cv2.imwrite(str(root / "depth" / f"{stem}.png"), depth_mm)
    return root
