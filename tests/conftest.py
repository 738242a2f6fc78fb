"""Shared fixtures. Test data lives in tests/data (fixtures) and in the package (murk/data, shipped samples)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from testkit.video import make_frames, mjpeg_camera

TESTS_DATA = Path(__file__).resolve().parent / "data"


def pytest_configure(config: pytest.Config) -> None:
    """Under pytest-xdist each worker gets one torch thread: N workers x all-core OpenMP pools on N cores
    oversubscribe, and two trainings side by side then ran 10x slower (measured: a 20 s test took 268 s)."""
    import os

    if os.environ.get("PYTEST_XDIST_WORKER"):
        import torch

        torch.set_num_threads(1)


@pytest.fixture(autouse=True)
def _reset_pixel_limit() -> Iterator[None]:
    """``murk --max-pixels N`` sets a process-wide limit (:func:`murk._limits.set_max_pixels`); a CLI test that
    invokes it in-process left it set for the next test on the same worker (a 35-pixel limit from a snow-bank test
    failed three training-data tests, 2026-12-07, depending on the order). Every test starts and ends without it."""
    from murk._limits import set_max_pixels

    set_max_pixels(None)
    yield
    set_max_pixels(None)


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


@pytest.fixture
def mjpeg_server() -> Iterator[Callable[..., str]]:
    """Start MJPEG-over-HTTP cameras on localhost: ``start(frames, delay_s=0.005, loop=False) -> url``; each
    serves its frames to a client, then disconnects (``loop``: serves them until the client goes away)."""
    with contextlib.ExitStack() as stack:
        yield lambda frames, delay_s=0.005, loop=False: stack.enter_context(mjpeg_camera(frames, delay_s, loop=loop))


@pytest.fixture
def mjpeg_url(mjpeg_server: Callable[..., str]) -> str:
    """A camera on localhost streaming 15 MJPEG frames over HTTP, then disconnecting."""
    return mjpeg_server(make_frames(15))
