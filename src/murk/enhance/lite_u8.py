"""``lite`` on 8-bit frames on the CPU: the restorer's steps fused into two passes over the frame (issue 48).

The general path (:meth:`murk.enhance.lite_restorer.LiteRestorer.restore_tensor`) converts a decoded frame to
float32, balances it, area-downsamples it with torch, upsamples the network's 12 coefficient maps to full
resolution (4 frame-sized float32 maps of 3 channels), applies them and clamps, and the caller converts the result
back to 8 bits: at 1920x1080 that is about 15 passes over a float32 frame. This path computes the same output from
a uint8 frame in two passes:

1. the balance (``input_balance_pct``, :mod:`murk.restore_ops.balance`) as a 256-entry float32 table per channel
   (the same float32 operations as :func:`~murk.restore_ops.balance.apply_levels` on the 256 possible values, so the
   balanced frame is bit for bit the general path's), looked up by ``cv2.LUT`` (8 bits in, float32 out), and the
   working image pooled from it with the windows of torch's ``area`` interpolation (:func:`area_pool`);
2. after the network: in strips of rows, the coefficient maps interpolated vertically between two rows of maps
   already upsampled horizontally (OpenCV's bilinear coefficients, as the general path's ``cv2.resize``), the
   guide's luma, ``gain * x + offset``, the clamp and the conversion to 8 bits (or float32 for a chain), each
   strip small enough to stay in the cache.

Outputs equal the general path's within float rounding of the maps (below 1e-5 on real photographs; converted
to 8 bits as :func:`murk.io.images.to_uint` does, a pixel a few thousandths of a grey level from a rounding tie may
come out one grey level apart; pinned by ``tests/enhance/test_lite_u8.py``). Frames that the network sees at their own
resolution (at most ``work_area_px`` pixels), ONNX runners, CUDA and ``refine`` keep the general path.
"""

from __future__ import annotations

import cv2
import numpy as np
import torch

from murk.io.images import to_float
from murk.models.lite.network import LUMA, work_size
from murk.restore_ops.balance import apply_levels, sample_levels, sample_of

STRIP_ROWS = 32
"""Rows per strip of the apply pass (at 1920x1080 with 1 thread: 4 rows 29 ms, 8 rows 23.5, 16 rows 22.1,
32 rows 21.2 ms of CPU per frame, the whole restoration; bands between two rows of maps are about 38 rows)."""

_RAMP = (np.arange(256, dtype=np.float32) / np.float32(255.0)).reshape(1, 256, 1)
"""The 256 values of :func:`murk.io.images.to_float` of an 8-bit channel."""
_LUMA3 = np.array([LUMA] * 3, np.float32)


def balance_table(levels: np.ndarray | None) -> np.ndarray:
    """The float32 value (1, 256, 3) of each 8-bit level of each channel after ``to_float`` and, when ``levels``
    (2, 3) is given, :func:`~murk.restore_ops.balance.apply_levels` (the same float32 operations, so looking a frame
    up in it is bit for bit the general path)."""
    ramp = np.repeat(_RAMP, 3, axis=2)
    return ramp if levels is None else apply_levels(ramp, levels)


def frame_levels(frame_u8: np.ndarray, pct: float) -> np.ndarray:
    """:func:`~murk.restore_ops.balance.balance_levels` of ``to_float(frame_u8)`` (float32 (2, 3)), from the frame's
    8-bit sample (only the sampled pixels are converted; the same values, so the same levels)."""
    return sample_levels(to_float(np.ascontiguousarray(sample_of(frame_u8))), pct, pct)


def _windows(n: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) of the ``m`` windows of torch's adaptive average pooling over ``n`` samples."""
    i = np.arange(m)
    return (i * n) // m, -((-(i + 1) * n) // m)


