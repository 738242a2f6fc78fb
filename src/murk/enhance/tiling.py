"""Padding to a size multiple and tiled inference with blended seams (generic, torch).

Networks with a total stride (Joint-ID: 32) need input sizes that are multiples of it. Instead of resizing
(which the original Joint-ID inference does, and which blurs and distorts the output), the image is
reflect-padded up to the next multiple and the output cropped back, so every output pixel corresponds to the
input pixel at the same place.

Large frames can be processed in overlapping tiles: each tile's output is weighted by a window that ramps
linearly from ~0 to 1 across the overlap on every side that has a neighbour (and is 1 on the image border),
and the weighted outputs are divided by the summed weights. A pointwise function is reproduced exactly; a
function with a receptive field larger than the overlap, or with global context (attention, per-image
normalisation statistics as in Joint-ID), is approximated (see ``docs/jointid.md`` for measured differences).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
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


def padding_for(height: int, width: int, multiple: int = 32) -> Padding:
    """The symmetric padding (extra pixel at the bottom/right) that makes (height, width) multiples of ``multiple``.

    Raises:
        ValueError: non-positive sizes or multiple.
    """
    if height < 1 or width < 1:
        raise ValueError(f"size: expected a positive height and width, got {height}x{width}")
    if multiple < 1:
        raise ValueError(f"multiple: expected a positive integer, got {multiple}")
    ph = -height % multiple
    pw = -width % multiple
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


def pad_to_multiple(x: Tensor, multiple: int = 32, mode: PadMode = "reflect") -> tuple[Tensor, Padding]:
    """Pad a (B, C, H, W) batch so that H and W become multiples of ``multiple``; never resizes.

    Reflection mirrors without repeating the edge pixel (like ``numpy.pad(mode="reflect")``) and is repeated
    when the padding is larger than the image; a 1-pixel axis is replicated instead.

    Args:
        x: (B, C, H, W) tensor, any float dtype/device.
        multiple: the size multiple (32 for Joint-ID).
        mode: ``"reflect"`` or ``"replicate"``.

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
    pad = padding_for(x.shape[2], x.shape[3], multiple)
    x = _pad_axis(x, pad.top, pad.bottom, -2, mode)
    x = _pad_axis(x, pad.left, pad.right, -1, mode)
    return x, pad


def tile_starts(size: int, tile: int, overlap: int) -> list[int]:
    """Start offsets of tiles of length ``tile`` covering ``size`` with at least ``overlap`` shared pixels.

    Tiles are spread evenly from 0 to ``size - tile`` (so the actual overlap can exceed ``overlap``); a size
    not larger than the tile gives one tile at 0.

    Raises:
        ValueError: ``tile`` < 1 or ``overlap`` not in [0, tile).
    """
    if tile < 1:
        raise ValueError(f"tile: expected a positive size in pixels, got {tile}")
    if not 0 <= overlap < tile:
        raise ValueError(f"overlap: expected 0 <= overlap < tile ({tile}), got {overlap}")
    if size <= tile:
        return [0]
    n = math.ceil((size - overlap) / (tile - overlap))
    last = size - tile
    return [round(i * last / (n - 1)) for i in range(n)]


def _ramp(length: int, overlap: int, rise: bool, fall: bool, device: torch.device) -> Tensor:
    """1-D blending weights: linear ramps of ``overlap`` pixels at the sides that have a neighbour."""
    w = torch.ones(length, dtype=torch.float32, device=device)
    if overlap > 0:
        r = (torch.arange(overlap, dtype=torch.float32, device=device) + 0.5) / overlap
        if rise:
            w[:overlap] = torch.minimum(w[:overlap], r)
        if fall:
            w[length - overlap :] = torch.minimum(w[length - overlap :], r.flip(0))
    return w


TileFn = Callable[[Tensor], Sequence[Tensor]]


def tiled_apply(
    fn: TileFn,
    x: Tensor,
    *,
    tile: int,
    overlap: int,
    multiple: int = 32,
    max_batch: int | None = None,
) -> list[Tensor]:
    """Apply ``fn`` to overlapping tiles of ``x`` and blend the outputs into full-size maps.

    Args:
        fn: maps a (N, C, h, w) batch of tiles to a sequence of (N, C_k, h, w) outputs (same spatial size).
        x: (B, C, H, W) with H and W multiples of ``multiple`` (pad first with :func:`pad_to_multiple`).
        tile: tile size in pixels (square), a multiple of ``multiple``; an axis not larger than ``tile``
            is processed whole.
        overlap: minimum overlap between neighbouring tiles in pixels, 0 <= overlap < tile; it is also the
            width of the blending ramps.
        multiple: the size multiple ``fn`` requires.
        max_batch: at most this many tiles per call of ``fn`` (the B images of one tile position always go
            together); None = one tile position per call.

    Returns:
        One float32 (B, C_k, H, W) tensor per output of ``fn``.

    Raises:
        ShapeError: ``x`` is not 4-D or its size is not a multiple of ``multiple``.
        ValueError: bad ``tile``/``overlap``/``max_batch``, or ``fn`` returns a different spatial size.
    """
    from murk.errors import ShapeError

    if x.ndim != 4:
        raise ShapeError(f"x: expected shape (B, C, H, W), got {tuple(x.shape)}")
    b, _, h, w = x.shape
    if h % multiple or w % multiple:
        raise ShapeError(f"x: expected height and width that are multiples of {multiple}, got {h}x{w}")
    if tile < multiple or tile % multiple:
        raise ValueError(f"tile: expected a positive multiple of {multiple} pixels, got {tile}")
    if not 0 <= overlap < tile:
        raise ValueError(f"overlap: expected 0 <= overlap < tile ({tile}), got {overlap}")
    if max_batch is not None and max_batch < 1:
        raise ValueError(f"max_batch: expected a positive integer or None, got {max_batch}")
    th, tw = min(tile, h), min(tile, w)
    ys, xs = tile_starts(h, th, min(overlap, th - 1)), tile_starts(w, tw, min(overlap, tw - 1))
    positions = [(y, x0) for y in ys for x0 in xs]
    wy = {y: _ramp(th, overlap, y > 0, y < ys[-1], x.device) for y in ys}
    wx = {x0: _ramp(tw, overlap, x0 > 0, x0 < xs[-1], x.device) for x0 in xs}
    per_call = max(1, (max_batch or b) // b)
    acc: list[Tensor] = []
    wsum = torch.zeros(1, 1, h, w, dtype=torch.float32, device=x.device)
    for i in range(0, len(positions), per_call):
        group = positions[i : i + per_call]
        tiles = torch.cat([x[:, :, y : y + th, x0 : x0 + tw] for y, x0 in group], dim=0)
        outs = list(fn(tiles))
        if not acc:
            acc = [torch.zeros(b, o.shape[1], h, w, dtype=torch.float32, device=x.device) for o in outs]
        for o in outs:
            if o.shape[-2:] != (th, tw):
                raise ValueError(f"fn: expected outputs of spatial size {(th, tw)}, got {tuple(o.shape[-2:])}")
        for k, (y, x0) in enumerate(group):
            win = wy[y][:, None] * wx[x0][None, :]
            for a, o in zip(acc, outs, strict=True):
                a[:, :, y : y + th, x0 : x0 + tw] += o[k * b : (k + 1) * b].float() * win
            wsum[:, :, y : y + th, x0 : x0 + tw] += win
    return [a / wsum for a in acc]
