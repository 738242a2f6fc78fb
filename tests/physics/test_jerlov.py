from __future__ import annotations

import math

import numpy as np
import pytest

from murk.physics.jerlov import (
    RESIDUAL_RATIO,
    WATER_TYPES,
    beta_per_m,
    parse_water_types,
    residual_ratio,
    visible_range_m,
)

# N_c table of docs/spec/synthesis.md (Li et al. 2020 / Berman et al. 2021), R, G, B.
SPEC_TABLE = {
    "I": (0.85, 0.961, 0.982),
    "IA": (0.84, 0.955, 0.975),
    "IB": (0.83, 0.95, 0.968),
    "II": (0.80, 0.925, 0.94),
    "III": (0.75, 0.885, 0.89),
    "1C": (0.75, 0.885, 0.875),
    "3C": (0.71, 0.82, 0.80),
    "5C": (0.67, 0.73, 0.67),
    "7C": (0.62, 0.61, 0.50),
    "9C": (0.55, 0.46, 0.29),
}


def test_table_is_the_spec_and_has_ten_types() -> None:
    assert WATER_TYPES == tuple(SPEC_TABLE)
    assert RESIDUAL_RATIO == SPEC_TABLE
    assert RESIDUAL_RATIO["I"][0] == 0.85  # not the UWCNN paper's 0.805 typo


@pytest.mark.parametrize("wt", list(SPEC_TABLE))
def test_beta_is_minus_log_n(wt: str) -> None:
    np.testing.assert_allclose(beta_per_m(wt), [-math.log(n) for n in SPEC_TABLE[wt]], rtol=0, atol=1e-15)
    # one metre of water keeps exactly N_c
    np.testing.assert_allclose(np.exp(-beta_per_m(wt)), residual_ratio(wt), rtol=1e-14)


def test_visible_range() -> None:
    assert visible_range_m("I") == 15.0  # capped: clear ocean water
    # 9C: red is the least attenuated channel (N = 0.55): -ln(0.02) / -ln(0.55)
    assert visible_range_m("9C") == pytest.approx(math.log(0.02) / math.log(0.55))
    assert visible_range_m("9C") < visible_range_m("5C") < visible_range_m("III")
    with pytest.raises(ValueError, match="floor: expected a fraction"):
        visible_range_m("I", floor=1.5)


def test_parse_water_types() -> None:
    assert parse_water_types("all") == WATER_TYPES
    assert parse_water_types("i, ia,3,9C,3C") == ("I", "IA", "3C", "9C")
    with pytest.raises(ValueError, match="unknown type 'IV'"):
        parse_water_types("I,IV")
    with pytest.raises(ValueError, match="at least one type"):
        parse_water_types(" , ")
    with pytest.raises(ValueError, match="water_type: expected one of"):
        beta_per_m("2C")