def area_pool(frame_u8: np.ndarray, table: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """``F.interpolate(x, size, mode="area")`` of ``x = cv2.LUT(frame_u8, table)`` (float32 (H, W, 3)) to ``size``
    = (h, w) <= (H, W), without ``x`` in memory: the mean over torch's adaptive-pooling windows (start
    ``floor(i n / m)``, end ``ceil((i + 1) n / m)``; neighbours may share a row or column), the rows of each window
    looked up and summed (``cv2.reduce``) while they are in the cache, then the columns; equal to torch's to float
    rounding."""
    h, w = size
    (rs, re), (cs, ce) = _windows(frame_u8.shape[0], h), _windows(frame_u8.shape[1], w)
    width = frame_u8.shape[1] * 3
    rows = np.empty((h, width), np.float32)
    for i in range(h):
        block = cv2.LUT(frame_u8[rs[i] : re[i]], table).reshape(re[i] - rs[i], width)
        cv2.reduce(block, 0, cv2.REDUCE_SUM, dst=rows[i : i + 1])
    rows3 = rows.reshape(h, frame_u8.shape[1], 3)
    sums = np.add.reduceat(rows3, cs, axis=1)  # columns [cs_j, cs_{j+1}); the last to the end
    shared = np.nonzero(ce[:-1] > cs[1:])[0]  # a window that also takes its neighbour's first column
    if shared.size:
        sums[:, shared] += rows3[:, cs[shared + 1]]
    count = ((re - rs)[:, None] * (ce - cs)[None, :]).astype(np.float32)[..., None]
    return np.divide(sums, count, out=sums)


def restore_frame(
    model: torch.nn.Module,
    frame_u8: np.ndarray,
    levels: np.ndarray | None,
    work_area_px: int,
    *,
    out_dtype: type = np.uint8,
    ema: object | None = None,
) -> np.ndarray | None:
    """``lite``'s output for one uint8 RGB frame (H, W, 3) with the balance ``levels`` (None: no balance), as
    uint8 (``out_dtype``) or float32 in [0, 1]; None when the frame is not larger than ``work_area_px`` (the network
    then sees the frame itself: the general path). ``ema``: the restorer's average of the maps over time."""
    h, w = frame_u8.shape[:2]
    size = work_size(h, w, work_area_px)
    if size is None or size[0] > h or size[1] > w:
        return None
    table = balance_table(levels)
    work = torch.from_numpy(area_pool(frame_u8, table, size)).permute(2, 0, 1)[None]  # pass 1
    maps = model.maps(work)  # type: ignore[operator]
    if ema is not None:
        maps = ema(maps)  # type: ignore[operator]
    lo = np.ascontiguousarray(maps[0].permute(1, 2, 0).numpy())  # (hl, wl, 12)
    hl = lo.shape[0]
    # horizontal bilinear to the frame's width (rows unchanged: cv2.resize's coefficients, as the general path's),
    # four groups of 3 channels side by side in each row (a_gain, a_offset, b_gain, b_offset), the last row repeated
    # so that the step from row k to k + 1 exists for every k
    wide = np.stack([cv2.resize(np.ascontiguousarray(lo[:, :, k : k + 3]), (w, hl)) for k in (0, 3, 6, 9)], 1)
    base = torch.from_numpy(np.concatenate([wide, wide[-1:]], 0))  # (hl + 1, 4, w, 3)
    step = base[1:] - base[:-1]
    y0, frac = _vertical(h, hl)
    out: np.ndarray = np.empty((h, w, 3), out_dtype)
    out_t = torch.from_numpy(out)
    rows = min(STRIP_ROWS, h)
    gain, offset, res = (torch.empty((rows, w, 3), dtype=torch.float32) for _ in range(3))
    r0 = 0
    while r0 < h:  # pass 2, strip by strip within a band of rows between the same two rows of maps
        k = int(y0[r0])
        r1 = min(r0 + rows, h, int(np.searchsorted(y0, k, side="right")))
        n = r1 - r0
        m = torch.addcmul(base[k], step[k], torch.from_numpy(frac[r0:r1]).view(n, 1, 1, 1))  # (n, 4, w, 3)
        xb = cv2.LUT(frame_u8[r0:r1], table)  # the balanced rows
        luma = torch.from_numpy(cv2.transform(xb, _LUMA3))  # the guide's luma in each of the 3 channels
        torch.addcmul(m[:, 2], m[:, 0], luma, out=gain[:n])  # coefficients = a * luma + b
        torch.addcmul(m[:, 3], m[:, 1], luma, out=offset[:n])
        if out_dtype == np.uint8:  # to_uint's rounding: times 255, plus 0.5, truncated
            torch.addcmul(offset[:n], gain[:n], torch.from_numpy(xb), out=res[:n]).clamp_(0.0, 1.0)
            out_t[r0:r1].copy_(res[:n].mul_(255.0).add_(0.5))
        else:  # float32 (a chain's next stage): straight into the output's rows
            torch.addcmul(offset[:n], gain[:n], torch.from_numpy(xb), out=out_t[r0:r1]).clamp_(0.0, 1.0)
        r0 = r1
    return out


def _vertical(h: int, hl: int) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``h`` output rows, the upper source row (int64) and the float32 weight of the next one:
    OpenCV's bilinear coordinates ((r + 0.5) hl / h - 0.5, clamped to the first and the last row)."""
    fy = ((np.arange(h) + 0.5) * (hl / h) - 0.5).astype(np.float32)
    y0 = np.floor(fy).astype(np.int64)
    frac = fy - y0.astype(np.float32)
    frac[y0 < 0] = 0.0
    y0 = np.clip(y0, 0, hl - 1)
    frac[y0 >= hl - 1] = 0.0
    return y0, frac.astype(np.float32)
