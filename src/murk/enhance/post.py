"""Post-processing of Sec. 4.3: histogram equalisation, then Laplacian-of-Gaussian edge enhancement (Eq. 9).

Reference: S. Yun, G. Yang, J. Lee, C. Park, J. Choi, Y. Cho, "Robust Image Processing Techniques for
Construction Environment Monitoring Using Underwater Robots" (no DOI in the source text), Sec. 4.3, Eq. (9):
``I_out = I_HE - lambda * (LoG_sigma * I_HE)`` with sigma = 1.0 px and lambda = 0.3.

Everything works on float32 RGB in [0, 1]. The float pipeline is defined exactly, so that the OpenCV path
(:func:`post_process`, one image) and the torch twin (:func:`post_process_torch`, batches on any device)
agree to float rounding (the LoG sums are accumulated in a different order; see ``tests/enhance/test_post.py``):

1. Histogram equalisation (``he``):

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
2. Laplacian of Gaussian, per channel, border reflect-101: ``LoG = g'' (x) g (y) + g (x) g'' (y)`` with the
   sampled Gaussian ``g`` (radius ``ceil(4 sigma)``, sum 1) and its second derivative ``g''`` made exactly
   zero-sum, so the LoG of a constant image is 0.
3. ``I_out = clip(I_HE - lambda * LoG(I_HE), 0, 1)`` (Eq. 9).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from murk._checks import check_positive, check_range, check_rgb
from murk.enhance.choices import HE_MODES, HEMode
from murk.enhance.declare import Checked
from murk.enhance.restorer import Restored, RestoredTensor, Restorer, as_batch, device_type
from murk.enhance.temporal import FrameEMA
from murk.errors import ShapeError

if TYPE_CHECKING:  # the torch twins import it when called: post on the CPU runs without torch
    import torch

SIGMA_PX = 1.0
"""LoG standard deviation of the paper (Sec. 5.1)."""
LAMBDA = 0.3
"""Edge-enhancement weight of the paper (Sec. 5.1)."""
CLAHE_CLIP = 2.0
"""Default CLAHE clip limit (OpenCV's convention: multiple of the mean bin height)."""
CLAHE_TILES = 8
"""Default CLAHE grid (tiles per row and per column)."""

_LUMA = (0.299, 0.587, 0.114)  # BT.601, the Y of OpenCV's YCrCb
_F255 = np.float32(255.0)
_INV255 = np.float32(1.0 / 255.0)
_LEVELS = np.arange(256, dtype=np.float32)
_LUMA_ROWS = [np.eye(3, dtype=np.float32)[i : i + 1] * np.float32(_LUMA[i]) for i in range(3)]


@dataclass(frozen=True)
class PostParams:
    """Parameters of Eq. (9). ``clahe_tiles`` is an int (square grid) or (columns, rows)."""

    sigma_px: float = SIGMA_PX
    lam: float = LAMBDA
    he: HEMode = "y"
    clahe_clip: float = CLAHE_CLIP
    clahe_tiles: int | tuple[int, int] = CLAHE_TILES
    he_strength: float = 1.0
    """Share of the equalisation applied: ``I + s (I_HE - I)`` (1 = Eq. 9 as written)."""

    def __post_init__(self) -> None:
        check_range("he_strength", self.he_strength, 0.0, 1.0)
        check_positive("sigma_px", self.sigma_px)
        check_positive("lam", self.lam, allow_zero=True)
        if self.he not in HE_MODES:
            raise ValueError(f"he: expected one of {', '.join(HE_MODES)}, got {self.he!r}")
        check_positive("clahe_clip", self.clahe_clip)
        _tiles(self.clahe_tiles)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        return post_process(image, **self._kwargs())

    def _kwargs(self) -> dict[str, Any]:
        return {
            "sigma_px": self.sigma_px,
            "lam": self.lam,
            "he": self.he,
            "clahe_clip": self.clahe_clip,
            "clahe_tiles": self.clahe_tiles,
            "he_strength": self.he_strength,
        }


TableHook = Callable[[Any], Any]
"""Replaces equalisation tables: numpy (C, 256) -> (C, 256) for one image, torch (B, C, 256) -> (B, C, 256) for a
batch of consecutive images; values are output levels in 0..255 (C = 1 for the luma, 3 for ``he="rgb"``).
:class:`murk.enhance.temporal.FrameEMA` is one: averaged over a video's frames, the tables change gradually (a
mix of monotone tables is monotone, so grey levels never swap order)."""


# ----------------------------------------------------------------------------------------------------------
# Laplacian of Gaussian
# ----------------------------------------------------------------------------------------------------------


def log_kernels(sigma_px: float) -> tuple[np.ndarray, np.ndarray]:
    """1-D kernels ``(g, g2)`` of the separable LoG: sampled Gaussian (sum 1) and its second derivative
    (made zero-sum), radius ``ceil(4 sigma)``, float32. ``LoG = g2 (x) g + g (x) g2``."""
    sigma_px = check_positive("sigma_px", sigma_px)
    r = max(1, math.ceil(4.0 * sigma_px))
    x = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-(x**2) / (2.0 * sigma_px**2))
    g /= g.sum()
    g2 = g * (x**2 - sigma_px**2) / sigma_px**4  # d^2/dx^2 of the Gaussian
    g2 -= g * g2.sum()  # exact zero sum: LoG of a constant is 0
    return g.astype(np.float32), g2.astype(np.float32)


