"""Joint-ID's learning-rate schedule: one warm-up epoch, then cosine annealing, stepped every iteration.

With fractional epoch ``e = (step - 1) / steps_per_epoch`` (step 0 uses the minimum):

- ``e < warmup``: ``lr = min + (base - min) * e / warmup``
- ``warmup <= e < epochs``: ``lr = min + (base - min) * (1 + cos(pi (e - warmup) / (epochs - warmup))) / 2``

The original: base 2e-4, min 2e-6, 1 warm-up epoch, 5 epochs. For 4 steps per epoch the sequence starts
2e-6, 2e-6, 5.15e-5, 1.01e-4, 1.505e-4, 2e-4, 1.981e-4, ... and ends at 9.54e-6.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Schedule:
    """Warm-up + cosine schedule over ``epochs`` of ``steps_per_epoch`` optimiser steps."""

    steps_per_epoch: int
    epochs: float = 5.0
    base_lr: float = 2e-4
    min_lr: float = 2e-6
    warmup_epochs: float = 1.0

    def __post_init__(self) -> None:
        if self.steps_per_epoch < 1:
            raise ValueError(f"steps_per_epoch: expected >= 1, got {self.steps_per_epoch}")
        if not 0 <= self.warmup_epochs < self.epochs:
            raise ValueError(f"warmup_epochs: expected 0 <= warmup < epochs, got {self.warmup_epochs}, {self.epochs}")

    @property
    def total_steps(self) -> int:
        return math.ceil(self.epochs * self.steps_per_epoch)

    def lr(self, step: int) -> float:
        """Learning rate of optimiser step ``step`` (0-based)."""
        if step <= 0:
            return self.min_lr
        e = (step - 1) / self.steps_per_epoch
        span = self.base_lr - self.min_lr
        if e < self.warmup_epochs:
            return self.min_lr + span * e / self.warmup_epochs
        t = min(1.0, (e - self.warmup_epochs) / (self.epochs - self.warmup_epochs))
        return self.min_lr + span * (1.0 + math.cos(math.pi * t)) / 2.0
