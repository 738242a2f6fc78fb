from __future__ import annotations

import numpy as np
import pytest

from murk.snow.bank import ParticleBank, build_bank
from murk.snow.extract import Particle


def make_bank(colour: tuple[int, int, int] = (200, 150, 100), sizes: tuple[int, ...] = (1, 3, 5)) -> ParticleBank:
    """A bank of solid square particles of one colour (size s -> s x s pixels)."""
    parts = []
    for s in sizes:
        mask = np.ones((s, s), bool)
        parts.append(Particle(np.full((s, s, 3), colour, np.uint8), mask, 0, 0))
    return build_bank([({"path": "synthetic"}, parts)])


@pytest.fixture
def solid_bank() -> ParticleBank:
    return make_bank()
