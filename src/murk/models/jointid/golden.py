"""Deterministic weights and input of the golden forward (``docs/spec/jointid.md``, "Golden-forward fill rule").

With these, the official model produced ``tests/data/jointid_golden_forward.json``; matching it proves the
re-implementation computes the same function, not only that the parameter names and shapes agree.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn

GOLDEN_INPUT_SHAPE = (1, 3, 64, 96)


def golden_values(key_index: int, shape: tuple[int, ...], key: str) -> np.ndarray:
    """The fill of the state-dict tensor number ``key_index`` (in sorted key order), float64.

    A 32-bit integer hash of (element index, key index) mapped to u in [-1, 1), then scaled: u*sqrt(3/fan_in)
    for tensors with >= 2 dims (fan_in = n // shape[0]), 1 + 0.1u for 1-D weights, 0.02u otherwise.
    """
    n = math.prod(shape)
    i = np.arange(n, dtype=np.uint64)
    m = np.uint64(0xFFFFFFFF)
    h = (i * np.uint64(0x9E3779B1) + np.uint64((key_index + 1) * 0x85EBCA77)) & m
    h ^= h >> np.uint64(15)
    h = (h * np.uint64(0x2C1B3C6D)) & m
    h ^= h >> np.uint64(12)
    h = (h * np.uint64(0x297A2D39)) & m
    h ^= h >> np.uint64(15)
    u = h.astype(np.float64) / 2.0**32 * 2.0 - 1.0
    if len(shape) >= 2:
        v = u * math.sqrt(3.0 / (n // shape[0]))
    elif key.endswith("weight"):
        v = 1.0 + 0.1 * u
    else:
        v = 0.02 * u
    return v.reshape(shape)


@torch.no_grad()
def fill_golden_(model: nn.Module) -> nn.Module:
    """Overwrite every state-dict tensor of ``model`` with the golden fill rule (in place); return ``model``.

    Keys are taken in sorted order; the order is the same with or without the official ``structure.``
    prefix, since every key carries it.
    """
    state = model.state_dict()
    for k, key in enumerate(sorted(state)):
        t = state[key]
        t.copy_(torch.from_numpy(golden_values(k, tuple(t.shape), key)).to(t.dtype))
    return model


def golden_input() -> torch.Tensor:
    """x[0, c, i, j] = sin(j/7 + c) * cos(i/5 - c), shape (1, 3, 64, 96), float32 (fed without normalisation)."""
    _, c, h, w = GOLDEN_INPUT_SHAPE
    cc, ii, jj = np.meshgrid(np.arange(c), np.arange(h), np.arange(w), indexing="ij")
    x = np.sin(jj / 7.0 + cc) * np.cos(ii / 5.0 - cc)
    return torch.from_numpy(x[None].astype(np.float32))
