"""Snow removal on pairs of the same scene without and with snow (murk.metrics.snow_pairs)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from murk.errors import ShapeError
from murk.metrics.snow_pairs import snow_residue, snow_sites


def _pair(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    clean = cv2.GaussianBlur(rng.random((80, 100, 3)).astype(np.float32), (0, 0), 4.0) * 0.5 + 0.2
    snow = np.zeros((80, 100), np.float32)
    for y, x in rng.integers(5, 75, size=(30, 2)):
        cv2.circle(snow, (int(x), int(y)), 1, 1.0, -1)
    snowy = np.clip(clean + 0.3 * snow[..., None], 0, 1).astype(np.float32)
    return clean.astype(np.float32), snowy, snow


def test_sites_are_the_added_particles() -> None:
    clean, snowy, snow = _pair(np.random.default_rng(0))
    sites = snow_sites(snowy, clean)
    n_true = cv2.connectedComponents((snow > 0).astype(np.uint8))[0] - 1
    assert sites.count == n_true
    assert np.array_equal(sites.labels > 0, snow > 0)


def test_identity_keeps_everything_and_a_perfect_remover_nothing() -> None:
    clean, snowy, _ = _pair(np.random.default_rng(1))
    sites = snow_sites(snowy, clean)
    kept = snow_residue(sites, clean, snowy, clean)
    assert kept.residue == pytest.approx(1.0) and kept.sites_left == 1.0 and kept.gain == pytest.approx(1.0)
    assert kept.colour_residue == pytest.approx(1.0)
    removed = snow_residue(sites, clean, clean, clean)
    assert removed.residue == 0.0 and removed.sites_left == 0.0 and removed.colour_residue == 0.0


def test_a_particle_recoloured_into_a_dark_dot_is_removed_for_luma_and_not_for_colour() -> None:
    # What the shipped jointid does to many real particles: they come out pinkish and darker, not gone.
    clean, snowy, snow = _pair(np.random.default_rng(4))
    sites = snow_sites(snowy, clean)
    dot = clean + snow[..., None] * np.array([0.15, -0.15, -0.15], np.float32)  # redder and darker than the scene
    r = snow_residue(sites, clean, np.clip(dot, 0, 1).astype(np.float32), clean)
    assert r.residue == 0.0 and r.sites_left == 0.0  # nothing brighter is left
    assert r.colour_residue > 0.4  # but the dots are still there in colour


def test_a_contrast_stretch_is_not_counted_as_keeping_more_snow() -> None:
    clean, snowy, _ = _pair(np.random.default_rng(2))
    sites = snow_sites(snowy, clean)

    def stretch(x: np.ndarray) -> np.ndarray:
        return np.clip((x - 0.45) * 1.5 + 0.45, 0, 1)

    r = snow_residue(sites, clean, stretch(snowy), stretch(clean))
    assert r.gain == pytest.approx(1.5, rel=0.05) and r.residue == pytest.approx(1.0, abs=0.1)


def test_half_removed_particles() -> None:
    clean, snowy, _ = _pair(np.random.default_rng(3))
    sites = snow_sites(snowy, clean)
    half = (clean + 0.5 * (snowy - clean)).astype(np.float32)
    assert snow_residue(sites, clean, half, clean).residue == pytest.approx(0.5, abs=0.05)


def test_mismatched_pair_is_refused() -> None:
    with pytest.raises(ShapeError, match="differ in size"):
        snow_sites(np.zeros((8, 8, 3), np.float32), np.zeros((8, 9, 3), np.float32))


def test_structure_away_from_snow_sees_blur_and_not_the_particles() -> None:
    """The "without blurring the rest" measure: a blur lowers it, removing only the particles does not."""
    from murk.metrics.fidelity import structure_fidelity
    from murk.metrics.snow_pairs import snow_free_mask

    rng = np.random.default_rng(4)
    clean = (rng.random((80, 100, 3)).astype(np.float32) * 0.5 + 0.2).astype(np.float32)  # fine texture
    snow = np.zeros((80, 100), np.float32)
    for y, x in rng.integers(5, 75, size=(20, 2)):
        cv2.circle(snow, (int(x), int(y)), 1, 1.0, -1)
    snowy = np.clip(clean + 0.3 * snow[..., None], 0, 1).astype(np.float32)
    away = snow_free_mask(snow_sites(snowy, clean))
    assert not away[snow > 0].any() and 0.5 < away.mean() < 1.0
    removed_only = structure_fidelity(snowy, clean, where=away).gms_mean
    blurred = structure_fidelity(snowy, cv2.GaussianBlur(clean, (0, 0), 1.5), where=away).gms_mean
    assert removed_only > 0.95 and blurred < 0.9  # 0.9: the real-snow issue's floor
    assert np.isnan(structure_fidelity(snowy, clean, where=np.zeros((80, 100), bool)).gms_mean)
