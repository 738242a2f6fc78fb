"""Procedural construction-site scenes as a training source (``data.source: scenes``).

Scene ``i`` is ``sample_scene(derive_seed(seed, i))``, the same scene as number ``i`` of
``murk scenes OUT --seed seed``; it is rendered (numpy, in DataLoader workers) at a 4:3 size that covers the
training crop, then centre-cropped. With a scale range (``data.scene_scale``) it is rendered ``s`` times larger
and a crop-sized window is cut at a position fixed per scene (:func:`scene_window`). Its water comes from the
online degradation, fresh every epoch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from murk.rng import derive_seed


def render_size(crop_hw: tuple[int, int]) -> tuple[int, int]:
    """(width, height) of the 4:3 render that covers ``crop_hw`` (the scene layout assumes 4:3)."""
    h, w = crop_hw
    if h * 4 >= w * 3:
        return math.ceil(h * 4 / 3), h
    return w, math.ceil(w * 3 / 4)


def scene_window(
    seed: int, index: int, crop_hw: tuple[int, int], scale: tuple[float, float]
) -> tuple[tuple[int, int], tuple[int, int]]:
    """Render size ``(width, height)`` and window origin ``(y0, x0)`` of scene ``index``: ``s`` uniform in
    ``scale`` from ``derive_seed(seed, index, "scale")`` times :func:`render_size`, origin uniform over the valid
    positions from the same generator. ``scale == (1, 1)`` gives the centre crop of the covering render."""
    w, h = render_size(crop_hw)
    th, tw = crop_hw
    if scale == (1.0, 1.0):
        return (w, h), ((h - th) // 2, (w - tw) // 2)
    return random_window(np.random.default_rng(derive_seed(seed, index, "scale")), (w, h), crop_hw, scale)


def random_window(
    rng: np.random.Generator, cover_wh: tuple[float, float], crop_hw: tuple[int, int], scale: tuple[float, float]
) -> tuple[tuple[int, int], tuple[int, int]]:
    """An image of size ``cover_wh`` (width, height: one that just covers ``crop_hw``) scaled by ``s`` uniform in
    ``scale``, and a crop-sized window in it: ``((width, height), (y0, x0))``, drawn from ``rng`` (``s`` first, then
    the origin, uniform over the valid positions)."""
    w, h = cover_wh
    th, tw = crop_hw
    s = float(rng.uniform(*scale))
    w_s, h_s = max(tw, round(w * s)), max(th, round(h * s))
    return (w_s, h_s), (int(rng.integers(0, h_s - th + 1)), int(rng.integers(0, w_s - tw + 1)))


def scale_saturation(rgb: np.ndarray, factor: float) -> np.ndarray:
    """``clip(Y + factor * (rgb - Y), 0, 1)`` with ``Y`` the BT.601 luma: saturation scaled, luma kept (until a
    channel clips). float32 (H, W, 3) in [0, 1]."""
    y = rgb @ np.asarray([0.299, 0.587, 0.114], np.float32)
    out = y[..., None] + np.float32(factor) * (rgb - y[..., None])
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def scale_contrast(rgb: np.ndarray, factor: float) -> np.ndarray:
    """``clip(m + factor * (rgb - m), 0, 1)`` with ``m`` the image's mean BT.601 luma: every colour moved away
    from the mean grey (luma contrast and chroma both scaled). float32 (H, W, 3) in [0, 1]."""
    m = np.float32(float((rgb @ np.asarray([0.299, 0.587, 0.114], np.float32)).mean()))
    return np.clip(m + np.float32(factor) * (rgb - m), 0.0, 1.0).astype(np.float32)


class SceneDataset(Dataset):
    """Clean RGB + exact distance of procedural scenes: ``clean``, ``depth_filled``, ``depth`` and ``index``."""

    def __init__(
        self,
        indices: Sequence[int],
        crop_hw: tuple[int, int],
        *,
        seed: int,
        config: Any = None,
        cache: bool = False,
        scale: tuple[float, float] = (1.0, 1.0),
        saturation: tuple[float, float] = (1.0, 1.0),
        contrast: tuple[float, float] = (1.0, 1.0),
        balance_pct: float | None = None,
    ) -> None:
        self.indices = list(indices)
        self.crop_hw = crop_hw
        self.scale = scale
        self.saturation = saturation
        self.contrast = contrast
        self.balance_pct = balance_pct
        self.seed = seed
        self.config = config
        self._cache: dict[int, dict[str, Any]] | None = {} if cache else None

    def __len__(self) -> int:
        return len(self.indices)

    def __getitem__(self, i: int) -> dict[str, Any]:
        if self._cache is None:
            return self._render(i)
        if i not in self._cache:
            self._cache[i] = self._render(i)
        return {k: v.clone() if torch.is_tensor(v) else v for k, v in self._cache[i].items()}

    def _render(self, i: int) -> dict[str, Any]:
        from murk.scenes import render_scene, sample_scene

        index = self.indices[i]
        scene = sample_scene(derive_seed(self.seed, index), self.config)
        size_wh, (y0, x0) = scene_window(self.seed, index, self.crop_hw, self.scale)
        rgb, dist = render_scene(scene, size_wh)
        th, tw = self.crop_hw
        rgb = rgb[y0 : y0 + th, x0 : x0 + tw]
        dist = dist[y0 : y0 + th, x0 : x0 + tw, None]
        if self.contrast != (1.0, 1.0):
            c = np.random.default_rng(derive_seed(self.seed, index, "contrast")).uniform(*self.contrast)
            rgb = scale_contrast(rgb, float(c))
        if self.saturation != (1.0, 1.0):
            s = np.random.default_rng(derive_seed(self.seed, index, "saturation")).uniform(*self.saturation)
            rgb = scale_saturation(rgb, float(s))
        if self.balance_pct is not None:
            from murk.restore_ops.balance import color_balance

            rgb = color_balance(rgb, self.balance_pct, self.balance_pct)
        d = torch.from_numpy(np.ascontiguousarray(dist.transpose(2, 0, 1)))
        return {
            "clean": torch.from_numpy(np.ascontiguousarray(rgb.transpose(2, 0, 1))),
            "depth_filled": d,
            "depth": d.clone(),
            "index": self.indices[i],
        }
