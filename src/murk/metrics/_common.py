"""Shared pieces of the metric modules: input validation, scaling, the warning class and block reductions.

Every metric takes its data range explicitly (``data_range=255`` for uint8-scaled input, ``1.0`` for floats
in [0, 1]) and never infers it from the data (DESIGN.md rule 7). Inputs outside ``[0, data_range]`` are
rejected, which catches the most common cause of wrong UIQM/UCIQE numbers: a [0, 1] image scored as if it
were [0, 255] or the reverse.

torch is imported lazily, inside the functions that need it, so that ``import murk.metrics`` stays light.
"""

from __future__ import annotations

import math
import sys
import warnings
from typing import TYPE_CHECKING, Any

import numpy as np

from murk.errors import ShapeError

if TYPE_CHECKING:
    import torch

# Values may exceed the data range by this fraction of it (float rounding of a clamp), then they are clipped.
_RANGE_SLACK = 1e-6


class MetricWarning(UserWarning):
    """A metric (or one of its terms) is undefined for this input; a documented finite value was returned."""


def warn_metric(message: str) -> None:
    """Emit a :class:`MetricWarning` attributed to the first caller outside ``murk.metrics``."""
    frame = sys._getframe(1)
    level = 2
    while frame.f_back is not None and str(frame.f_globals.get("__name__", "")).startswith("murk.metrics"):
        frame = frame.f_back
        level += 1
    warnings.warn(message, MetricWarning, stacklevel=level)


def check_data_range(data_range: Any) -> float:
    """Validate ``data_range`` (a finite number > 0) and return it as float."""
    if isinstance(data_range, bool) or not isinstance(data_range, (int, float, np.integer, np.floating)):
        raise TypeError(
            f"data_range: expected a number (255 for uint8-scaled input, 1.0 for [0, 1] floats), "
            f"got {type(data_range).__name__}"
        )
    value = float(data_range)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"data_range: expected a finite number > 0, got {value}")
    return value


def check_choice(name: str, value: Any, choices: tuple[str, ...]) -> str:
    """Validate an option string against ``choices``."""
    if not isinstance(value, str):
        raise TypeError(f"{name}: expected one of {', '.join(map(repr, choices))}, got {type(value).__name__}")
    if value not in choices:
        raise ValueError(f"{name}: expected one of {', '.join(map(repr, choices))}, got {value!r}")
    return value


def _range_message(name: str, lo: float, hi: float, data_range: float) -> str:
    hint = " (values look 0-255: pass data_range=255)" if hi > data_range and data_range <= 1.0 else ""
    return f"{name}: expected values in [0, data_range={data_range:g}], got min {lo:g}, max {hi:g}{hint}"


def check_real_array(name: str, a: Any, shape: str) -> np.ndarray:
    """``a`` unchanged when it is a numpy array of an integer or float dtype.

    Raises:
        TypeError: not a numpy array (the message says the ``shape`` expected, e.g. ``"(H, W, 3)"``), or a
            bool/complex/object dtype.
    """
    if not isinstance(a, np.ndarray):
        raise TypeError(f"{name}: expected a numpy array of shape {shape}, got {type(a).__name__}")
    if not (np.issubdtype(a.dtype, np.integer) or np.issubdtype(a.dtype, np.floating)):
        raise TypeError(f"{name}: expected an integer or float array, got dtype {a.dtype}")
    return a


def check_rgb_numpy(name: str, image: Any, data_range: float) -> np.ndarray:
    """Validate an RGB image (H, W, 3) of a real dtype with values in [0, data_range]; return it unchanged.

    Raises:
        TypeError: not a numpy array, or a bool/complex/object dtype.
        ShapeError: not (H, W, 3) with H, W >= 1.
        ValueError: NaN/inf values, or values outside [0, data_range].
    """
    check_real_array(name, image, "(H, W, 3)")
    if image.ndim != 3 or image.shape[2] != 3 or image.shape[0] < 1 or image.shape[1] < 1:
        raise ShapeError(f"{name}: expected shape (H, W, 3) with H, W >= 1, got {image.shape}")
    lo, hi = float(image.min()), float(image.max())
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ValueError(f"{name}: contains NaN or inf values")
    if lo < 0 or hi > data_range * (1 + _RANGE_SLACK):
        raise ValueError(_range_message(name, lo, hi, data_range))
    if np.issubdtype(image.dtype, np.floating):
        _warn_if_unit_range(name, hi, data_range)
    return image


def _warn_if_unit_range(name: str, hi: float, data_range: float) -> None:
    """A float image whose values all lie in (0, 1] scored with data_range >= 255 is almost surely a mistake."""
    if data_range >= 255.0 and 0.0 < hi <= 1.0:
        warn_metric(
            f"{name}: float values all in [0, {hi:g}] with data_range={data_range:g}; if this is a [0, 1] image, "
            "pass data_range=1.0 (the metric is computed as asked)"
        )