def laplacian_of_gaussian(image: np.ndarray, sigma_px: float = SIGMA_PX) -> np.ndarray:
    """``LoG_sigma * image``, the edge term of Eq. (9), per channel (OpenCV, border reflect-101); (H, W) or
    (H, W, C) float32."""
    if not isinstance(image, np.ndarray):
        raise TypeError(f"image: expected a numpy array, got {type(image).__name__}")
    if image.ndim not in (2, 3):
        raise ShapeError(f"image: expected shape (H, W) or (H, W, C), got {image.shape}")
    g, g2 = log_kernels(sigma_px)
    src = np.ascontiguousarray(image, dtype=np.float32)
    a = cv2.sepFilter2D(src, cv2.CV_32F, g2, g, borderType=cv2.BORDER_REFLECT_101)  # d2/dx2
    b = cv2.sepFilter2D(src, cv2.CV_32F, g, g2, borderType=cv2.BORDER_REFLECT_101)  # d2/dy2
    return cv2.add(a, b, dst=a).reshape(image.shape)


def laplacian_of_gaussian_torch(images: torch.Tensor, sigma_px: float = SIGMA_PX) -> torch.Tensor:
    """Torch twin of :func:`laplacian_of_gaussian` on (B, C, H, W), on the input's device (float32)."""
    _check_batch(images, channels=None)
    g_np, g2_np = log_kernels(sigma_px)
    r = (g_np.size - 1) // 2
    x = images.float()
    b, c, h, w = x.shape
    x = _pad_reflect101(x.reshape(b * c, h, w), r)
    g, g2 = [float(v) for v in g_np], [float(v) for v in g2_np]
    # Row filter first, then column filter, as cv2.sepFilter2D does; taps as shifted slices (fast on CPU and GPU).
    a = _filter_axis(_filter_axis(x, g2, axis=2, n=w), g, axis=1, n=h)  # d2/dx2
    bb = _filter_axis(_filter_axis(x, g, axis=2, n=w), g2, axis=1, n=h)  # d2/dy2
    return (a + bb).reshape(b, c, h, w)


def _filter_axis(x: torch.Tensor, taps: list[float], axis: int, n: int) -> torch.Tensor:
    """Correlate ``x`` with ``taps`` along ``axis`` (valid part, output length ``n``)."""
    out = x.narrow(axis, 0, n) * taps[0]
    for k in range(1, len(taps)):
        out.add_(x.narrow(axis, k, n), alpha=taps[k])
    return out


