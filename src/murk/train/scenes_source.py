"""Procedural construction-site scenes as a training source (``data.source: scenes``).

Scene ``i`` is ``sample_scene(derive_seed(seed, i))``, the same scene as number ``i`` of
``murk scenes OUT --seed seed``; it is rendered (numpy, in DataLoader workers) at a 4:3 size that covers the
training crop, then centre-cropped. Its water comes from the online degradation, fresh every epoch.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from murk.rng import derive_seed
from murk.train.augment import centre_crop


def render_size(crop_hw: tuple[int, int]) -> tuple[int, int]:
    """(width, height) of the 4:3 render that covers ``crop_hw`` (the scene layout assumes 4:3)."""
    h, w = crop_hw
    if h * 4 >= w * 3:
        return math.ceil(h * 4 / 3), h
    return w, math.ceil(w * 3 / 4)


class SceneDataset(Dataset):
    """Clean RGB + exact distance of procedural scenes: ``clean``, ``depth_filled``, ``depth`` and ``index``."""

    def __init__(
        self, indices: Sequence[int], crop_hw: tuple[int, int], *, seed: int, config: Any = None, cache: bool = False
    ) -> None:
        self.indices = list(indices)
        self.crop_hw = crop_hw
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

        scene = sample_scene(derive_seed(self.seed, self.indices[i]), self.config)
        rgb, dist = render_scene(scene, render_size(self.crop_hw))
        rgb, dist = centre_crop([rgb, dist[:, :, None]], self.crop_hw, source=f"scene {self.indices[i]}")
        d = torch.from_numpy(np.ascontiguousarray(dist.transpose(2, 0, 1)))
        return {
            "clean": torch.from_numpy(np.ascontiguousarray(rgb.transpose(2, 0, 1))),
            "depth_filled": d,
            "depth": d.clone(),
            "index": self.indices[i],
        }
