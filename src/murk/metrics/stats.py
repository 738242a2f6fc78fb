"""The one statistics helper of the reports: mean and population standard deviation of a column of scores over
images, finite values only (PSNR of an exact copy is +inf), with the counts. ``murk eval`` and ``murk compare``
both summarise with it."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ColumnStats:
    """Statistics of one metric column: ``n`` values, ``n_finite`` of them finite; ``mean``/``std`` (population,
    ddof = 0) over the finite ones, NaN when there is none."""

    n: int
    n_finite: int
    mean: float
    std: float

    @property
    def n_inf(self) -> int:
        """Values left out of mean/std (infinite or NaN)."""
        return self.n - self.n_finite


def column_stats(values: Iterable[float]) -> ColumnStats:
    """Mean and population std of the finite ``values`` (float64), with the counts."""
    vals = np.asarray(list(values), dtype=np.float64)
    finite = vals[np.isfinite(vals)]
    if finite.size == 0:
        return ColumnStats(int(vals.size), 0, float("nan"), float("nan"))
    return ColumnStats(int(vals.size), int(finite.size), float(finite.mean()), float(finite.std()))
