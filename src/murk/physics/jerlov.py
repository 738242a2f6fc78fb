"""Jerlov water types: per-metre residual energy ratios and attenuation coefficients.

The ten Jerlov types (open ocean I, IA, IB, II, III; coastal 1C, 3C, 5C, 7C, 9C) with the normalised
residual energy ratios ``N_c`` (fraction of light left after one metre, order R, G, B) used by the common
underwater synthesis code (Li et al., "Underwater scene prior inspired deep underwater image and video
enhancement", Pattern Recognition 98, 2020, doi:10.1016/j.patcog.2019.107038; cross-checked against Berman
et al., "Underwater single image color restoration using haze-lines and a new quantitative dataset",
IEEE TPAMI 43(8), 2021, doi:10.1109/TPAMI.2020.2977624). The UWCNN paper's printed 0.805/0.804 for red of I/IA
is a typo and is not used.

Transmission over a path of ``d`` metres is ``T_c = N_c ** d = exp(-beta_c d)``, so ``beta_c = -ln N_c``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Literal

import numpy as np

WaterType = Literal["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]

RESIDUAL_RATIO: dict[str, tuple[float, float, float]] = {
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
"""Per-metre residual energy ratio N_c (R, G, B) of each Jerlov type."""

WATER_TYPES: tuple[str, ...] = tuple(RESIDUAL_RATIO)
"""All ten types, clearest first."""


def _check_type(water_type: str) -> str:
    if water_type not in RESIDUAL_RATIO:
        raise ValueError(f"water_type: expected one of {', '.join(WATER_TYPES)}, got {water_type!r}")
    return water_type


def residual_ratio(water_type: str) -> np.ndarray:
    """N_c of ``water_type`` as float64 (R, G, B)."""
    return np.asarray(RESIDUAL_RATIO[_check_type(water_type)], dtype=np.float64)


def beta_per_m(water_type: str) -> np.ndarray:
    """Attenuation coefficients beta_c = -ln N_c (1/m) of ``water_type``, float64 (R, G, B)."""
    return -np.log(residual_ratio(water_type))


def visible_range_m(water_type: str, *, floor: float = 0.02, cap_m: float = 15.0) -> float:
    """Farthest useful line-of-sight distance: ``min(cap_m, -ln(floor) / min_c beta_c)``.

    Beyond it every channel keeps less than ``floor`` of the scene signal (the scene is gone).
    """
    if not 0.0 < floor < 1.0:
        raise ValueError(f"floor: expected a fraction in (0, 1), got {floor}")
    return float(min(cap_m, -math.log(floor) / float(beta_per_m(water_type).min())))


def parse_water_types(spec: str | Iterable[str]) -> tuple[str, ...]:
    """Parse ``"all"`` or a comma list like ``"I,IA,3C"`` (or an iterable of names) into type names.

    Coastal types may be written with or without the ``C`` (``"3"`` = ``"3C"``); case is ignored.
    """
    items = spec.split(",") if isinstance(spec, str) else list(spec)
    names = [str(s).strip().upper() for s in items if str(s).strip()]
    if names == ["ALL"]:
        return WATER_TYPES
    out: list[str] = []
    for n in names:
        n = f"{n}C" if n.isdigit() else n
        if n not in RESIDUAL_RATIO:
            raise ValueError(
                f"water_types: unknown type {n!r}; expected 'all' or a comma list of {','.join(WATER_TYPES)}"
            )
        if n not in out:
            out.append(n)
    if not out:
        raise ValueError("water_types: expected 'all' or at least one type name, got nothing")
    return tuple(out)
