"""Input-vs-output restoration measures (murk.metrics.fidelity): invariants on a constructed scene.

The scene (smooth gradients, rectangles with edges, a faint blurred texture; fixed seed) is degraded in the
ways the measures must catch: checkerboards, Gaussian and impulse noise, blur, a collapse to grey, darkening,
pasted particles, a colour cast. Bounds were chosen with margin from the values these constructions give
(recorded next to each assertion); calibration on real images is in docs/metrics.md.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from murk.errors import ShapeError
from murk.metrics import (
    FLAG_NAMES,
    MEASURE_KEYS,
    MetricWarning,
    artefact_energy,
    artefact_ratio,
    colour_exposure,
    count_flags,
    flags,
    join_flags,
    particle_count,
    restoration_measures,
    structure_fidelity,
    uiqm,
)
from murk.metrics import fidelity as fid

H, W = 240, 320


def _scene(seed: int = 0) -> np.ndarray:
    g = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    base = 0.2 + 0.3 * xx / W + 0.15 * yy / H
    img = np.stack([base * 0.7, base, base * 0.95 + 0.05], axis=-1)
    for _ in range(6):
        y0, x0 = g.integers(0, H - 60), g.integers(0, W - 80)
        hh, ww = g.integers(25, 60), g.integers(30, 80)
        img[y0 : y0 + hh, x0 : x0 + ww] += g.uniform(-0.15, 0.15, 3).astype(np.float32)
    texture = cv2.GaussianBlur(g.normal(0, 0.03, (H, W)).astype(np.float32), (0, 0), 2.0)
    return np.clip(img + texture[..., None], 0.05, 0.95).astype(np.float32)


@pytest.fixture(scope="module")
def scene() -> np.ndarray:
    return _scene()


def _checkerboard(period_px: int, amplitude: float, shape: tuple[int, int] = (H, W)) -> np.ndarray:
    """A +-amplitude checkerboard of square cells period/2 px wide (a pixel-shuffle / tiling artefact)."""
    yy, xx = np.mgrid[0 : shape[0], 0 : shape[1]]
    cells = (yy // (period_px // 2) + xx // (period_px // 2)) % 2
    return (amplitude * (2.0 * cells - 1.0))[..., None].astype(np.float32)


def _paste_dots(image: np.ndarray, n: int, delta: float, seed: int = 1) -> np.ndarray:
    """``n`` separated 3x3 dots brightened (delta > 0) or darkened (delta < 0) by |delta|."""
    out = image.copy()
    g = np.random.default_rng(seed)
    ys = g.choice(np.arange(8, H - 8, 12), n)
    xs = g.choice(np.arange(8, W - 8, 12), n)
    for y, x in zip(ys, xs, strict=True):
        out[y : y + 3, x : x + 3] = np.clip(out[y : y + 3, x : x + 3] + delta, 0.0, 1.0)
    return out


def _stretch(image: np.ndarray, gain: float) -> np.ndarray:
    m = np.float32(image.mean())
    return (m + np.float32(gain) * (image - m)).astype(np.float32)


# ----------------------------------------------------------------------------------------------------------
# identity and invariants


def test_identity_gives_exact_identity_values(scene: np.ndarray) -> None:
    m = restoration_measures(scene, scene)
    assert tuple(m) == MEASURE_KEYS
    for k in (
        "artefact_periodic_ratio",
        "artefact_isolated_ratio",
        "particle_residue_ratio",
        "luminance_ratio",
        "contrast_ratio",
        "structure_gms",
    ):
        assert m[k] == 1.0, k
    assert m["structure_gmsd"] == 0.0
    assert m["particles_bright_in"] == m["particles_bright_out"] > 0  # the scene's rectangle corners
    assert (m["cast_in"], m["luminance_in"], m["contrast_in"]) == (m["cast_out"], m["luminance_out"], m["contrast_out"])
    assert all(math.isfinite(v) for v in m.values())
    assert flags(m) == []
    assert artefact_ratio(scene, scene) == fid.ArtefactEnergy(1.0, 1.0)
    assert structure_fidelity(scene, scene) == fid.StructureFidelity(1.0, 0.0)


def test_global_contrast_stretch_changes_only_contrast(scene: np.ndarray) -> None:
    stretched = _stretch(scene, 1.5)
    assert 0.0 <= stretched.min() and stretched.max() <= 1.0  # no clipping: a pure affine change
    m = restoration_measures(scene, stretched)
    assert m["artefact_periodic_ratio"] == pytest.approx(1.0, abs=1e-3)
    assert m["artefact_isolated_ratio"] == pytest.approx(1.0, abs=1e-3)
    assert m["structure_gms"] > 0.999
    assert m["particle_residue_ratio"] == pytest.approx(1.0, abs=0.05)
    assert m["contrast_ratio"] == pytest.approx(1.5, rel=0.01)
    assert flags(m) == []


def test_image_borders_are_not_periodic_artefacts() -> None:
    """Moisan's decomposition: a steep ramp's border jump adds no periodic energy (a plain FFT would give
    the ramp's axis cross ~100x the checkerboard's energy)."""
    ramp = np.repeat(np.linspace(0.1, 0.8, W, dtype=np.float32)[None, :], H, axis=0)[..., None].repeat(3, axis=2)
    board = np.repeat(_checkerboard(2, 0.02), 3, axis=2)
    assert artefact_energy(0.45 + board).periodic > 0.99  # all of a checkerboard's energy is one grid peak
    assert artefact_energy(ramp + board).periodic > 0.9


# ----------------------------------------------------------------------------------------------------------
# (a) artefact energy


@pytest.mark.parametrize("period_px", [2, 4, 8])
def test_checkerboard_raises_periodic_ratio(scene: np.ndarray, period_px: int) -> None:
    out = np.clip(scene + _checkerboard(period_px, 0.02), 0.0, 1.0)
    r = artefact_ratio(scene, out)
    assert r.periodic > 50.0  # measured ~440 for each period
    assert "artefacts" in flags(restoration_measures(scene, out))


def test_faint_checkerboard_is_still_caught(scene: np.ndarray) -> None:
    out = np.clip(scene + _checkerboard(2, 0.004), 0.0, 1.0)  # one grey level of 255
    assert artefact_ratio(scene, out).periodic > 5 * fid.ARTEFACT_RATIO_MAX  # measured ~28


def test_noise_raises_isolated_ratio(scene: np.ndarray) -> None:
    g = np.random.default_rng(2)
    noisy = np.clip(scene + g.normal(0, 0.02, scene.shape).astype(np.float32), 0.0, 1.0)
    impulses = scene.copy()
    u = g.random(scene.shape[:2])
    impulses[u < 0.005], impulses[u > 0.995] = 0.0, 1.0
    for out, bound in ((noisy, 10.0), (impulses, 10.0)):  # measured ~35 and ~54
        r = artefact_ratio(scene, out)
        assert r.isolated > bound
        assert r.periodic < 2.0  # noise has no periodic grid
        assert "artefacts" in flags(restoration_measures(scene, out))


def test_noise_fools_uiqm_but_not_the_measures(scene: np.ndarray) -> None:
    """The premise: UIQM scores the destroyed outputs higher than the unchanged image; the flags catch them."""
    g = np.random.default_rng(3)
    noisy = np.clip(scene + g.normal(0, 0.02, scene.shape).astype(np.float32), 0.0, 1.0)
    board = np.clip(scene + _checkerboard(2, 0.02), 0.0, 1.0)
    base = uiqm(scene, data_range=1.0).uiqm
    for out in (noisy, board):
        assert uiqm(out, data_range=1.0).uiqm > base + 0.2
        assert "artefacts" in flags(restoration_measures(scene, out))


def test_artefact_energy_of_flat_image_is_zero() -> None:
    e = artefact_energy(np.full((64, 64, 3), 0.4, np.float32))
    assert e == fid.ArtefactEnergy(0.0, 0.0)


def test_small_image_periodic_term_warns() -> None:
    img = np.random.default_rng(0).random((20, 40, 3)).astype(np.float32)
    with pytest.warns(MetricWarning, match="at least 32x32"):
        e = artefact_energy(img)
    assert e.periodic == 0.0 and e.isolated > 0.0
    tiny = np.random.default_rng(1).random((1, 1, 3))  # float64 is accepted too
    with pytest.warns(MetricWarning, match="image 1x1"):
        m = restoration_measures(tiny, tiny * 0.5)
    assert all(math.isfinite(v) for v in m.values()) and m["luminance_ratio"] < 0.6


# ----------------------------------------------------------------------------------------------------------
# (b) structure fidelity


def test_blur_and_flat_grey_lower_structure(scene: np.ndarray) -> None:
    stretch = structure_fidelity(scene, _stretch(scene, 1.5)).gms_mean
    blur = structure_fidelity(scene, cv2.GaussianBlur(scene, (0, 0), 3.0))
    flat = structure_fidelity(scene, np.full_like(scene, scene.mean()))
    assert stretch > 0.999
    assert blur.gms_mean < fid.STRUCTURE_GMS_MIN and blur.gms_mean < stretch - 0.3  # measured 0.59
    assert flat.gms_mean < 0.3  # measured 0.19
    assert blur.gmsd > 0.1 and flat.gmsd > 0.1
    assert "structure loss" in flags(restoration_measures(scene, cv2.GaussianBlur(scene, (0, 0), 3.0)))
    m_flat = restoration_measures(scene, np.full_like(scene, scene.mean()))
    assert {"structure loss", "grey collapse"} <= set(flags(m_flat))


def test_noise_lowers_structure(scene: np.ndarray) -> None:
    noisy = np.clip(scene + np.random.default_rng(4).normal(0, 0.02, scene.shape).astype(np.float32), 0.0, 1.0)
    assert structure_fidelity(scene, noisy).gms_mean < 0.8  # measured 0.65


def test_local_contrast_change_keeps_structure(scene: np.ndarray) -> None:
    """A monotone tone curve (gamma 0.6) changes contrast locally, not the structure."""
    assert structure_fidelity(scene, scene**0.6).gms_mean > 0.95


# ----------------------------------------------------------------------------------------------------------
# (c) particles


def test_pasted_bright_particles_raise_bright_count(scene: np.ndarray) -> None:
    dotted = _paste_dots(scene, 40, +0.4)
    before, after = particle_count(scene), particle_count(dotted)
    added_per_mp = 40 / (H * W / 1e6)  # 521
    assert after.bright_per_mp - before.bright_per_mp > 0.8 * added_per_mp
    assert after.total_per_mp == after.bright_per_mp + after.dark_per_mp
    m = restoration_measures(scene, dotted)
    assert m["particle_residue_ratio"] > 2.0 and "particles not removed" in flags(m)
    # the reverse pair: a method that removed the particles
    m_removed = restoration_measures(dotted, scene)
    assert m_removed["particle_residue_ratio"] < 0.5
    assert "particles not removed" not in flags(m_removed)


def test_pasted_dark_dots_raise_dark_count(scene: np.ndarray) -> None:
    dotted = _paste_dots(scene, 40, -0.4)
    before, after = particle_count(scene), particle_count(dotted)
    assert after.dark_per_mp - before.dark_per_mp > 0.8 * 40 / (H * W / 1e6)
    assert after.dark_per_mp - before.dark_per_mp > 3 * (after.bright_per_mp - before.bright_per_mp)


def test_particle_count_ignores_global_contrast(scene: np.ndarray) -> None:
    dotted = _paste_dots(scene, 40, +0.3)
    a, b = particle_count(dotted), particle_count(_stretch(dotted, 0.5))
    assert b.bright_per_mp == pytest.approx(a.bright_per_mp, rel=0.05)


# ----------------------------------------------------------------------------------------------------------
# (d) colour and exposure


def test_colour_cast_and_exposure() -> None:
    grey = np.full((32, 32, 3), 0.5, np.float32)
    neutral = colour_exposure(grey)
    assert neutral.cast < 0.05 and neutral.luminance == pytest.approx(0.5) and neutral.contrast == 0.0
    tinted = grey * np.array([0.6, 1.0, 0.9], np.float32)  # blue-green water
    assert colour_exposure(tinted).cast > 10.0  # CIELAB units
    # reference: the CIELAB chroma of that colour by scikit-image 0.26 ``rgb2lab`` (D65, an independent
    # implementation); OpenCV's float conversion differs from it by ~0.1 CIELAB units (its sRGB/white constants)
    from skimage.color import rgb2lab

    lab = rgb2lab(tinted[:1, :1].astype(np.float64))[0, 0]
    assert colour_exposure(tinted).cast == pytest.approx(math.hypot(lab[1], lab[2]), rel=0.01)


def test_darkening_and_grey_collapse_flags(scene: np.ndarray) -> None:
    dark = restoration_measures(scene, scene * np.float32(0.7))
    assert dark["luminance_ratio"] == pytest.approx(0.7, abs=0.01)
    assert flags(dark) == ["darkened"]
    grey = restoration_measures(scene, _stretch(scene, 0.3))
    assert grey["contrast_ratio"] == pytest.approx(0.3, abs=0.02)
    assert flags(grey) == ["grey collapse"]
    stronger = restoration_measures(scene, scene * np.array([0.6, 1.0, 1.0], np.float32))  # more cyan
    assert stronger["cast_out"] > stronger["cast_in"] + 5.0  # measured 12.0 -> 19.7
    grey_world = scene * (scene.mean() / scene.reshape(-1, 3).mean(axis=0)).astype(np.float32)
    corrected = restoration_measures(scene, grey_world)
    assert corrected["cast_out"] < 0.2 * corrected["cast_in"]


# ----------------------------------------------------------------------------------------------------------
# flags


def _neutral() -> dict[str, float]:
    return dict.fromkeys(MEASURE_KEYS, 1.0)


@pytest.mark.parametrize(
    ("key", "bad", "good", "name"),
    [
        ("artefact_periodic_ratio", 1.31, 1.29, "artefacts"),
        ("artefact_isolated_ratio", 1.31, 1.29, "artefacts"),
        ("structure_gms", 0.69, 0.71, "structure loss"),
        ("contrast_ratio", 0.49, 0.51, "grey collapse"),
        ("luminance_ratio", 0.89, 0.91, "darkened"),
        ("particle_residue_ratio", 1.01, 1.0, "particles not removed"),
    ],
)
def test_each_flag_has_its_stated_threshold(key: str, bad: float, good: float, name: str) -> None:
    assert flags({**_neutral(), key: bad}) == [name]
    assert flags({**_neutral(), key: good}) == []
    assert flags({**_neutral(), key: float("nan")}) == []


def test_flags_order_join_and_count() -> None:
    m = {**_neutral(), "particle_residue_ratio": 2.0, "luminance_ratio": 0.5, "artefact_periodic_ratio": 9.0}
    assert flags(m) == ["artefacts", "darkened", "particles not removed"]
    joined = [join_flags(flags(m)), join_flags([]), join_flags(["darkened"])]
    assert joined[0] == "artefacts; darkened; particles not removed" and joined[1] == ""
    counts = count_flags(joined)
    assert counts == {
        "flagged": 2,
        "n": 3,
        "artefacts": 1,
        "structure loss": 0,
        "grey collapse": 0,
        "darkened": 2,
        "particles not removed": 1,
    }
    assert set(counts) == {"flagged", "n", *FLAG_NAMES}


# ----------------------------------------------------------------------------------------------------------
# errors


def test_errors(scene: np.ndarray) -> None:
    with pytest.raises(TypeError, match=r"input: expected a float RGB image .* got dtype uint8"):
        restoration_measures((scene * 255).astype(np.uint8), scene)
    with pytest.raises(TypeError, match="image: expected a numpy array"):
        artefact_energy([[0.5]])  # type: ignore[arg-type]
    with pytest.raises(ShapeError, match=r"image: expected shape \(H, W, 3\)"):
        particle_count(scene[..., 0])
    with pytest.raises(ShapeError, match=r"output: expected the shape of input \(240, 320, 3\), got \(240, 160, 3\)"):
        structure_fidelity(scene, scene[:, :160])
    with pytest.raises(ValueError, match=r"output: expected values in \[0, data_range=1\]"):
        restoration_measures(scene, scene * 255)
    bad = scene.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="input: contains NaN"):
        artefact_ratio(bad, scene)
    with pytest.raises(ValueError, match="measures: expected the keys of restoration_measures, missing structure_gms"):
        flags({k: v for k, v in _neutral().items() if k != "structure_gms"})
    with pytest.raises(TypeError, match="measures: expected a mapping"):
        flags([1.0])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="flags: expected names from"):
        count_flags(["artefacts; blurry"])
