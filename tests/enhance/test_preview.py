"""Depth colour previews (fixed range, near = warm) and side-by-side panels."""

from __future__ import annotations

import numpy as np
import pytest

from murk.enhance.preview import DEPTH_PREVIEW_RANGE_M, INVALID_GREY, colorize_depth, side_by_side
from murk.errors import ShapeError


def test_colours_come_from_a_fixed_range_not_from_the_image() -> None:
    a = np.array([[2.0, 5.0]], np.float32)
    b = np.array([[2.0, 14.0]], np.float32)  # same 2 m pixel, different neighbour
    ca, cb = colorize_depth(a), colorize_depth(b)
    np.testing.assert_array_equal(ca[0, 0], cb[0, 0])  # a per-image min/max stretch would change this colour
    assert DEPTH_PREVIEW_RANGE_M == (0.0, 15.0)


def test_near_is_warm_and_bright_far_is_dark_and_invalid_is_grey() -> None:
    d = np.array([[0.5, 7.5, 15.0, 40.0, 0.0, np.nan]], np.float32)
    c = colorize_depth(d)
    assert c.shape == (1, 6, 3) and c.dtype == np.float32 and 0 <= c.min() and c.max() <= 1
    near, mid, far, beyond = c[0, 0], c[0, 1], c[0, 2], c[0, 3]
    assert near[0] > near[2] and near.sum() > mid.sum() > far.sum()  # warm (red > blue), brightness falls
    assert far.sum() < 0.1 and np.array_equal(far, beyond)  # clipped at the far end of the range
    np.testing.assert_array_equal(c[0, 4:], INVALID_GREY)


def test_colorize_validation() -> None:
    with pytest.raises(ValueError, match="range_m: expected near < far"):
        colorize_depth(np.ones((2, 2), np.float32), (5.0, 5.0))
    with pytest.raises(ShapeError, match=r"depth_m: expected shape \(H, W\)"):
        colorize_depth(np.ones((2, 2, 1), np.float32))


def test_side_by_side() -> None:
    left = np.zeros((4, 6, 3), np.uint16)
    right = np.full((4, 6, 3), 9, np.uint16)
    panel = side_by_side(left, right)
    assert panel.shape == (4, 12, 3) and panel.dtype == np.uint16 and (panel[:, 6:] == 9).all()
    assert side_by_side(np.zeros((8, 12, 3), np.float32), np.ones((4, 6, 3), np.float32)).shape == (4, 12, 3)
    with pytest.raises(ShapeError, match="left, right"):
        side_by_side(np.zeros((4, 6), np.uint8), right)
