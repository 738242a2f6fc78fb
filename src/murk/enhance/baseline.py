"""What the two comparison baselines' restorers share (``udaformer``, ``ursct``): the input policies, the
torch runner (device, precision, chunks) and validation of their options.

Two input policies (``policy`` option, ``docs/baselines.md``):

- ``native`` (default): any size. The frame is reflect-padded (to a multiple of 8, and for URSCT-SESR to at
  least one tile), run whole or in overlapping tiles blended at the seams as for Joint-ID, cropped back: the
  output has the input's size and every image of a batch is processed on its own (no batch coupling).
- ``official``: what each published test script does (the resize to 256x256, its channel order, its 8-bit
  rounding), and the output stays 256x256, so scores match published ones.
"""

from __future__ import annotations

import contextlib
from typing import Any

import torch
from torch import Tensor, nn

from murk.enhance.choices import DEFAULT_OVERLAP, POLICIES, Policy
from murk.errors import ShapeError

OFFICIAL_SIZE = 256
"""Side of the square the official test scripts resize every image to (and leave the output at)."""
_DTYPES: dict[str, torch.dtype] = {"bf16": torch.bfloat16, "fp16": torch.float16}


def check_policy(policy: Any) -> Policy:
    """Raises ValueError unless ``policy`` is ``"native"`` or ``"official"``."""
    if policy not in POLICIES:
        raise ValueError(f"policy: expected 'native' or 'official', got {policy!r}")
    return policy  # type: ignore[no-any-return]


def check_images(images: Any) -> None:
    """Raises TypeError/ShapeError unless ``images`` is a float (B, 3, H, W) tensor."""
    if not isinstance(images, Tensor) or not images.is_floating_point():
        raise TypeError(f"images: expected a float tensor (B, 3, H, W) in [0, 1], got {type(images).__name__}")
    if images.ndim != 4 or images.shape[1] != 3 or images.shape[0] < 1:
        raise ShapeError(f"images: expected shape (B, 3, H, W), got {tuple(images.shape)}")


class TorchRunner:
    """Runs a network on a device in fp32 or bf16/fp16 autocast, at most ``batch`` images per forward pass,
    under ``torch.inference_mode``; returns float32."""

    def __init__(self, model: nn.Module, device: torch.device, precision: str, batch: int | None) -> None:
        if precision not in ("fp32", "bf16", "fp16"):
            raise ValueError(f"precision: expected 'fp32', 'bf16' or 'fp16', got {precision!r}")
        if batch is not None and (isinstance(batch, bool) or batch < 1):
            raise ValueError(f"batch: expected None or a positive integer, got {batch!r}")
        self.model = model.to(device).eval()
        self.device = device
        self.precision = precision
        self.batch = batch

    def _autocast(self) -> contextlib.AbstractContextManager[Any]:
        if self.precision == "fp32":
            return contextlib.nullcontext()
        return torch.autocast(self.device.type, dtype=_DTYPES[self.precision])

    def __call__(self, x: Tensor) -> Tensor:
        step = self.batch or x.shape[0]
        outs = []
        with torch.inference_mode(), self._autocast():
            for i in range(0, x.shape[0], step):
                outs.append(self.model(x[i : i + step].to(self.device, torch.float32)).float())
        return torch.cat(outs)


def check_tile(tile: Any, multiple: int, what: str) -> int | None:
    """``tile`` as None (0 = None) or a positive multiple of ``multiple``; ValueError otherwise."""
    if tile is None or tile == 0:
        return None
    if isinstance(tile, bool) or not isinstance(tile, int) or tile < multiple or tile % multiple:
        raise ValueError(f"tile: expected None or a positive multiple of {multiple} pixels ({what}), got {tile!r}")
    return tile


def check_overlap(overlap: Any, tile: int | None) -> int:
    """``overlap`` (None = 64) as 0 <= overlap < tile; ValueError otherwise."""
    overlap = DEFAULT_OVERLAP if overlap is None else overlap
    if isinstance(overlap, bool) or not isinstance(overlap, int) or overlap < 0:
        raise ValueError(f"overlap: expected >= 0 pixels, got {overlap!r}")
    if tile is not None and overlap >= tile:
        raise ValueError(f"overlap: expected 0 <= overlap < tile ({tile}), got {overlap}")
    return overlap


def missing_weights_message(method: str, where: str) -> str:
    """The error of a baseline factory called without weights (murk never bundles or downloads them)."""
    return (
        f"checkpoint: {method} needs its weights file, which murk does not bundle or download; get it from {where} "
        f"(docs/baselines.md) and pass --method {method}:PATH (murk compare) or --checkpoint PATH (murk enhance)"
    )
