"""CIEDE2000 (murk.metrics.ciede2000) and its column in murk eval --ref."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.errors import ShapeError
from murk.metrics import ciede2000, table
from murk.report.evaluate import evaluate


def _lstar(srgb: float) -> float:
    """CIE L* of a neutral sRGB value (IEC 61966-2-1 decoding, CIE 1976 lightness), written out here."""
    lin = srgb / 12.92 if srgb <= 0.04045 else ((srgb + 0.055) / 1.055) ** 2.4
    f = lin ** (1 / 3) if lin > (6 / 29) ** 3 else lin / (3 * (6 / 29) ** 2) + 4 / 29
    return 116 * f - 16


def test_neutral_greys_differ_by_the_lightness_term_alone() -> None:
    a, b = np.full((4, 5, 3), 0.5), np.full((4, 5, 3), 0.6)
    l1, l2 = _lstar(0.5), _lstar(0.6)
    lbar = (l1 + l2) / 2
    s_l = 1 + 0.015 * (lbar - 50) ** 2 / math.sqrt(20 + (lbar - 50) ** 2)  # Sharma et al. 2005, Eq. (13)
    assert ciede2000(a, b, data_range=1.0) == pytest.approx(abs(l2 - l1) / s_l, abs=1e-3)
    assert ciede2000(a, a, data_range=1.0) == 0.0
    assert ciede2000(
        np.round(a * 255).astype(np.uint8), np.round(b * 255).astype(np.uint8), data_range=255
    ) == pytest.approx(ciede2000(np.round(a * 255) / 255, np.round(b * 255) / 255, data_range=1.0))


def test_grey_images_are_refused() -> None:
    with pytest.raises(ShapeError, match="CIEDE2000"):
        ciede2000(np.zeros((4, 4)), np.zeros((4, 4)), data_range=1.0)


def test_eval_ref_adds_the_ciede2000_column(tmp_path: Path) -> None:
    (tmp_path / "out").mkdir()
    (tmp_path / "ref").mkdir()
    rng = np.random.default_rng(0)
    ref = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    cv2.imwrite(str(tmp_path / "ref" / "a.png"), ref)
    cv2.imwrite(str(tmp_path / "out" / "a.png"), np.clip(ref.astype(int) + 20, 0, 255).astype(np.uint8))
    res = evaluate([tmp_path / "out"], ref=tmp_path / "ref")
    assert "ciede2000" in table.names("reference", default=True)
    (row,) = res.images
    want = ciede2000(cv2.imread(str(tmp_path / "out" / "a.png"))[:, :, ::-1], ref[:, :, ::-1], data_range=255)
    assert row["ciede2000"] == pytest.approx(want, rel=1e-6)  # murk reads to float32