# ----------------------------------------------------------------------------------------------------------
# Histogram equalisation
# ----------------------------------------------------------------------------------------------------------


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
    y = _luma(x)
    if he == "y":
        (y_he,) = _equalize_channels([y], tables)
    else:
        tiles = _tiles(clahe_tiles)
        clahe = cv2.createCLAHE(clipLimit=check_positive("clahe_clip", clahe_clip), tileGridSize=tiles)
        y_he = clahe.apply(_quantise(y).astype(np.uint8)).astype(np.float32) * _INV255
    y_he -= y  # the luma shift, added to every channel (chroma kept)
    out = cv2.add(x, cv2.merge((y_he, y_he, y_he)))  # the same float32 sum as a broadcast add, 3x faster
    return np.clip(out, 0.0, 1.0, out=out)


def _luma(x: np.ndarray) -> np.ndarray:
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
    luts = np.stack([equalize_lut(_histogram(y255)) for y255 in y255s])
    if tables is not None:
        luts = _checked_tables(tables(luts), luts.shape)
    return [_apply_lut(y255, lut) for y255, lut in zip(y255s, luts, strict=True)]


def _histogram(y255: np.ndarray) -> np.ndarray:
    q = cv2.convertScaleAbs(y255)  # the 8-bit bin of each pixel: round half to even, as np.rint (pinned by tests)
    return cv2.calcHist([q], [0], None, [256], [0, 256]).ravel().astype(np.int64)


def _checked_tables(luts: Any, shape: tuple[int, ...]) -> Any:
    if tuple(luts.shape) != tuple(shape):
        raise ShapeError(f"tables: the hook must return tables of shape {tuple(shape)}, got {tuple(luts.shape)}")
    return luts


