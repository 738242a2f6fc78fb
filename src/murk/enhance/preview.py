"""Visual previews of restoration outputs: coloured depth maps and input|output panels.

Depth previews use a fixed range (:data:`DEPTH_PREVIEW_RANGE_M`, 0-15 m, Joint-ID's maximum depth), never one
inferred from the image, so that colours mean the same distance in every frame of a video and across images.
Near is warm: OpenCV's perceptually uniform ``INFERNO`` map runs from pale yellow (0 m) to black (15 m and
beyond); invalid pixels (0, negative, NaN, inf) are mid grey.
"""

from __future__ import annotations

import cv2
import numpy as np

from murk._checks import check_interval, check_map
from murk.errors import ShapeError

DEPTH_PREVIEW_RANGE_M: tuple[float, float] = (0.0, 15.0)
"""Depth range mapped onto the colormap: near end (warm) to far end (dark)."""
INVALID_GREY = 0.5


def colorize_depth(depth_m: np.ndarray, range_m: tuple[float, float] = DEPTH_PREVIEW_RANGE_M) -> np.ndarray:
    """Colour a metric depth map for display: float32 RGB (H, W, 3) in [0, 1], near = warm.

    Args:
        depth_m: depth in metres (H, W).
        range_m: (near, far) in metres mapped onto the colormap; depths outside are clipped.

    Raises:
        ValueError: ``range_m`` is not 0 <= near < far.
    """
    depth_m = check_map("depth_m", depth_m)
    near, far = check_interval("range_m", range_m, 0.0, float("inf"))
    if not far > near:
        raise ValueError(f"range_m: expected near < far, got ({near}, {far})")
    valid = np.isfinite(depth_m) & (depth_m > 0)
    t = np.clip((np.where(valid, depth_m, far) - near) / (far - near), 0.0, 1.0)
    u8 = np.rint((1.0 - t) * 255.0).astype(np.uint8)  # near -> 255 -> warm end
    rgb = cv2.applyColorMap(u8, cv2.COLORMAP_INFERNO)[:, :, ::-1].astype(np.float32) / np.float32(255.0)
    rgb[~valid] = INVALID_GREY
    return np.ascontiguousarray(rgb)


def side_by_side(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Panel ``left | right`` (same dtype); ``left`` is resized to ``right``'s size when they differ."""
    if left.ndim != 3 or right.ndim != 3 or left.shape[2] != right.shape[2]:
        raise ShapeError(f"left, right: expected (H, W, C) images, got {left.shape} and {right.shape}")
    if left.shape[:2] != right.shape[:2]:
        left = cv2.resize(left, (right.shape[1], right.shape[0]), interpolation=cv2.INTER_AREA)
    return np.concatenate([left.astype(right.dtype, copy=False), right], axis=1)