def to_255_numpy(image: np.ndarray, data_range: float, dtype: type[np.floating]) -> np.ndarray:
    """Scale a validated image to [0, 255] in ``dtype`` (no multiplication when data_range is 255)."""
    x = image.astype(dtype)
    if data_range != 255.0:
        x *= dtype(255.0 / data_range)
    np.clip(x, 0.0, 255.0, out=x)
    return x


def check_rgb_torch(name: str, images: Any, data_range: float) -> torch.Tensor:
    """Validate a batch (B, 3, H, W) of a real dtype with values in [0, data_range]; return it unchanged.

    The range check costs one device synchronisation.
    """
    import torch

    if not isinstance(images, torch.Tensor):
        raise TypeError(f"{name}: expected a torch.Tensor of shape (B, 3, H, W), got {type(images).__name__}")
    if images.dtype == torch.bool or images.is_complex():
        raise TypeError(f"{name}: expected an integer or float tensor, got dtype {images.dtype}")
    if images.ndim != 4 or images.shape[1] != 3 or min(images.shape[0], images.shape[2], images.shape[3]) < 1:
        raise ShapeError(f"{name}: expected shape (B, 3, H, W) with B, H, W >= 1, got {tuple(images.shape)}")
    x = images.detach()
    if x.is_floating_point():
        stats = torch.stack([x.amin(), x.amax(), (~torch.isfinite(x)).any().to(x.dtype)]).double().cpu()
        if stats[2] > 0:
            raise ValueError(f"{name}: contains NaN or inf values")
    else:
        stats = torch.stack([x.amin(), x.amax()]).double().cpu()
    lo, hi = float(stats[0]), float(stats[1])
    if lo < 0 or hi > data_range * (1 + _RANGE_SLACK):
        raise ValueError(_range_message(name, lo, hi, data_range))
    if x.is_floating_point():
        _warn_if_unit_range(name, hi, data_range)
    return images


def to_255_torch(images: torch.Tensor, data_range: float, dtype: torch.dtype) -> torch.Tensor:
    """Scale a validated batch to [0, 255] in ``dtype`` (the factor is rounded to ``dtype`` as numpy does)."""
    import torch

    x = images.detach().to(dtype)
    if data_range != 255.0:
        factor = torch.tensor(255.0 / data_range, dtype=dtype, device=x.device)
        x = x * factor
    return x.clamp(0.0, 255.0)


def crop_to_blocks(shape_hw: tuple[int, int], block: int) -> tuple[int, int]:
    """Number of whole blocks (k2 rows, k1 columns) of ``block`` x ``block`` pixels; partial blocks are dropped."""
    return shape_hw[0] // block, shape_hw[1] // block


def block_max_min(a: np.ndarray, block: int) -> tuple[np.ndarray, np.ndarray]:
    """Max and min over whole ``block`` x ``block`` blocks of ``a`` (H, W) or (H, W, C).

    Returns arrays of shape (k2, k1) or (k2, k1, C); partial border blocks are dropped. The reduction is an
    unrolled elementwise maximum over the ``block`` rows then columns, which is several times faster than a
    multi-axis ``ndarray.max`` on the strided block view.
    """
    k2, k1 = crop_to_blocks(a.shape[:2], block)
    tail = a.shape[2:]
    c = int(np.prod(tail)) if tail else 1
    crop = np.ascontiguousarray(a[: k2 * block, : k1 * block])
    rows = crop.reshape(k2, block, k1 * block * c)
    row_max = rows[:, 0].copy()
    row_min = rows[:, 0].copy()
    for i in range(1, block):
        np.maximum(row_max, rows[:, i], out=row_max)
        np.minimum(row_min, rows[:, i], out=row_min)
    cols_max = row_max.reshape(k2, k1, block, c)
    cols_min = row_min.reshape(k2, k1, block, c)
    out_max = cols_max[:, :, 0].copy()
    out_min = cols_min[:, :, 0].copy()
    for i in range(1, block):
        np.maximum(out_max, cols_max[:, :, i], out=out_max)
        np.minimum(out_min, cols_min[:, :, i], out=out_min)
    if not tail:
        return out_max[:, :, 0], out_min[:, :, 0]
    return out_max.reshape(k2, k1, *tail), out_min.reshape(k2, k1, *tail)


def block_max_min_torch(a: torch.Tensor, block: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Max and min over whole blocks of ``a`` (..., H, W); returns (..., k2, k1). Twin of :func:`block_max_min`."""
    h, w = a.shape[-2:]
    k2, k1 = h // block, w // block
    v = a[..., : k2 * block, : k1 * block].reshape(*a.shape[:-2], k2, block, k1, block)
    return v.amax(dim=(-3, -1)), v.amin(dim=(-3, -1))
