"""Small sharp details painted on a clean scene (murk.scenes.specks), and make_heldout's option for them."""

from __future__ import annotations

import numpy as np
import pytest

from murk.scenes.specks import DOT, ELLIPSE, STROKE, Specks, apply_specks, sample_specks


def _one(kind: int, length: float, width: float, angle: float = 0.0, colour: float = 1.0,
         centre: tuple[float, float] = (20.0, 30.0)) -> Specks:  # fmt: skip
    f = np.array
    return Specks(f([kind]), f([centre]), f([length]), f([width]), f([angle]), f([[colour] * 3]), f([1.0]))


def test_sampling_is_seeded_scales_with_the_frame_and_draws_what_the_docstring_says() -> None:
    a, b = sample_specks(3, (240, 320), 2000.0), sample_specks(np.random.default_rng(3), (240, 320), 2000.0)
    assert all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("kind", "centre_yx_px", "colour", "opacity"))
    assert 100 < len(a) < 210  # Poisson(2000 x 0.0768)
    assert set(np.unique(a.kind)) == {DOT, STROKE, ELLIPSE}
    assert np.all(a.length_px[a.kind == DOT] <= 2.5) and np.all(a.length_px[a.kind == STROKE] >= 6.0)
    luma = a.colour.max(axis=1)
    assert 0.6 < np.mean(luma >= 0.65) < 0.9 and np.all((luma <= 0.25) | (luma >= 0.65))
    big = sample_specks(3, (480, 640), 2000.0)
    assert np.all(big.length_px[big.kind == STROKE] >= 12.0)  # sizes follow the frame: twice the side, twice the px
    assert 100 < len(big) < 210  # ... and the count the reference frame's megapixels: the same share covered
    assert len(sample_specks(3, (240, 320), 0.0)) == 0
    for bad in (-1.0, float("nan")):
        with pytest.raises(ValueError, match="per_mpx"):
            sample_specks(0, (240, 320), bad)
    for size in ((0, 320), (240, 320.5), (240, 320, 3), (True, 320)):
        with pytest.raises(ValueError, match="size_hw"):
            sample_specks(0, size, 10.0)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kind", "length", "width", "area", "rel"),
    [
        (DOT, 4.0, 0.0, np.pi * 16, 0.03),
        (STROKE, 20.0, 2.0, 40.0 + np.pi, 0.03),
        (ELLIPSE, 6.0, 2.0, np.pi * 12, 0.03),
        (ELLIPSE, 6.0, 0.8, np.pi * 4.8, 0.08),  # tips of radius 0.1 px: a one-sample edge overestimates them
    ],
)
def test_each_kind_covers_its_area_with_a_soft_one_pixel_edge_and_leaves_the_rest(
    kind: int, length: float, width: float, area: float, rel: float
) -> None:
    grey = np.full((40, 60, 3), 0.2, np.float32)
    speck = _one(kind, length, width, angle=0.4, centre=(20.3, 30.6))
    out = apply_specks(grey, speck)
    covered = (out[..., 0] - 0.2) / 0.8
    assert covered.sum() == pytest.approx(area, rel=rel)
    assert out.dtype == np.float32 and np.all(out[:, :10] == np.float32(0.2))
    assert np.array_equal(grey, np.full((40, 60, 3), 0.2, np.float32))  # the input is not changed
    # the edge: partly covered pixels exist, and every one of them lies within a pixel of the outline
    yy, xx = np.mgrid[0:40, 0:60] + 0.5
    c, s = np.cos(0.4), np.sin(0.4)
    u, v = (xx - 30.6) * c + (yy - 20.3) * s, -(xx - 30.6) * s + (yy - 20.3) * c
    if kind == DOT:
        dist = np.hypot(u, v) - length
    elif kind == STROKE:
        dist = np.hypot(u - np.clip(u, -length / 2, length / 2), v) - width / 2
    else:  # the exact distance to an ellipse, from a dense sampling of its outline
        t = np.linspace(0, 2 * np.pi, 4000)
        ex, ey = length * np.cos(t), width * np.sin(t)
        near = np.min(np.hypot(u[..., None] - ex, v[..., None] - ey), axis=-1)
        dist = np.where(np.hypot(u / length, v / width) < 1, -near, near)
    partial = (covered > 1e-4) & (covered < 1 - 1e-4)
    assert partial.sum() >= 4 and np.all(np.abs(dist[partial]) <= 1.0), np.abs(dist[partial]).max()
    assert np.all(covered[dist > 0.75] < 0.3) and np.all(covered[dist < -0.75] > 0.7)


def test_painting_keeps_the_colour_the_angle_and_clips_at_the_frame() -> None:
    grey = np.full((40, 60, 3), 0.2, np.float32)
    assert apply_specks(grey, _one(DOT, 4.0, 0.0))[20, 30, 0] == pytest.approx(1.0)  # the centre: the speck's colour
    upright = apply_specks(grey, _one(STROKE, 20.0, 2.0, angle=np.pi / 2))
    assert upright[20 - 8, 30, 0] > 0.9 and upright[20, 30 - 8, 0] == pytest.approx(0.2)  # along its angle
    dark = apply_specks(grey, _one(DOT, 3.0, 0.0, colour=0.0))
    assert dark[20, 30, 0] == pytest.approx(0.0)
    clipped = apply_specks(grey, _one(DOT, 3.0, 0.0, centre=(0.0, 59.0)))
    assert clipped[0, 59, 0] > 0.9
    with pytest.raises(ValueError, match="rgb"):
        apply_specks(grey[..., 0], _one(DOT, 3.0, 0.0))


def test_make_heldout_paints_specks_on_the_clean_scene_before_the_water_and_none_by_default() -> None:
    from murk.report.heldout import make_heldout
    from murk.synth.config import SynthConfig

    synthesis = SynthConfig(stages=("basic",))
    plain = make_heldout(2, seed=4, size_hw=(48, 64), synthesis=synthesis)
    again = make_heldout(2, seed=4, size_hw=(48, 64), synthesis=synthesis, specks_per_mpx=0.0)
    assert np.array_equal(plain.clean, again.clean) and np.array_equal(plain.degraded, again.degraded)
    specked = make_heldout(
        2, seed=4, size_hw=(48, 64), synthesis=synthesis, specks_per_mpx=800.0
    )  # 20,000 per megapixel at this size
    changed = np.abs(specked.clean - plain.clean).max(axis=-1) > 1e-6
    assert 0.01 < changed.mean() < 0.6
    # in the input too, degraded by the same water: the speck is part of the scene
    assert np.abs(specked.degraded - plain.degraded).max(axis=-1)[changed].mean() > 0.01
    assert np.array_equal(specked.dist_m, plain.dist_m, equal_nan=True)
