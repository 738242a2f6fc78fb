"""Small sharp details painted on a clean scene (murk.scenes.specks), and make_heldout's option for them."""

from __future__ import annotations

import numpy as np
import pytest

from murk.scenes.specks import DOT, ELLIPSE, STROKE, Specks, apply_specks, sample_specks


def _one(kind: int, length: float, width: float, angle: float = 0.0, colour: float = 1.0) -> Specks:
    f = np.array
    return Specks(f([kind]), f([[20.0, 30.0]]), f([length]), f([width]), f([angle]), f([[colour] * 3]), f([1.0]))


def test_sampling_is_seeded_scales_with_the_frame_and_draws_what_the_docstring_says() -> None:
    a, b = sample_specks(3, (240, 320), 2000.0), sample_specks(3, (240, 320), 2000.0)
    assert all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("kind", "centre_yx_px", "colour", "opacity"))
    assert 100 < len(a) < 210  # Poisson(2000 x 0.0768)
    assert set(np.unique(a.kind)) == {DOT, STROKE, ELLIPSE}
    assert np.all(a.length_px[a.kind == DOT] <= 2.5) and np.all(a.length_px[a.kind == STROKE] >= 6.0)
    luma = a.colour.max(axis=1)
    assert 0.6 < np.mean(luma >= 0.65) < 0.9 and np.all((luma <= 0.25) | (luma >= 0.65))
    big = sample_specks(3, (480, 640), 2000.0)
    assert np.all(big.length_px[big.kind == STROKE] >= 12.0)  # sizes follow the frame: twice the height, twice the px
    assert len(sample_specks(3, (240, 320), 0.0)) == 0
    for bad in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="per_mpx"):
            sample_specks(0, (240, 320), bad)


def test_each_kind_covers_its_area_with_a_soft_one_pixel_edge_and_leaves_the_rest() -> None:
    grey = np.full((40, 60, 3), 0.2, np.float32)
    for kind, length, width, area in ((DOT, 4.0, 0.0, np.pi * 16), (STROKE, 20.0, 2.0, 40.0 + np.pi),
                                      (ELLIPSE, 6.0, 2.0, np.pi * 12)):  # fmt: skip
        out = apply_specks(grey, _one(kind, length, width))
        covered = (out[..., 0] - 0.2) / 0.8
        assert covered.sum() == pytest.approx(area, rel=0.08), kind
        assert out[20, 30, 0] == pytest.approx(1.0)  # the centre is the speck's colour
        assert np.all(out[:, :10] == 0.2) and out.dtype == np.float32
    assert np.array_equal(grey, np.full((40, 60, 3), 0.2, np.float32))  # the input is not changed
    upright = apply_specks(grey, _one(STROKE, 20.0, 2.0, angle=np.pi / 2))
    assert upright[20 - 8, 30, 0] > 0.9 and upright[20, 30 - 8, 0] == pytest.approx(0.2)  # along its angle
    dark = apply_specks(grey, _one(DOT, 3.0, 0.0, colour=0.0))
    assert dark[20, 30, 0] == pytest.approx(0.0)
    edge = _one(DOT, 3.0, 0.0)
    clipped = apply_specks(grey, Specks(edge.kind, np.array([[0.0, 59.0]]), *(getattr(edge, f) for f in
                                        ("length_px", "width_px", "angle_rad", "colour", "opacity"))))  # fmt: skip
    assert clipped[0, 59, 0] > 0.9
    with pytest.raises(ValueError, match="rgb"):
        apply_specks(grey[..., 0], edge)


def test_make_heldout_paints_specks_on_the_clean_scene_before_the_water_and_none_by_default() -> None:
    from murk.report.heldout import make_heldout
    from murk.synth.config import SynthConfig

    synthesis = SynthConfig(stages=("basic",))
    plain = make_heldout(2, seed=4, size_hw=(48, 64), synthesis=synthesis)
    again = make_heldout(2, seed=4, size_hw=(48, 64), synthesis=synthesis, specks_per_mpx=0.0)
    assert np.array_equal(plain.clean, again.clean) and np.array_equal(plain.degraded, again.degraded)
    specked = make_heldout(2, seed=4, size_hw=(48, 64), synthesis=synthesis, specks_per_mpx=20000.0)
    changed = np.abs(specked.clean - plain.clean).max(axis=-1) > 1e-6
    assert 0.01 < changed.mean() < 0.6
    # in the input too, degraded by the same water: the speck is part of the scene
    assert np.abs(specked.degraded - plain.degraded).max(axis=-1)[changed].mean() > 0.01
    assert np.array_equal(specked.dist_m, plain.dist_m, equal_nan=True)
