"""Deterministic weights and input of Joint-ID's golden forward (``docs/spec/jointid.md``, "Golden-forward fill
rule").

With these, the official model produced ``tests/data/jointid_golden_forward.json``; matching it proves the
re-implementation computes the same function, not only that the parameter names and shapes agree. The rule
itself lives in :mod:`murk.models.golden`, shared with the baselines (UDAformer, URSCT-SESR).
"""

from __future__ import annotations

import torch

from murk.models.golden import fill_golden_, golden_values
from murk.models.golden import golden_input as _golden_input

GOLDEN_INPUT_SHAPE = (1, 3, 64, 96)

__all__ = ["GOLDEN_INPUT_SHAPE", "fill_golden_", "golden_input", "golden_values"]


def golden_input() -> torch.Tensor:
    """x[0, c, i, j] = sin(j/7 + c) * cos(i/5 - c), shape (1, 3, 64, 96), float32 (fed without normalisation)."""
    return _golden_input(GOLDEN_INPUT_SHAPE)
