"""Restore decoded video frames as they come (8-bit RGB) into 8-bit frames: what ``murk enhance`` on a video and
``murk live`` write and show (issue 48).

:func:`restore_frames` gives the same frames as converting to float32 (:func:`murk.io.images.to_float`),
restoring (:func:`murk.enhance.job_common.restore_batch`) and converting back (:func:`to_u8`), within one grey level,
but lets a method take the 8-bit frames itself: a restorer (or the first stage of a chain) with a ``restore_u8``
method (``lite``: :mod:`murk.enhance.lite_u8`) restores them without float32 copies of the frame, and the stages
after it take its float32 output as in a chain. A method without one, on CUDA, or a frame it declines, takes the
float32 path.
"""

from __future__ import annotations

import sys
from typing import Any

import numpy as np

from murk.enhance.job_common import restore_batch
from murk.enhance.restorer import Restored, Restorer, device_type
from murk.io.images import to_float

ALONE_MIN_PX = 1280 * 720 + 1
"""Smallest frame (pixels) a method alone takes by its 8-bit path. That path uses less CPU per frame but runs on one
thread, where the float32 path's torch steps use both. Measured file to file on the idle 2-core box (BENCHMARKS.md,
"HD in real time", 2026-12-06, 05:18 and 05:22 UTC, against the previous tree in the same runs): `lite` alone at
640x480 96.7 frames/s by the 8-bit path against 107.2 for the previous tree, then 103.7 by the float32 path against
96.2 (runs spread by about 10 %); at 1280x720 37.0 and 36.5, no difference between the paths; at 1920x1080 the 8-bit
path 22.3-23.5 against 20.0-20.7. A chain (``lite+post``) takes it at every size, and so does a method alone when
torch runs one thread per call (:func:`alone_takes_u8`: ``murk enhance`` restoring two frames of a video at once,
:mod:`murk.enhance.frame_overlap`)."""


def alone_takes_u8(pixels: int) -> bool:
    """Whether a method alone (not a chain) takes its 8-bit path for frames of ``pixels`` pixels: from
    :data:`ALONE_MIN_PX` up, or at any size when torch runs one thread per call (then the float32 path's torch
    steps have no second thread either, and the 8-bit path costs less CPU)."""
    torch = sys.modules.get("torch")
    return pixels >= ALONE_MIN_PX or (torch is not None and torch.get_num_threads() == 1)


def restore_frames(restorer: Restorer, frames: np.ndarray) -> Restored:
    """Restore a batch of RGB frames (B, H, W, 3), uint8 (or uint16: the float32 path), into uint8 frames
    (``Restored.images`` uint8; ``depth_m`` and ``facts`` as the method gives them).

    Raises:
        what :func:`murk.enhance.job_common.restore_batch` raises.
    """
    if frames.dtype == np.uint8 and device_type(restorer) == "cpu":
        stages: list[Any] = list(getattr(restorer, "stages", [restorer]))
        if all(device_type(s) == "cpu" for s in stages):
            fast = getattr(stages[0], "restore_u8", None)
            alone = len(stages) == 1
            if alone and not alone_takes_u8(frames.shape[1] * frames.shape[2]):
                fast = None  # the float32 path is faster here (ALONE_MIN_PX)
            first = None if fast is None else fast(frames, np.uint8 if alone else np.float32)
            if first is not None:
                if alone:
                    return Restored(first)
                images, depth, facts = first, None, None
                for stage in stages[1:]:  # the rest of the chain, as Chain.restore runs it
                    out = stage.restore(images)
                    images, depth = out.images, out.depth_m if out.depth_m is not None else depth
                    facts = out.facts if out.facts is not None else facts
                return Restored(to_u8(images), depth, facts)
    result = restore_batch(restorer, to_float(frames))
    return Restored(to_u8(result.images), result.depth_m, result.facts)


def to_u8(images: np.ndarray) -> np.ndarray:
    """float images in [0, 1] (any shape) -> uint8: :func:`murk.io.images.to_uint` (clip, times 255, plus 0.5,
    truncated: the same bytes), a cache-sized chunk at a time instead of three frame-sized temporaries."""
    x = np.ascontiguousarray(images, dtype=np.float32)
    flat, out = x.reshape(-1), np.empty(x.size, np.uint8)
    tmp = np.empty(min(_CHUNK, flat.size), np.float32)
    for i in range(0, flat.size, _CHUNK):
        chunk = flat[i : i + _CHUNK]
        t = tmp[: chunk.size]
        np.clip(chunk, 0.0, 1.0, out=t)
        t *= np.float32(255.0)
        t += np.float32(0.5)
        np.copyto(out[i : i + _CHUNK], t, casting="unsafe")  # truncation, as astype
    return out.reshape(x.shape)


_CHUNK = 1 << 16
