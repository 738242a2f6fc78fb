"""Padding to a size multiple without resizing (generic, torch).

Networks with a total stride (Joint-ID: 32) need input sizes that are multiples of it. Instead of resizing
(which the original Joint-ID inference does, and which blurs and distorts the output), the image is
reflect-padded up to the next multiple and the output cropped back, so every output pixel corresponds to the
input pixel at the same place. Used by inference (:mod:`murk.enhance.tiling`, the ``jointid`` restorer) and by
evaluation during training.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import torch
import torch.nn.functional as F
from torch import Tensor

PadMode = Literal["reflect", "replicate"]


@dataclass(frozen=True)
class Padding:
    """Pixels added on each side by :func:`pad_to_multiple`; :meth:`crop` removes them."""

    top: int
    bottom: int
    left: int
    right: int

    def crop(self, x: Tensor) -> Tensor:
        """Remove the padding from a (..., H_padded, W_padded) tensor."""
        h, w = x.shape[-2], x.shape[-1]
        return x[..., self.top : h - self.bottom, self.left : w - self.right]


def padding_for(height: int, width: int, multiple: int = 32, *, min_size: int = 1) -> Padding:
    """The symmetric padding (extra pixel at the bottom/right) that makes (height, width) multiples of ``multiple``
    and at least ``min_size`` (a network that runs on fixed-size tiles needs frames at least one tile large).

    Raises:
        ValueError: non-positive sizes, multiple or min_size.
    """
    if height < 1 or width < 1:
        raise ValueError(f"size: expected a positive height and width, got {height}x{width}")
    if multiple < 1:
        raise ValueError(f"multiple: expected a positive integer, got {multiple}")
    if min_size < 1:
        raise ValueError(f"min_size: expected a positive integer, got {min_size}")
    ph = max(height + -height % multiple, min_size + -min_size % multiple) - height
    pw = max(width + -width % multiple, min_size + -min_size % multiple) - width
    return Padding(ph // 2, ph - ph // 2, pw // 2, pw - pw // 2)


def _pad_axis(x: Tensor, before: int, after: int, dim: int, mode: PadMode) -> Tensor:
    """Pad one spatial axis (dim -1 or -2); reflection is repeated when the pad exceeds the size - 1."""
    while before > 0 or after > 0:
        size = x.shape[dim]
        step = size - 1 if mode == "reflect" else max(before, after)
        if step < 1:  # a single row/column cannot be reflected: replicate it
            mode, step = "replicate", max(before, after)
        b, a = min(before, step), min(after, step)
        pads = (b, a, 0, 0) if dim == -1 else (0, 0, b, a)
        x = F.pad(x, pads, mode=mode)
        before, after = before - b, after - a
    return x


def reflect_index(pos: Tensor, n: Tensor | int) -> Tensor:
    """The source index of each position ``pos`` (integers, any sign or size) of an axis of length ``n`` extended by
    :func:`pad_to_multiple`'s ``reflect`` (mirrored without repeating the edge, repeated when the padding exceeds
    the axis: periodic with period ``2 (n - 1)``; a 1-pixel axis is replicated). Gathering the axis at
    ``reflect_index(arange(n + before + after) - before, n)`` equals the padding (pinned by a test); written with
    tensor arithmetic only, so that a traced ONNX graph computes it for any ``n``."""
    period = torch.clamp(2 * torch.as_tensor(n) - 2, min=1)
    m = torch.remainder(pos.abs(), period)
    return torch.where(m < n, m, period - m)


def reflect_rows(n: Tensor, n_padded: Tensor, before: Tensor) -> Tensor:
    """The rows (or columns) to gather from an axis of length ``n`` to pad it to ``n_padded`` with ``before`` of them
    first, as :func:`pad_to_multiple`'s ``reflect`` does (0-dim int64 tensors: traced, an ONNX graph computes the
    padding of each frame it gets)."""
    return reflect_index(torch.arange(n_padded) - before, n)  # type: ignore[call-overload]  # a 0-dim tensor


def pad_to_multiple(
    x: Tensor, multiple: int = 32, mode: PadMode = "reflect", *, min_size: int = 1
) -> tuple[Tensor, Padding]:
    """Pad a (B, C, H, W) batch so that H and W become multiples of ``multiple``; never resizes.

    Reflection mirrors without repeating the edge pixel (like ``numpy.pad(mode="reflect")``) and is repeated
    when the padding is larger than the image; a 1-pixel axis is replicated instead.

    Args:
        x: (B, C, H, W) tensor, any float dtype/device.
        multiple: the size multiple (32 for Joint-ID).
        mode: ``"reflect"`` or ``"replicate"``.
        min_size: pad smaller axes up to at least this size (rounded up to ``multiple``).

    Returns:
        The padded tensor and the :class:`Padding`, whose ``crop`` undoes it.

    Raises:
        ShapeError: ``x`` is not 4-D.
        ValueError: unknown mode.
    """
    from murk.errors import ShapeError

    if x.ndim != 4:
        raise ShapeError(f"x: expected shape (B, C, H, W), got {tuple(x.shape)}")
    if mode not in ("reflect", "replicate"):
        raise ValueError(f"mode: expected 'reflect' or 'replicate', got {mode!r}")
    pad = padding_for(x.shape[2], x.shape[3], multiple, min_size=min_size)
    x = _pad_axis(x, pad.top, pad.bottom, -2, mode)
    x = _pad_axis(x, pad.left, pad.right, -1, mode)
    return x, pad


def area_size(height: int, width: int, area_px: int, multiple: int) -> tuple[int, int] | None:
    """(h, w) of a ``height`` x ``width`` frame shrunk to about ``area_px`` pixels, or None to keep the frame.

    None when ``area_px`` is 0 or the frame has at most that many pixels. Otherwise the frame scaled by
    ``s = sqrt(area_px / (height * width))``, each side rounded to the nearest multiple of ``multiple`` (at least
    one multiple), so the aspect is kept to within the rounding. ``lite``'s working image
    (:func:`murk.models.lite.network.work_size`) and Joint-ID's depth pass (``depth_area``) are sized by it.
    """
    if area_px <= 0 or height * width <= area_px:
        return None
    s = (area_px / (height * width)) ** 0.5
    return max(multiple, round(height * s / multiple) * multiple), max(multiple, round(width * s / multiple) * multiple)
