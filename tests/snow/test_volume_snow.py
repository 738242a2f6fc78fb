"""Volume snow (``marine_snow.volume_m``): particles in the water between the camera and the scene, near ones
large and soft, hidden behind nearer surfaces, tinted by the water in front of them, lit by a lamp."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from murk._config import merge
from murk.snow.bank import load_bank
from murk.snow.composite import (
    SnowParams,
    composite_snow,
    composite_snow_torch,
    layer_plan,
    sample_snow,
    snow_layout,
    streak_kernel,
)
from murk.synth.config import SnowConfig, SynthConfig
from murk.synth.params import sample_variant, snow_sampler_for
from murk.synth.render import render, render_batch_torch

from .conftest import make_bank


def _vol(n: int = 300, seed: int = 2, **kw: object) -> SnowParams:
    base = SnowParams(n_particles=n, rho_px=0.5, scale_range=(0.3, 0.6), layout_seed=seed, bank_id="")
    return dataclasses.replace(base, **{"volume_m": (0.3, 4.0), **kw})  # type: ignore[arg-type]


def test_the_paper_draws_are_kept_and_scale_goes_with_focus_over_distance() -> None:
    flat, vol = _vol(volume_m=None), _vol(focus_m=1.5)
    a, b = snow_layout(flat, 50, 64, 48), snow_layout(vol, 50, 64, 48)
    assert a.distance_m is None and b.distance_m is not None
    np.testing.assert_array_equal(a.index, b.index)
    np.testing.assert_array_equal(a.centre_xy, b.centre_xy)
    np.testing.assert_allclose(b.scale * b.distance_m / 1.5, a.scale)  # near particles large


def test_distances_fill_the_volume_up_to_the_scene() -> None:
    lay = snow_layout(_vol(n=20000), 50, 64, 48)
    z = lay.distance_m
    assert z is not None and z.min() >= 0.3 and z.max() <= 4.0
    # uniform in volume: P(z < r) = (r^3 - a^3) / (b^3 - a^3); the median is the cube root of the mean cube
    assert abs(np.median(z) - np.cbrt((0.3**3 + 4.0**3) / 2)) < 0.03
    near = snow_layout(_vol(n=2000), 50, 64, 48, scene_far_m=1.2).distance_m
    assert near is not None and near.max() <= 1.2  # a near scene gets the whole count in front of it


def test_particles_behind_the_scene_are_hidden() -> None:
    p = _vol(n=3000)
    lay = snow_layout(p, 50, 64, 48)
    dist = np.full((48, 64), 4.0, np.float32)
    dist[:, :32] = 0.6  # a wall 0.6 m away on the left
    plan = layer_plan(p, lay, 64, 48, lambda y, x: dist[y, x])
    kept = np.concatenate([layer.layout.centre_xy for layer in plan])
    z = np.concatenate([layer.layout.distance_m for layer in plan])
    left = np.rint(kept[:, 0]) < 32
    assert left.any() and z[left].max() < 0.6
    assert z[~left].max() > 2.0
    assert sum(len(layer.layout.index) for layer in plan) < len(lay.index)


def test_layers_are_far_to_near_and_blurred_by_their_defocus() -> None:
    p = _vol(n=5000, focus_m=4.0, defocus_px=2.0, layers=4)
    plan = layer_plan(p, snow_layout(p, 50, 64, 48), 64, 48)
    assert len(plan) == 4
    means = [float(np.mean(layer.layout.distance_m)) for layer in plan]
    assert means == sorted(means, reverse=True)
    rhos = [layer.rho_px for layer in plan]
    assert rhos == sorted(rhos)  # focused far: the nearer, the softer
    inv = np.linspace(1 / 4.0, 1 / 0.3, 5)
    expected = [float(np.hypot(0.5, 2.0 * abs((inv[j] + inv[j + 1]) / 2 - 1 / 4.0))) for j in range(4)]
    np.testing.assert_allclose(rhos, expected)


def test_water_tints_the_particles_and_a_lamp_lights_the_near_ones() -> None:
    bank = make_bank(colour=(200, 200, 200), sizes=(3, 4))
    img = np.full((48, 64, 3), 0.1, np.float32)
    blue = (np.array([1.5, 1.0, 0.2]), np.array([0.0, 0.1, 0.6]))
    p = dataclasses.replace(_vol(n=60), volume_m=(0.5, 1.5), defocus_px=0.0)
    grey, a_grey = composite_snow(img, p, bank)
    tinted, a_tint = composite_snow(img, p, bank, water=blue)
    np.testing.assert_array_equal(a_grey, a_tint)  # the water changes colours, not coverage
    on = a_tint > 0.5
    r, g, b = (float(tinted[..., c][on].mean()) for c in range(3))
    assert b > g > r  # red goes first
    assert abs(float(grey[..., 0][on].mean()) - float(grey[..., 2][on].mean())) < 1e-6
    lit, _ = composite_snow(img, dataclasses.replace(p, lamp=0.3), bank, water=blue)
    assert float(lit[on].mean()) > float(tinted[on].mean())


def test_numpy_and_torch_volume_snow_agree() -> None:
    bank = load_bank("builtin:snow")
    rng = np.random.default_rng(0)
    imgs = rng.random((2, 40, 56, 3)).astype(np.float32)
    dist = np.stack(
        [np.full((40, 56), 2.0, np.float32), np.linspace(0.5, 3.0, 40 * 56, dtype=np.float32).reshape(40, 56)]
    )
    waters = [
        (np.array([0.4, 0.1, 0.2]), np.array([0.1, 0.4, 0.5])),
        (np.array([0.9, 0.3, 0.1]), np.array([0.2, 0.3, 0.1])),
    ]
    params = [
        sample_snow(s, bank, n_particles=(400, 500), volume_m=(0.3, 3.0), lamp=0.2, defocus_px=1.5) for s in range(2)
    ]
    scatters = [(0.5, 0.15, 0.2), (0.8, 1.0, 0.5)]
    out_t, alpha_t = composite_snow_torch(
        torch.from_numpy(imgs).permute(0, 3, 1, 2),
        params,
        bank,
        dist_m=torch.from_numpy(dist)[:, None],
        water=waters,
        scatter=scatters,
    )
    for i in range(2):
        out, alpha = composite_snow(imgs[i], params[i], bank, dist_m=dist[i], water=waters[i], scatter=scatters[i])
        assert alpha.max() > 0.3
        np.testing.assert_allclose(out_t[i].permute(1, 2, 0).numpy(), out, atol=2e-5)
        np.testing.assert_allclose(alpha_t[i, 0].numpy(), alpha, atol=2e-5)
    mixed = [params[0], dataclasses.replace(params[1], volume_m=None)]  # a plain image in a layered batch
    out_t, _ = composite_snow_torch(torch.from_numpy(imgs).permute(0, 3, 1, 2), mixed, bank)
    out, _ = composite_snow(imgs[1], mixed[1], bank)
    np.testing.assert_allclose(out_t[1].permute(1, 2, 0).numpy(), out, atol=2e-5)


def test_streak_kernel_is_a_normalised_line() -> None:
    assert streak_kernel(0.5, 0.0) is None
    k = streak_kernel(6.0, 0.0)
    assert k is not None and abs(float(k.sum()) - 1.0) < 1e-6
    r = k.shape[0] // 2
    assert float(k[r].sum()) > 0.99  # horizontal: all on the centre row
    cols = np.nonzero(k[r] > 1e-3)[0]
    assert cols.max() - cols.min() in (6, 7)
    v = streak_kernel(6.0, np.pi / 2)
    assert v is not None and float(v[:, r].sum()) > 0.99  # vertical


def test_motion_streaks_smear_particles_along_their_direction() -> None:
    bank = make_bank(colour=(255, 255, 255), sizes=(2,))
    img = np.zeros((60, 80, 3), np.float32)
    still = SnowParams(n_particles=3, rho_px=0.3, scale_range=(1.0, 1.0), layout_seed=5, bank_id="")
    moving = dataclasses.replace(still, motion_px=12.0, motion_angle_rad=0.0)
    _, a0 = composite_snow(img, still, bank)
    _, a1 = composite_snow(img, moving, bank)
    rows0, cols0 = np.nonzero(a0 > 0.02)
    rows1, cols1 = np.nonzero(a1 > 0.02)
    assert np.ptp(cols1) >= np.ptp(cols0) and len(cols1) > 2 * len(cols0)  # longer along x
    assert set(rows1) <= set(range(rows0.min() - 1, rows0.max() + 2))  # not across
    assert 0.8 * float(a0.sum()) < float(a1.sum()) <= float(a0.sum()) + 1e-3  # spread, not added (some leaves)
    _, ta = composite_snow_torch(torch.from_numpy(img).permute(2, 0, 1)[None], [moving], bank)
    np.testing.assert_allclose(ta[0, 0].numpy(), a1, atol=2e-5)


def test_volume_streaks_are_longer_near_the_camera() -> None:
    p = _vol(n=4000, motion_px=10.0, focus_m=1.0)
    plan = layer_plan(p, snow_layout(p, 50, 64, 48), 64, 48)
    streaks = [layer.streak_px for layer in plan]
    assert streaks == sorted(streaks) and streaks[-1] > 10.0 > streaks[0]


def test_synthesis_config_reaches_the_renderer() -> None:
    bank = load_bank("builtin:snow")
    cfg = merge(
        SynthConfig(),
        {"stages": ["basic", "marine_snow"], "marine_snow": {"volume_m": [0.3, 3.0], "lamp": 0.1, "layers": 3}},
    )
    params = sample_variant(5, cfg, snow_sampler=snow_sampler_for(cfg, bank))
    assert params.snow is not None and params.snow.volume_m == (0.3, 3.0) and params.snow.layers == 3
    clean = np.full((48, 64, 3), 0.5, np.float32)
    depth = np.full((48, 64), 2.0, np.float32)
    res = render(clean, depth, params, bank=bank)
    assert res.snow_alpha is not None and res.snow_alpha.max() > 0.2
    batch = render_batch_torch(
        torch.from_numpy(clean).permute(2, 0, 1)[None], torch.from_numpy(depth)[None, None], [params], bank=bank
    )
    assert np.abs(batch.degraded[0].permute(1, 2, 0).numpy() - res.degraded).max() < 1 / 255


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("volume_m", (2.0, 1.0), "volume_m"),
        ("volume_m", (0.0, 1.0), "volume_m"),
        ("focus_m", 0.0, "focus_m"),
        ("defocus_px", -1.0, "defocus_px"),
        ("layers", 0, "layers"),
        ("lamp", -0.1, "lamp"),
        ("motion_px", (5.0, 1.0), "motion_px"),
    ],
)
def test_bad_volume_options_are_refused(field: str, value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        SnowConfig(**{field: value})  # type: ignore[arg-type]


def test_a_lamp_needs_volume_snow() -> None:
    with pytest.raises(ValueError, match=r"lamp: .*set volume_m"):
        SnowConfig(lamp=0.2)
    assert SnowConfig(lamp=0.2, volume_m=(0.3, 3.0)).lamp == 0.2


def test_forward_scattering_blurs_far_layers_more() -> None:
    p = _vol(n=4000, focus_m=1.0)
    lay = snow_layout(p, 50, 64, 48)
    plain = layer_plan(p, lay, 64, 48)
    fs = layer_plan(p, lay, 64, 48, scatter=(0.5, 1.0, 0.3))
    assert all(layer.scatter_weight == 0 for layer in plain)
    z = [1 / np.mean(1 / layer.layout.distance_m) for layer in fs]
    weights = [layer.scatter_weight for layer in fs]
    sigmas = [layer.scatter_px for layer in fs]
    assert weights == sorted(weights, reverse=True) and sigmas == sorted(sigmas, reverse=True)  # far first
    assert all(0 < w < 1 for w in weights) and z == sorted(z, reverse=True)
    bank = make_bank(colour=(255, 255, 255), sizes=(2,))
    img = np.zeros((48, 64, 3), np.float32)
    far = dataclasses.replace(_vol(n=30), volume_m=(3.0, 3.5), defocus_px=0.0)
    _, sharp = composite_snow(img, far, bank)
    _, soft = composite_snow(img, far, bank, scatter=(0.5, 0.3, 0.5))
    assert soft.max() < 0.8 * sharp.max()  # the same particles, spread wider
    assert 0.8 * sharp.sum() < soft.sum() <= 1.01 * sharp.sum()