def _apply_lut(y255: np.ndarray, lut: np.ndarray) -> np.ndarray:
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
    _check_batch(images, channels=3)
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
        y_he = _clahe_torch(q, check_positive("clahe_clip", clahe_clip), _tiles(clahe_tiles)).float() * _INV255.item()
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
        lut = _checked_tables(tables(lut.reshape(shape)), shape).reshape(n, 256).float()
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
        qp = q.index_select(1, _reflect101_index(h, ty - h % ty, dev)).index_select(
            2, _reflect101_index(w, tx - w % tx, dev)
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


# ----------------------------------------------------------------------------------------------------------
# Eq. (9)
# ----------------------------------------------------------------------------------------------------------


def post_process(
    image: np.ndarray,
    *,
    sigma_px: float = SIGMA_PX,
    lam: float = LAMBDA,
    he: HEMode = "y",
    clahe_clip: float = CLAHE_CLIP,
    clahe_tiles: int | tuple[int, int] = CLAHE_TILES,
    tables: TableHook | None = None,
    he_strength: float = 1.0,
) -> np.ndarray:
    """Post-process one image: histogram equalisation, then LoG edge enhancement. Implements Eq. (9).

    Args:
        image: float RGB (H, W, 3) in [0, 1].
        sigma_px: LoG standard deviation in pixels (paper: 1.0).
        lam: edge-enhancement weight lambda >= 0 (paper: 0.3; 0 gives pure equalisation).
        he: equalisation mode, see :func:`equalize`.
        clahe_clip: CLAHE clip limit (``he="clahe"``).
        clahe_tiles: CLAHE grid (``he="clahe"``).
        tables: replaces the equalisation tables (``he="y"``/``"rgb"``; see :func:`equalize`).
        he_strength: share ``s`` of the equalisation, ``I_HE <- I + s (I_HE - I)`` (1, the paper's: Eq. 9 as
            written; murk's ``real`` preset uses 0.3).

    Returns:
        float32 (H, W, 3) in [0, 1].

    Raises:
        TypeError: ``image`` is not a float numpy array.
        ShapeError: ``image`` is not (H, W, 3).
        ValueError: a parameter is out of range.
    """
    params = PostParams(sigma_px, lam, he, clahe_clip, clahe_tiles, he_strength)
    i_he = equalize(image, params.he, clahe_clip=params.clahe_clip, clahe_tiles=params.clahe_tiles, tables=tables)
    if params.he_strength != 1.0:
        x = np.clip(np.asarray(image, np.float32), 0.0, 1.0)
        i_he = cv2.addWeighted(i_he, params.he_strength, x, 1.0 - params.he_strength, 0.0, dtype=cv2.CV_32F)
    if params.lam == 0.0:
        return i_he
    # Eq. (9): I_HE - lambda (LoG * I_HE), with -lambda folded into the second-derivative taps (one pass each
    # for the two separable terms and two adds; the same sum as the unscaled LoG to float rounding).
    g, g2 = log_kernels(params.sigma_px)
    g2 = g2 * np.float32(-params.lam)
    out = cv2.sepFilter2D(i_he, cv2.CV_32F, g2, g, borderType=cv2.BORDER_REFLECT_101)
    cv2.add(out, cv2.sepFilter2D(i_he, cv2.CV_32F, g, g2, borderType=cv2.BORDER_REFLECT_101), dst=out)
    cv2.add(out, i_he, dst=out)
    return np.clip(out, 0.0, 1.0, out=out)


POST_STRIP_ROWS = 64
"""Rows per strip of :func:`post_process_strips` (plus the LoG's radius above and below)."""


def post_process_strips(
    image: np.ndarray, params: PostParams, tables: TableHook | None = None, out: np.ndarray | None = None
) -> np.ndarray:
    """:func:`post_process` with ``he="y"`` in two passes over the frame: the luma and its histogram, then strip by
    strip (:data:`POST_STRIP_ROWS` rows and the LoG's radius around them, in the cache) the equalisation, the share
    ``he_strength``, the two LoG filters and the clip (every step the same OpenCV operation on the same values, so
    the output equals :func:`post_process`'s to float rounding; pinned by ``tests/enhance/test_post_strips.py``).
    At 1920x1080 a pass over a float32 frame leaves the cache; strips keep the cost per pixel of a 640x480 frame.

    Args:
        image: float32 RGB (H, W, 3).
        params: the parameters; ``params.he`` must be ``"y"``.
        tables: as :func:`post_process`'s.
        out: float32 (H, W, 3) to write into (a new array when None); may not be ``image``.

    Raises:
        ValueError: ``params.he`` is not ``"y"``.
    """
    if params.he != "y":
        raise ValueError(f"params.he: the strip path equalises the luma ('y'), got {params.he!r}")
    image = check_rgb("image", image)
    h = image.shape[0]
    rows = POST_STRIP_ROWS
    y = np.empty(image.shape[:2], np.float32)
    for r0 in range(0, h, rows):  # pass 1: the luma of the clipped frame, and its histogram
        y[r0 : r0 + rows] = _luma(np.clip(image[r0 : r0 + rows], 0.0, 1.0))
    y255 = np.clip(y, 0.0, 1.0)
    y255 *= _F255
    luts = equalize_lut(_histogram(y255))[None]
    if tables is not None:
        luts = _checked_tables(tables(luts), luts.shape)
    lut = luts[0]
    g, g2 = log_kernels(params.sigma_px)
    g2 = g2 * np.float32(-params.lam)
    radius = (g.size - 1) // 2 if params.lam != 0.0 else 0
    s = params.he_strength
    result = np.empty(image.shape, np.float32) if out is None else out
    for r0 in range(0, h, rows):  # pass 2, strip by strip, with the LoG's radius of rows around each
        a0, a1 = max(0, r0 - radius), min(h, r0 + rows + radius)
        x = np.clip(image[a0:a1], 0.0, 1.0)
        y_he = _apply_lut(y255[a0:a1], lut)
        y_he -= y[a0:a1]  # the luma shift, added to every channel (chroma kept)
        i_he = cv2.add(x, cv2.merge((y_he, y_he, y_he)))
        np.clip(i_he, 0.0, 1.0, out=i_he)
        if s != 1.0:
            i_he = cv2.addWeighted(i_he, s, x, 1.0 - s, 0.0, dtype=cv2.CV_32F)
        keep = slice(r0 - a0, r0 - a0 + min(rows, h - r0))
        if params.lam == 0.0:
            result[r0 : r0 + rows] = i_he[keep]
            continue
        res = cv2.sepFilter2D(i_he, cv2.CV_32F, g2, g, borderType=cv2.BORDER_REFLECT_101)  # Eq. (9)
        cv2.add(res, cv2.sepFilter2D(i_he, cv2.CV_32F, g, g2, borderType=cv2.BORDER_REFLECT_101), dst=res)
        cv2.add(res, i_he, dst=res)
        np.clip(res[keep], 0.0, 1.0, out=result[r0 : r0 + rows])
    return result


def post_process_torch(
    images: torch.Tensor,
    *,
    sigma_px: float = SIGMA_PX,
    lam: float = LAMBDA,
    he: HEMode = "y",
    clahe_clip: float = CLAHE_CLIP,
    clahe_tiles: int | tuple[int, int] = CLAHE_TILES,
    tables: TableHook | None = None,
    he_strength: float = 1.0,
) -> torch.Tensor:
    """Torch twin of :func:`post_process` on a batch (B, 3, H, W) in [0, 1], on the input's device.
    Implements Eq. (9)."""
    params = PostParams(sigma_px, lam, he, clahe_clip, clahe_tiles, he_strength)
    i_he = equalize_torch(
        images, params.he, clahe_clip=params.clahe_clip, clahe_tiles=params.clahe_tiles, tables=tables
    )
    if params.he_strength != 1.0:
        s = float(np.float32(params.he_strength))
        i_he = i_he * s + images.float().clamp(0.0, 1.0) * (1.0 - s)
    if params.lam == 0.0:
        return i_he
    return (i_he - float(np.float32(params.lam)) * laplacian_of_gaussian_torch(i_he, params.sigma_px)).clamp(
        0.0, 1.0
    )  # Eq. (9)


# ----------------------------------------------------------------------------------------------------------
# The "post" restorer
# ----------------------------------------------------------------------------------------------------------


class PostRestorer(Restorer):
    """Eq. (9) as a :class:`~murk.enhance.restorer.Restorer`: OpenCV per image on CPU, the torch twin in
    batches on CUDA (and always for :meth:`restore_tensor`). Returns no depth. On the CPU, :meth:`restore` does not
    import torch.

    With ``temporal`` > 0, frames restored inside :meth:`sequence` are equalised with their tables averaged over
    time (:class:`murk.enhance.temporal.FrameEMA`); images restored outside it are each equalised on their own.

    Raises:
        ValueError: ``temporal`` outside [0, 1), or set with ``he="clahe"``.
    """

    name = "post"

    def __init__(
        self, params: PostParams | None = None, device: str | torch.device = "cpu", temporal: float = 0.0
    ) -> None:
        self.params = params or PostParams()
        if not (isinstance(device, str) and device == "cpu"):  # "cpu" keeps the default, built when first read
            import torch

            self.device = torch.device(device)
        ema = FrameEMA(temporal)
        if ema.weight > 0 and self.params.he == "clahe":
            raise ValueError("temporal: applies to he 'y' and 'rgb' (CLAHE has a table per tile)")
        self.temporal_state = ema if ema.weight > 0 else None

    def restore(self, images: np.ndarray) -> Restored:
        batch = _check_numpy_batch(images)
        if device_type(self) != "cpu":
            return super().restore(batch)
        if self.params.he == "y":  # the strip path: the same output, the cost per pixel of a small frame
            out = np.empty(batch.shape, np.float32)
            for i, im in enumerate(batch):
                post_process_strips(im, self.params, self.temporal_hook(), out=out[i])
            return Restored(out)
        kw = self.params._kwargs()
        out = np.stack([post_process(im, **kw, tables=self.temporal_hook()) for im in batch])
        return Restored(out)

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        return RestoredTensor(post_process_torch(images, **self.params._kwargs(), tables=self.temporal_hook()))


def make_post(o: Checked) -> PostRestorer:
    """Implementation of the ``post`` method (declared in :mod:`murk.enhance.methods`): histogram equalisation
    then LoG edge enhancement (see :func:`post_process`), with the settings of ``preset`` (:data:`POST_PRESETS`:
    ``real``, murk's default, or ``paper``, Eq. 9 exactly); any parameter given explicitly overrides the preset's.
    ``temporal`` averages the equalisation tables over the frames of a video (:mod:`murk.enhance.temporal`; 0 = per
    frame, the paper's)."""
    preset = o.preset
    if preset not in POST_PRESETS:
        raise ValueError(f"preset: expected one of {', '.join(POST_PRESETS)}, got {preset!r}")
    base = POST_PRESETS[preset]
    given = {k: o[k] for k in ("sigma_px", "lam", "he", "clahe_clip", "clahe_tiles", "he_strength")}
    params = dataclasses.replace(base, **{k: v for k, v in given.items() if v is not None})
    return PostRestorer(params, device=o.device, temporal=o.temporal)


# ----------------------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------------------


def _tiles(tiles: Any) -> tuple[int, int]:
    if isinstance(tiles, bool):
        raise TypeError(f"clahe_tiles: expected an int or a (columns, rows) pair, got {tiles!r}")
    if isinstance(tiles, (int, np.integer)):
        tiles = (int(tiles), int(tiles))
    try:
        tx, ty = (int(t) for t in tiles)
    except (TypeError, ValueError):
        raise TypeError(f"clahe_tiles: expected an int or a (columns, rows) pair, got {tiles!r}") from None
    if tx < 1 or ty < 1:
        raise ValueError(f"clahe_tiles: expected tiles >= 1, got {(tx, ty)}")
    return tx, ty


def _reflect101_index(n: int, pad_after: int, device: torch.device, pad_before: int = 0) -> torch.Tensor:
    """Source indices of a reflect-101 extension of an axis of length n (any pad size, like OpenCV)."""
    import torch

    i = torch.arange(-pad_before, n + pad_after, device=device)
    if n == 1:
        return torch.zeros_like(i)
    period = 2 * (n - 1)
    i = torch.remainder(i, period)
    return torch.where(i < n, i, period - i)


def _pad_reflect101(x: torch.Tensor, r: int) -> torch.Tensor:
    import torch.nn.functional as F

    h, w = x.shape[-2:]
    if h > r and w > r:
        return F.pad(x, (r, r, r, r), mode="reflect")
    return x.index_select(-2, _reflect101_index(h, r, x.device, r)).index_select(
        -1, _reflect101_index(w, r, x.device, r)
    )


def _check_batch(images: Any, channels: int | None) -> None:
    import torch

    if not isinstance(images, torch.Tensor):
        raise TypeError(f"images: expected a torch tensor (B, C, H, W), got {type(images).__name__}")
    if images.ndim != 4 or (channels is not None and images.shape[1] != channels):
        want = f"(B, {channels}, H, W)" if channels else "(B, C, H, W)"
        raise ShapeError(f"images: expected shape {want}, got {tuple(images.shape)}")
    if not images.is_floating_point():
        raise TypeError(f"images: expected a float tensor in [0, 1], got dtype {images.dtype}")


def _check_numpy_batch(images: Any) -> np.ndarray:
    batch = as_batch(images)  # the batch contract of every restorer
    if not np.issubdtype(batch.dtype, np.floating):
        raise TypeError(f"images: expected a float array in [0, 1], got dtype {batch.dtype}")
    return batch.astype(np.float32, copy=False)


POST_PRESETS: dict[str, PostParams] = {
    "paper": PostParams(),
    "real": PostParams(lam=0.1, he_strength=0.3),
}
"""``paper``: Eq. (9) exactly as the paper writes it (full luma equalisation, lambda 0.3). ``real`` (murk's
default): 30 % of the luma equalisation and lambda 0.1, the settings that do not undo a good restoration on
real paired photographs (docs/enhance.md, "post presets": full equalisation after a restorer lost 1.9 dB on
the development set)."""
