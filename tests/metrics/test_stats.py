"""The shared statistics helper of eval and compare."""

from __future__ import annotations

import math

import numpy as np

from murk.metrics.stats import column_stats


def test_mean_and_population_std_of_the_finite_values():
    s = column_stats([1.0, 2.0, 4.0, math.inf])
    assert (s.n, s.n_finite, s.n_inf) == (4, 3, 1)
    assert s.mean == np.mean([1.0, 2.0, 4.0]) and s.std == np.std([1.0, 2.0, 4.0])  # ddof = 0


def test_no_finite_value_gives_nan():
    s = column_stats([math.inf])
    assert s.n == 1 and s.n_finite == 0 and math.isnan(s.mean) and math.isnan(s.std)
    assert column_stats([]).n == 0
