"""Clean photographs mixed into the procedural scenes (``data.photos``), degraded online like them.

The procedural scenes are flatter than photographs, so a restorer trained on them alone learns to stretch every
output (issue 46). ``data.photos`` names a folder of clean in-air photographs (RGB-D with ``data.depth_from:
file``, or photographs without depth with ``depth_from: layout``: the ground-plane prior of
:mod:`murk.io.distance_prior`). Each photograph is shown ``repeats`` times per epoch; repeat ``r`` of photograph
``p`` is a window of the training crop's size cut from the photograph resized by ``s`` (uniform in ``scale``) times
the size that just covers the crop, at a position drawn with ``s`` from ``derive_seed(seed, "photo", stem, r)``, so
the repeats show different parts at different sizes and every run sees the same ones. With ``balance_pct`` the
window goes through the simplest colour balance, as the scenes do (``data.scene_balance_pct``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
import torch
from torch.utils.data import ConcatDataset

from murk.io.pairs import DepthOptions, RGBDSource, load_pair
from murk.rng import derive_seed
from murk.train.data import FileDataset, depth_target
from murk.train.scenes_source import random_window

INDEX_OFFSET = 1 << 30
"""Added to a photograph window's sample index, so that its online water (drawn from the index) never repeats a
procedural scene's."""


def photo_window(
    seed: int, stem: str, repeat: int, image_hw: tuple[int, int], crop_hw: tuple[int, int], scale: tuple[float, float]
) -> tuple[tuple[int, int], tuple[int, int]]:
    """Resized size ``(width, height)`` and window origin ``(y0, x0)`` of repeat ``repeat`` of photograph ``stem``
    (``image_hw`` its size): the photograph is resized by ``s`` times the factor that makes it just cover
    ``crop_hw`` (aspect kept), ``s`` uniform in ``scale``."""
    h, w = image_hw
    f = max(crop_hw[0] / h, crop_hw[1] / w)
    rng = np.random.default_rng(derive_seed(seed, "photo", stem, repeat))
    return random_window(rng, (w * f, h * f), crop_hw, scale)


class PhotoDataset(FileDataset):
    """Windows of clean photographs with their distance: ``clean``, ``depth_filled``, ``depth``, ``index`` and
    ``failed`` (an unreadable photograph is replaced as :func:`murk.train.data.first_readable` says). Sample ``i``
    is repeat ``i // n`` of photograph ``i % n`` (``n`` photographs)."""

    def __init__(
        self,
        sources: Sequence[RGBDSource],
        crop_hw: tuple[int, int],
        options: DepthOptions,
        *,
        seed: int,
        repeats: int = 1,
        scale: tuple[float, float] = (1.0, 1.0),
        balance_pct: float | None = None,
        cache: bool = False,
    ) -> None:
        if repeats < 1:
            raise ValueError(f"repeats: expected >= 1, got {repeats}")
        self.sources = list(sources)
        self.entries = [(k, r) for r in range(repeats) for k in range(len(self.sources))]
        self.crop_hw, self.scale, self.balance_pct = crop_hw, scale, balance_pct
        self.options, self.seed = options, seed
        self._cache: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = {} if cache else None

    def _base(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Photograph ``k`` loaded and, when larger, area-resized to the largest size a window needs (the cover
        size times ``scale``'s upper end); kept in memory with ``cache``."""
        if self._cache is not None and k in self._cache:
            return self._cache[k]
        rgb, depth, valid = load_pair(self.sources[k], self.options)
        h, w = depth.shape
        f = self.scale[1] * max(self.crop_hw[0] / h, self.crop_hw[1] / w)
        if f < 1.0:
            size = (max(self.crop_hw[1], round(w * f)), max(self.crop_hw[0], round(h * f)))
            rgb = np.clip(cv2.resize(rgb, size, interpolation=cv2.INTER_AREA), 0.0, 1.0)
            depth = cv2.resize(depth, size, interpolation=cv2.INTER_NEAREST)
            valid = cv2.resize(valid.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
        if self._cache is not None:
            self._cache[k] = (rgb, depth, valid)
        return rgb, depth, valid

    def _load(self, i: int) -> dict[str, Any]:
        k, repeat = self.entries[i]
        rgb, depth, valid = self._base(k)
        stem = self.sources[k].stem
        (w_s, h_s), (y0, x0) = photo_window(self.seed, stem, repeat, depth.shape, self.crop_hw, self.scale)
        interp = cv2.INTER_AREA if w_s < depth.shape[1] else cv2.INTER_CUBIC
        th, tw = self.crop_hw
        rgb = np.clip(cv2.resize(rgb, (w_s, h_s), interpolation=interp), 0.0, 1.0)[y0 : y0 + th, x0 : x0 + tw]
        depth = cv2.resize(depth, (w_s, h_s), interpolation=cv2.INTER_NEAREST)[y0 : y0 + th, x0 : x0 + tw]
        valid = cv2.resize(valid.astype(np.uint8), (w_s, h_s), interpolation=cv2.INTER_NEAREST)[
            y0 : y0 + th, x0 : x0 + tw
        ]
        if self.balance_pct is not None:
            from murk.restore_ops.balance import color_balance

            rgb = color_balance(rgb, self.balance_pct, self.balance_pct)
        gt = depth_target(depth, valid > 0, self.options)
        return {
            "clean": torch.from_numpy(np.ascontiguousarray(rgb.transpose(2, 0, 1), dtype=np.float32)),
            "depth_filled": torch.from_numpy(np.ascontiguousarray(depth[None], dtype=np.float32)),
            "depth": torch.from_numpy(np.ascontiguousarray(gt[None])),
            "index": self._index(i),
        }

    def _index(self, i: int) -> int:
        return INDEX_OFFSET + i


class ScenesAndPhotos(ConcatDataset):
    """Procedural scenes followed by photograph windows, as one training set; every sample carries ``failed``
    (empty for a scene), so that mixed batches collate."""

    def __getitem__(self, i: int) -> dict[str, Any]:
        sample = dict(super().__getitem__(i))
        sample.setdefault("failed", "")
        return sample


def photo_repeats(n_scenes: int, n_photos: int, share: float) -> int:
    """How many times each photograph is shown per epoch so that photographs make about ``share`` of the samples
    beside ``n_scenes`` scenes (at least once)."""
    if not 0.0 < share < 1.0:
        raise ValueError(f"photos_share: expected 0 < share < 1, got {share}")
    return max(1, round(share / (1.0 - share) * n_scenes / max(1, n_photos)))
