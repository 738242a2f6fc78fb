"""Tiled inference with blended seams (generic, torch); padding to a size multiple lives in
:mod:`murk.models.padding` and is re-exported here.

Large frames can be processed in overlapping tiles: each tile's output is weighted by a window that ramps
linearly from ~0 to 1 across the overlap on every side that has a neighbour (and is 1 on the image border),
and the weighted outputs are divided by the summed weights. A pointwise function is reproduced exactly; a
function with a receptive field larger than the overlap, or with global context (attention, per-image
normalisation statistics as in Joint-ID), is approximated (see ``docs/jointid.md`` for measured differences).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import torch
from torch import Tensor

from murk.models.padding import Padding, PadMode, pad_to_multiple, padding_for

__all__ = ["PadMode", "Padding", "pad_to_multiple", "padding_for", "tile_starts", "tiled_apply"]


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
