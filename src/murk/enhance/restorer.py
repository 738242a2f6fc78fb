"""The restoration interface and the registry of methods by name.

A :class:`Restorer` takes a batch of float32 RGB images in [0, 1] and returns the enhanced batch, plus metric
depth when the method estimates it (Joint-ID does). Methods are registered by name (``post``, ``jointid``,
...); a spec ``"a+b"`` chains them left to right (``jointid+post`` = Joint-ID, then Eq. (9) on its output),
and the depth of the chain is the last depth any stage produced.

Two entry points per restorer:

- :meth:`Restorer.restore` on numpy batches (B, H, W, 3), what file/video pipelines use;
- :meth:`Restorer.restore_tensor` on torch batches (B, 3, H, W) on the restorer's device, so that chains on a
  GPU never leave the device. The default implementation of each one goes through the other, so a subclass
  overrides at least one of them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch


@dataclass(frozen=True)
class Restored:
    """A restored numpy batch: ``images`` (B, H, W, 3) float32 in [0, 1]; ``depth_m`` (B, H, W) or None."""

    images: np.ndarray
    depth_m: np.ndarray | None = None


@dataclass(frozen=True)
class RestoredTensor:
    """A restored torch batch: ``images`` (B, 3, H, W) in [0, 1]; ``depth_m`` (B, 1, H, W) or None."""

    images: torch.Tensor
    depth_m: torch.Tensor | None = None


class Restorer:
    """Base class of restoration methods. Subclasses set ``name`` and override ``restore`` and/or
    ``restore_tensor``; ``device`` is where the tensor path runs."""

    name: str = "restorer"
    device: torch.device = torch.device("cpu")

    def restore(self, images: np.ndarray) -> Restored:
        """Restore a numpy batch (B, H, W, 3) float32 in [0, 1]."""
        if type(self).restore_tensor is Restorer.restore_tensor:
            raise NotImplementedError(f"{type(self).__name__} implements neither restore nor restore_tensor")
        x = torch.from_numpy(np.ascontiguousarray(images)).permute(0, 3, 1, 2).to(self.device, torch.float32)
        out = self.restore_tensor(x)
        imgs = out.images.detach().float().permute(0, 2, 3, 1).cpu().numpy()
        depth = None if out.depth_m is None else out.depth_m.detach().float()[:, 0].cpu().numpy()
        return Restored(np.ascontiguousarray(imgs), depth)

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        """Restore a torch batch (B, 3, H, W) in [0, 1] on ``self.device``."""
        if type(self).restore is Restorer.restore:
            raise NotImplementedError(f"{type(self).__name__} implements neither restore nor restore_tensor")
        out = self.restore(images.detach().float().permute(0, 2, 3, 1).cpu().numpy())
        imgs = torch.from_numpy(out.images).permute(0, 3, 1, 2).to(images.device)
        depth = None if out.depth_m is None else torch.from_numpy(out.depth_m)[:, None].to(images.device)
        return RestoredTensor(imgs, depth)

    def __call__(self, images: np.ndarray) -> Restored:
        return self.restore(images)


class Chain(Restorer):
    """Stages applied left to right; keeps the last depth any stage produced."""

    def __init__(self, stages: list[Restorer]) -> None:
        if not stages:
            raise ValueError("stages: expected at least one restorer")
        self.stages = stages
        self.name = "+".join(s.name for s in stages)
        self.device = stages[0].device

    def restore(self, images: np.ndarray) -> Restored:
        depth = None
        for stage in self.stages:
            out = stage.restore(images)
            images, depth = out.images, out.depth_m if out.depth_m is not None else depth
        return Restored(images, depth)

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        depth = None
        for stage in self.stages:
            out = stage.restore_tensor(images.to(stage.device))
            images, depth = out.images, out.depth_m if out.depth_m is not None else depth
        return RestoredTensor(images, depth)


Factory = Callable[..., Restorer]
_REGISTRY: dict[str, Factory] = {}


def register(name: str) -> Callable[[Factory], Factory]:
    """Decorator registering a factory ``f(**options) -> Restorer`` under ``name`` (no ``+`` allowed)."""
    if not name or "+" in name:
        raise ValueError(f"name: expected a non-empty name without '+', got {name!r}")

    def deco(factory: Factory) -> Factory:
        _REGISTRY[name] = factory
        return factory

    return deco


def available() -> list[str]:
    """Names of the registered methods."""
    _load_builtin()
    return sorted(_REGISTRY)


def weights_of(restorer: Any) -> str | None:
    """The weights file a restorer (or any stage of a chain) loaded, e.g. the shipped Joint-ID when no checkpoint
    was given; None for methods without weights."""
    for stage in getattr(restorer, "stages", [restorer]):
        if getattr(stage, "weights", None):
            return str(stage.weights)
    return None


def create(spec: str, **options: Any) -> Restorer:
    """Build the restorer for ``spec`` (``"post"``, ``"jointid"``, ``"jointid+post"``, ...).

    Every stage receives ``options``; each factory picks what it understands and ignores the rest.

    Raises:
        ValueError: an unknown method name (the known ones are listed).
    """
    _load_builtin()
    names = [n.strip() for n in spec.split("+")]
    unknown = [n for n in names if n not in _REGISTRY]
    if unknown or not all(names):
        raise ValueError(
            f"method: unknown {', '.join(repr(n) for n in unknown) or repr(spec)}; "
            f"available: {', '.join(sorted(_REGISTRY))} (chain them with '+')"
        )
    stages = [_REGISTRY[n](**options) for n in names]
    return stages[0] if len(stages) == 1 else Chain(stages)


def _load_builtin() -> None:
    """Import the modules that register the built-in methods (kept lazy: some pull in large models)."""
    import importlib

    for module in _BUILTIN_MODULES:
        importlib.import_module(module)


_BUILTIN_MODULES: list[str] = [
    "murk.enhance.post",
    "murk.enhance.jointid_restorer",
    "murk.enhance.lite_restorer",
    "murk.enhance.udaformer_restorer",
    "murk.enhance.ursct_restorer",
]
"""Modules whose import registers built-in methods (imported on first use of the registry)."""
