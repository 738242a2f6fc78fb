"""Deterministic weights and inputs of the golden forwards (``docs/spec/jointid.md``, "Golden-forward fill
rule"; the same rule for the baselines in ``docs/spec/baselines.md``).

Every golden fixture in ``tests/data`` (Joint-ID, UDAformer, URSCT-SESR) was produced by the official model
with these weights and inputs; matching it proves a re-implementation computes the same function, not only
that the parameter names and shapes agree. The rule fills the *learnable parameters* in sorted-name order
(``k`` = position in that list); buffers (URSCT-SESR's relative-position indices and attention masks) are not
filled, take no index and keep their constructed values. Joint-ID and UDAformer have no buffers, so for them
this is the same as iterating the state dict.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn


def golden_values(key_index: int, shape: tuple[int, ...], key: str) -> np.ndarray:
    """The fill of the parameter number ``key_index`` (in sorted-name order), float64.

    A 32-bit integer hash of (element index, key index) mapped to u in [-1, 1), then scaled: u*sqrt(3/fan_in)
    for tensors with >= 2 dims (fan_in = n // shape[0]), 1 + 0.1u for 1-D tensors whose name ends in
    ``weight``, 0.02u otherwise.
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


def golden_keys(model: nn.Module) -> list[str]:
    """The names the fill rule enumerates: the learnable parameters of ``model``, sorted (k = list position)."""
    return sorted(name for name, _ in model.named_parameters())


@torch.no_grad()
def fill_golden_(model: nn.Module) -> nn.Module:
    """Overwrite every learnable parameter of ``model`` with the golden fill rule (in place); return ``model``.

    Values are computed in float64 and rounded to each parameter's dtype by the copy. Buffers are left as
    they are. The order is the same with or without a common prefix (Joint-ID's official ``structure.``).
    """
    params = dict(model.named_parameters())
    for k, key in enumerate(golden_keys(model)):
        p = params[key]
        p.copy_(torch.from_numpy(golden_values(k, tuple(p.shape), key)).to(p.dtype))
    return model


def golden_param_sum(model: nn.Module) -> float:
    """Sum of every learnable parameter in float64 (the fixtures' ``fill_param_sum_float64`` check)."""
    return float(sum(p.detach().double().sum() for p in model.parameters()))


def golden_input(shape: tuple[int, int, int, int] = (1, 3, 64, 96)) -> torch.Tensor:
    """x[b, c, i, j] = sin(j/7 + c) * cos(i/5 - c), float32 (fed to the network without normalisation)."""
    b, c, h, w = shape
    cc, ii, jj = np.meshgrid(np.arange(c), np.arange(h), np.arange(w), indexing="ij")
    x = np.sin(jj / 7.0 + cc) * np.cos(ii / 5.0 - cc)
    return torch.from_numpy(np.broadcast_to(x[None], (b, c, h, w)).astype(np.float32))
