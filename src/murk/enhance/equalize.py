"""Histogram equalisation, the first step of Eq. (9) (``I_HE``), in numpy/OpenCV and torch twins (pinned equal by
``tests/twins.py``; the torch twin has its own CLAHE, OpenCV's algorithm on a batch).

Modes (``he``):

- ``"y"`` (default): equalise the BT.601 luma ``Y = 0.299 R + 0.587 G + 0.114 B`` (the Y of OpenCV's
  YCrCb) and keep the chroma: since YCrCb -> RGB adds ``Y`` to every channel with fixed Cr/Cb, this is
  ``I_HE = clip(I + (Y_HE - Y), 0, 1)``. Colours do not shift (hue is kept until a channel clips).
- ``"rgb"``: equalise R, G and B independently (colours shift).
- ``"clahe"``: OpenCV's contrast-limited adaptive equalisation of the 8-bit ``Y`` (``clahe_clip``,
  ``clahe_tiles``), chroma kept as for ``"y"``.

``"y"``/``"rgb"`` use a 256-bin float equivalent of ``cv2.equalizeHist``: the histogram counts the channel
quantised to 8 bits (``round(255 c)``), the look-up table is OpenCV's (``lut[k] = round(255 * (cdf[k] -
cdf[k0]) / (N - h[k0]))`` with ``k0`` the first non-empty bin, identity for a constant channel), and it is
applied by linear interpolation at ``255 c``. On 8-bit values this equals ``cv2.equalizeHist`` exactly;
16-bit inputs keep their precision (no banding). ``"clahe"`` maps the quantised ``Y`` (8-bit result).

Reference: S. Yun, G. Yang, J. Lee, C. Park, J. Choi, Y. Cho, "Robust Image Processing Techniques for
Construction Environment Monitoring Using Underwater Robots" (no DOI in the source text), Sec. 4.3, Eq. (9):
``I_out = I_HE - lambda * (LoG_sigma * I_HE)`` with sigma = 1.0 px and lambda = 0.3.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from murk._checks import check_positive, check_rgb, int_pair
from murk.enhance.choices import HE_MODES, HEMode
from murk.enhance.torch_twins import check_image_batch, reflect101_index
from murk.errors import ShapeError

if TYPE_CHECKING:  # the torch twin imports it when called: post on the CPU runs without torch
    import torch

CLAHE_CLIP = 2.0
"""Default CLAHE clip limit (OpenCV's convention: multiple of the mean bin height)."""
CLAHE_TILES = 8
"""Default CLAHE grid (tiles per row and per column)."""

_LUMA = (0.299, 0.587, 0.114)  # BT.601, the Y of OpenCV's YCrCb
_F255 = np.float32(255.0)
_INV255 = np.float32(1.0 / 255.0)
_LEVELS = np.arange(256, dtype=np.float32)
_LUMA_ROWS = [np.eye(3, dtype=np.float32)[i : i + 1] * np.float32(_LUMA[i]) for i in range(3)]

TableHook = Callable[[Any], Any]
"""Replaces equalisation tables: numpy (C, 256) -> (C, 256) for one image, torch (B, C, 256) -> (B, C, 256) for a
batch of consecutive images; values are output levels in 0..255 (C = 1 for the luma, 3 for ``he="rgb"``).
:class:`murk.enhance.temporal.FrameEMA` is one: averaged over a video's frames, the tables change gradually (a
mix of monotone tables is monotone, so grey levels never swap order)."""


def equalize_lut(hist: np.ndarray) -> np.ndarray:
    """OpenCV's ``equalizeHist`` look-up table (256 float32 values in 0..255) from a 256-bin histogram;
    identity when a single bin is populated (a constant channel is left unchanged)."""
    hist = np.asarray(hist, dtype=np.int64)
    if hist.shape != (256,):
        raise ShapeError(f"hist: expected shape (256,), got {hist.shape}")
    total = int(hist.sum())
    k0 = int(np.argmax(hist > 0))
    if hist[k0] == total:
        return np.arange(256, dtype=np.float32)
    scale = _F255 / np.float32(total - int(hist[k0]))
    csum = np.cumsum(hist) - np.cumsum(hist)[k0]
    lut = np.rint(csum.astype(np.float32) * scale)
    lut[: k0 + 1] = 0
    return np.clip(lut, 0, 255).astype(np.float32)


def equalize(
    image: np.ndarray,
    he: HEMode = "y",
    *,
    clahe_clip: float = CLAHE_CLIP,
    clahe_tiles: int | tuple[int, int] = CLAHE_TILES,
    tables: TableHook | None = None,
) -> np.ndarray:
    """The histogram-equalised image ``I_HE`` of Eq. (9) (OpenCV/numpy path); see the module docstring.

    Args:
        image: float RGB (H, W, 3) in [0, 1].
        he: ``"y"`` (luma, chroma kept), ``"rgb"`` (per channel) or ``"clahe"`` (CLAHE on the luma).
        clahe_clip: CLAHE clip limit (``he="clahe"`` only).
        clahe_tiles: CLAHE grid, int or (columns, rows) (``he="clahe"`` only).
        tables: ``he="y"``/``"rgb"``: called with the image's own look-up tables, (C, 256) float32 in 0..255
            (C = 1 luma or 3 channels), returns the tables to apply instead (:data:`TableHook`).

    Returns:
        float32 (H, W, 3) in [0, 1].
    """
    image = check_rgb("image", image)
    if he not in HE_MODES:
        raise ValueError(f"he: expected one of {', '.join(HE_MODES)}, got {he!r}")
    x = np.clip(image, 0.0, 1.0)
    if tables is not None and he == "clahe":
        raise ValueError("tables: CLAHE has a table per tile; table smoothing applies to he 'y' and 'rgb'")
    if he == "rgb":
        return np.stack(_equalize_channels([x[:, :, i] for i in range(3)], tables), axis=-1)
    y = luma(x)
    if he == "y":
        (y_he,) = _equalize_channels([y], tables)
    else:
        tiles = clahe_grid(clahe_tiles)
        clahe = cv2.createCLAHE(clipLimit=check_positive("clahe_clip", clahe_clip), tileGridSize=tiles)
        y_he = clahe.apply(_quantise(y).astype(np.uint8)).astype(np.float32) * _INV255
    y_he -= y  # the luma shift, added to every channel (chroma kept)
    out = cv2.add(x, cv2.merge((y_he, y_he, y_he)))  # the same float32 sum as a broadcast add, 3x faster
    return np.clip(out, 0.0, 1.0, out=out)


def luma(x: np.ndarray) -> np.ndarray:
    """BT.601 luma ``(0.299 R + 0.587 G) + 0.114 B`` in float32, in that order (the torch twin's order).

    Each product comes from a one-row ``cv2.transform`` whose other two weights are 0 (exact: the zero terms add
    nothing), which reads the interleaved image directly: faster than splitting it into planes first.
    """
    x = np.ascontiguousarray(x, dtype=np.float32)
    y: np.ndarray = cv2.transform(x, _LUMA_ROWS[0])
    y += cv2.transform(x, _LUMA_ROWS[1])
    y += cv2.transform(x, _LUMA_ROWS[2])
    return y


def _quantise(c: np.ndarray) -> np.ndarray:
    """Channel in [0, 1] -> 8-bit bin index (int64), round half to even."""
    return np.rint(np.clip(c, 0.0, 1.0) * _F255).astype(np.int64)


def _equalize_channels(channels: list[np.ndarray], tables: TableHook | None) -> list[np.ndarray]:
    """256-bin float equalisation of channels in [0, 1] (float32 out), each by its own table, or by the tables
    ``tables`` returns for them."""
    y255s = [np.clip(c, 0.0, 1.0) * _F255 for c in channels]
    luts = np.stack([equalize_lut(level_histogram(y255)) for y255 in y255s])
    if tables is not None:
        luts = checked_tables(tables(luts), luts.shape)
    return [apply_lut(y255, lut) for y255, lut in zip(y255s, luts, strict=True)]


def level_histogram(y255: np.ndarray) -> np.ndarray:
    """The 256-bin histogram (int64) of a channel scaled to [0, 255], by 8-bit bins."""
    q = cv2.convertScaleAbs(y255)  # the 8-bit bin of each pixel: round half to even, as np.rint (pinned by tests)
    return cv2.calcHist([q], [0], None, [256], [0, 256]).ravel().astype(np.int64)


def checked_tables(luts: Any, shape: tuple[int, ...]) -> Any:
    """``luts`` (what a :data:`TableHook` returned), or a ShapeError unless it has ``shape``."""
    if tuple(luts.shape) != tuple(shape):
        raise ShapeError(f"tables: the hook must return tables of shape {tuple(shape)}, got {tuple(luts.shape)}")
    return luts


def apply_lut(y255: np.ndarray, lut: np.ndarray) -> np.ndarray:
    """``lut`` (256 values in 0..255) at ``y255`` (in [0, 255]) by linear interpolation, divided by 255.

    ``(lut[i0] + step[i0] * (y255 - i0)) / 255`` with ``step[i] = lut[i + 1] - lut[i]`` and ``i0 = min(floor(y255),
    254)``, the torch twin's operations in its order. The three gathers are 8-bit ``cv2.LUT`` look-ups: ``i0`` is
    ``round_half_even(y255 - 0.5)`` (one ``cv2.convertScaleAbs``), which is ``floor`` except at an exact integer
    ``k > 0``, where it is ``k - 1`` with ``frac = 1``: the same value, ``lut[k - 1] + (lut[k] - lut[k - 1])``, bit
    for bit while the table holds integers (tables from a :data:`TableHook` may differ in the last bit there).
    """
    lut = np.ascontiguousarray(lut, np.float32)
    step = np.zeros(256, np.float32)
    step[:255] = lut[1:] - lut[:-1]
    y255 = np.ascontiguousarray(y255, np.float32)
    i0 = cv2.convertScaleAbs(y255, alpha=1.0, beta=-0.5)  # |y255 - 0.5| rounded half to even, in 0..254
    frac = cv2.subtract(y255, cv2.LUT(i0, _LEVELS))
    out = cv2.multiply(cv2.LUT(i0, step), frac, dst=frac)
    cv2.add(out, cv2.LUT(i0, lut), dst=out)
    out *= _INV255
    return out


# --- torch twin ---------------------------------------------------------------------------------------------


def equalize_torch(
    images: torch.Tensor,
    he: HEMode = "y",
    *,
    clahe_clip: float = CLAHE_CLIP,
    clahe_tiles: int | tuple[int, int] = CLAHE_TILES,
    tables: TableHook | None = None,
) -> torch.Tensor:
    """Torch twin of :func:`equalize` on a batch (B, 3, H, W) in [0, 1]; every image has its own histogram.
    ``tables`` gets the batch's tables as (B, C, 256) float32, the images in order."""
    check_image_batch(images, channels=3)
    if he not in HE_MODES:
        raise ValueError(f"he: expected one of {', '.join(HE_MODES)}, got {he!r}")
    if tables is not None and he == "clahe":
        raise ValueError("tables: CLAHE has a table per tile; table smoothing applies to he 'y' and 'rgb'")
    x = images.float().clamp(0.0, 1.0)
    b, _, h, w = x.shape
    if he == "rgb":
        return _equalize_channels_torch(x.reshape(b * 3, h, w), tables, per_image=3).reshape(b, 3, h, w)
    y = _LUMA[0] * x[:, 0] + _LUMA[1] * x[:, 1] + _LUMA[2] * x[:, 2]
    if he == "y":
        y_he = _equalize_channels_torch(y, tables, per_image=1)
    else:
        q = _quantise_torch(y)
        clip = check_positive("clahe_clip", clahe_clip)
        y_he = _clahe_torch(q, clip, clahe_grid(clahe_tiles)).float() * _INV255.item()
    return (x + (y_he - y)[:, None]).clamp(0.0, 1.0)


def _quantise_torch(c: torch.Tensor) -> torch.Tensor:
    import torch

    return torch.round(c.clamp(0.0, 1.0) * 255.0).long()


def _equalize_luts_torch(hist: torch.Tensor) -> torch.Tensor:
    """Batched :func:`equalize_lut`: (N, 256) int64 -> (N, 256) float32."""
    import torch

    total = hist.sum(dim=1, keepdim=True)
    k0 = torch.argmax((hist > 0).to(torch.uint8), dim=1, keepdim=True)
    h0 = hist.gather(1, k0)
    csum = torch.cumsum(hist, dim=1)
    csum = csum - csum.gather(1, k0)
    denom = (total - h0).clamp(min=1).float()
    scale = torch.full_like(denom, 255.0) / denom
    lut = torch.round(csum.float() * scale)
    bins = torch.arange(256, device=hist.device)
    lut = torch.where(bins[None] <= k0, torch.zeros_like(lut), lut).clamp(0.0, 255.0)
    constant = h0 == total
    return torch.where(constant, bins[None].float().expand_as(lut), lut)


def _equalize_channels_torch(c: torch.Tensor, tables: TableHook | None = None, per_image: int = 1) -> torch.Tensor:
    """Equalise N independent channels (N, H, W) in [0, 1]; ``tables`` sees them as (N / per_image, per_image,
    256)."""
    import torch

    n = c.shape[0]
    q = _quantise_torch(c).reshape(n, -1)
    offsets = (torch.arange(n, device=c.device) * 256)[:, None]
    hist = torch.bincount((q + offsets).reshape(-1), minlength=n * 256).reshape(n, 256)
    lut = _equalize_luts_torch(hist)
    if tables is not None:
        shape = (n // per_image, per_image, 256)
        lut = checked_tables(tables(lut.reshape(shape)), shape).reshape(n, 256).float()
    step = torch.zeros_like(lut)
    step[:, :255] = lut[:, 1:] - lut[:, :-1]
    y255 = c.clamp(0.0, 1.0).reshape(n, -1) * 255.0
    i0 = y255.clamp(max=254.0).long()  # truncation == floor, y255 >= 0
    frac = y255 - i0.float()
    return ((lut.gather(1, i0) + step.gather(1, i0) * frac) * _INV255.item()).reshape(c.shape)


def _clahe_torch(q: torch.Tensor, clip_limit: float, tiles: tuple[int, int]) -> torch.Tensor:
    """OpenCV's CLAHE (8-bit) on a batch of quantised channels q (N, H, W) int64 -> (N, H, W) int64.

    Follows OpenCV's definition: the image is extended by reflect-101 to a multiple of the grid when it does
    not divide evenly; per-tile histograms are clipped at ``max(int(clip * tile_area / 256), 1)`` and the
    excess redistributed uniformly (remainder one count every ``256 // remainder`` bins); each tile's LUT is
    ``round(cdf * 255 / tile_area)``; pixels blend the four nearest tile LUTs bilinearly (tile centres).
    """
    import torch

    n, h, w = q.shape
    tx, ty = tiles
    dev = q.device
    if h % ty == 0 and w % tx == 0:
        qp = q
    else:  # OpenCV adds (tiles - size % tiles) on BOTH axes in this case
        qp = q.index_select(1, reflect101_index(h, ty - h % ty, dev)).index_select(
            2, reflect101_index(w, tx - w % tx, dev)
        )
    hp, wp = qp.shape[1:]
    th, tw = hp // ty, wp // tx
    area = th * tw
    # Per-tile histograms.
    tile_id = (torch.arange(hp, device=dev) // th)[:, None] * tx + (torch.arange(wp, device=dev) // tw)[None, :]
    idx = (torch.arange(n, device=dev)[:, None, None] * (ty * tx) + tile_id[None]) * 256 + qp
    hist = torch.bincount(idx.reshape(-1), minlength=n * ty * tx * 256).reshape(n * ty * tx, 256)
    # Clip and redistribute.
    limit = max(int(clip_limit * area / 256), 1)
    excess = (hist - limit).clamp(min=0).sum(dim=1, keepdim=True)
    hist = hist.clamp(max=limit)
    batch = excess // 256
    residual = excess - batch * 256
    hist = hist + batch
    bins = torch.arange(256, device=dev)[None]
    step = torch.where(residual > 0, (256 // residual.clamp(min=1)).clamp(min=1), torch.ones_like(residual))
    hist = hist + ((bins % step == 0) & (bins // step < residual)).long()
    lut_scale = np.float32(255.0) / np.float32(area)
    luts = torch.round(torch.cumsum(hist, dim=1).float() * float(lut_scale)).clamp(0, 255)
    luts = luts.reshape(n, ty * tx * 256)
    # Bilinear blend of the four nearest tiles' LUTs.
    inv_tw, inv_th = float(np.float32(1.0) / np.float32(tw)), float(np.float32(1.0) / np.float32(th))
    txf = torch.arange(w, device=dev, dtype=torch.float32) * inv_tw - 0.5
    tyf = torch.arange(h, device=dev, dtype=torch.float32) * inv_th - 0.5
    tx1, ty1 = torch.floor(txf), torch.floor(tyf)
    xa, ya = txf - tx1, tyf - ty1
    xa1, ya1 = 1.0 - xa, 1.0 - ya
    tx1, ty1 = tx1.long(), ty1.long()
    tx2, ty2 = (tx1 + 1).clamp(max=tx - 1), (ty1 + 1).clamp(max=ty - 1)
    tx1, ty1 = tx1.clamp(min=0), ty1.clamp(min=0)
    qf = q.reshape(n, -1)

    def lut_at(tyi: torch.Tensor, txi: torch.Tensor) -> torch.Tensor:
        base = ((tyi[:, None] * tx + txi[None, :]) * 256).reshape(1, -1)
        return luts.gather(1, base + qf)

    l11, l12 = lut_at(ty1, tx1), lut_at(ty1, tx2)
    l21, l22 = lut_at(ty2, tx1), lut_at(ty2, tx2)
    xa_f, xa1_f = xa.repeat(h)[None], xa1.repeat(h)[None]
    ya_f, ya1_f = ya.repeat_interleave(w)[None], ya1.repeat_interleave(w)[None]
    res = (l11 * xa1_f + l12 * xa_f) * ya1_f + (l21 * xa1_f + l22 * xa_f) * ya_f
    return torch.round(res).clamp(0, 255).long().reshape(n, h, w)


def clahe_grid(tiles: Any) -> tuple[int, int]:
    """A CLAHE grid (an int: square, or (columns, rows)) as (columns, rows), checked."""
    if isinstance(tiles, bool):
        raise TypeError(f"clahe_tiles: expected an int or a (columns, rows) pair, got {tiles!r}")
    pair = int_pair((tiles, tiles) if isinstance(tiles, (int, np.integer)) else tiles)
    if pair is None:
        raise TypeError(f"clahe_tiles: expected an int or a (columns, rows) pair, got {tiles!r}")
    tx, ty = pair
    if tx < 1 or ty < 1:
        raise ValueError(f"clahe_tiles: expected tiles >= 1, got {(tx, ty)}")
    return tx, ty
