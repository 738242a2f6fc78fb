"""Validation helpers for public entry points (one style, see DESIGN.md rule 7)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from murk.errors import ShapeError


def check_rgb(name: str, image: Any) -> np.ndarray:
    """Check a float RGB image of shape (H, W, 3) and return it as a float32 array (no copy when possible).

    Raises:
        TypeError: ``image`` is not a numpy array or not a float array.
        ShapeError: ``image`` is not (H, W, 3) with H, W >= 1.
    """
    if not isinstance(image, np.ndarray):
        raise TypeError(f"{name}: expected a numpy array of shape (H, W, 3), got {type(image).__name__}")
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] < 1 or image.shape[1] < 1:
        raise ShapeError(f"{name}: expected shape (H, W, 3), got {image.shape}")
    if not np.issubdtype(image.dtype, np.floating):
        raise TypeError(
            f"{name}: expected a float image in [0, 1], got dtype {image.dtype} (convert with murk.io.to_float)"
        )
    return image.astype(np.float32, copy=False)


def check_map(name: str, array: Any, shape: tuple[int, int] | None = None) -> np.ndarray:
    """Check a single-channel float map of shape (H, W) (optionally equal to ``shape``); return float32."""
    if not isinstance(array, np.ndarray):
        raise TypeError(f"{name}: expected a numpy array of shape (H, W), got {type(array).__name__}")
    if array.ndim != 2:
        raise ShapeError(f"{name}: expected shape (H, W), got {array.shape}")
    if shape is not None and array.shape != tuple(shape):
        raise ShapeError(f"{name}: expected shape {tuple(shape)} to match the image, got {array.shape}")
    if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
        raise TypeError(f"{name}: expected a numeric array, got dtype {array.dtype}")
    return array.astype(np.float32, copy=False)


def check_positive(name: str, value: float, *, allow_zero: bool = False) -> float:
    """Check a finite real number > 0 (or >= 0); return it as float."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__}")
    value = float(value)
    ok = math.isfinite(value) and (value >= 0 if allow_zero else value > 0)
    if not ok:
        raise ValueError(f"{name}: expected a finite number {'>=' if allow_zero else '>'} 0, got {value}")
    return value


def check_range(name: str, value: float, low: float, high: float) -> float:
    """Check low <= value <= high; return it as float."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__}")
    value = float(value)
    if not (math.isfinite(value) and low <= value <= high):
        raise ValueError(f"{name}: expected a number in [{low}, {high}], got {value}")
    return value


def check_interval(name: str, interval: Any, low: float, high: float) -> tuple[float, float]:
    """Check a (min, max) pair with low <= min <= max <= high; return it as a float tuple."""
    try:
        a, b = interval
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected a (min, max) pair, got {interval!r}") from None
    a = check_range(f"{name}[0]", a, low, high)
    b = check_range(f"{name}[1]", b, low, high)
    if a > b:
        raise ValueError(f"{name}: expected min <= max, got ({a}, {b})")
    return a, b


def int_pair(value: Any) -> tuple[int, int] | None:
    """``value`` as a pair of ints (two items ``int()`` accepts), or None when it is not one: the caller raises
    its own error."""
    try:
        a, b = (int(v) for v in value)
    except (TypeError, ValueError):
        return None
    return a, b
