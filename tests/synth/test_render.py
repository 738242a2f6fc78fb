from __future__ import annotations

import numpy as np
import pytest
import torch

from murk._config import merge
from murk.data import default_snow_bank
from murk.errors import ShapeError
from murk.snow.bank import load_bank
from murk.snow.composite import sample_snow
from murk.synth.config import SynthConfig
from murk.synth.params import sample_variant
from murk.synth.render import depth_range, render, render_batch_torch


@pytest.fixture(scope="module")
def scene() -> tuple[np.ndarray, np.ndarray]:
    g = np.random.default_rng(5)
    clean = g.random((36, 44, 3)).astype(np.float32)
    yy, xx = np.mgrid[0:36, 0:44]
    depth = (1.0 + 0.1 * xx + 0.05 * yy).astype(np.float32)
    return clean, depth


def test_render_is_deterministic_and_in_range(scene: tuple[np.ndarray, np.ndarray]) -> None:
    clean, depth = scene
    p = sample_variant(3, SynthConfig())
    a, b = render(clean, depth, p), render(clean, depth, p)
    assert a.degraded.tobytes() == b.degraded.tobytes()
    assert a.degraded.dtype == np.float32 and 0.0 <= a.degraded.min() and a.degraded.max() <= 1.0
    assert a.sigma_max_px == pytest.approx(0.5 + 0.15 * float(a.dist_m.max()), rel=1e-5)
    assert a.dist_m.max() == pytest.approx(p.medium.far_m, rel=1e-5)


def test_intermediates(scene: tuple[np.ndarray, np.ndarray]) -> None:
    clean, depth = scene
    r = render(clean, depth, sample_variant(1, SynthConfig()), keep_intermediate=True)
    assert r.basic is not None and r.transmission is not None and r.transmission.shape == clean.shape
    assert not np.allclose(r.basic, r.degraded)  # forward scattering changed the Eq. (1) image
    only_basic = render(clean, depth, sample_variant(1, merge(SynthConfig(), {"stages": ["basic"]})))
    np.testing.assert_allclose(only_basic.degraded, r.basic, atol=1e-7)


def test_forward_scatter_alone_is_eqs_5_6_on_the_clean_image(scene: tuple[np.ndarray, np.ndarray]) -> None:
    from murk.physics.forward_scatter import forward_scatter_approx

    clean, depth = scene
    p = sample_variant(0, merge(SynthConfig(), {"stages": ["forward_scatter"]}))
    r = render(clean, depth, p)
    expect, _ = forward_scatter_approx(clean, r.dist_m)
    np.testing.assert_allclose(r.degraded, np.clip(expect, 0, 1), atol=1e-7)


def test_render_errors(scene: tuple[np.ndarray, np.ndarray]) -> None:
    clean, depth = scene
    p = sample_variant(0, SynthConfig())
    with pytest.raises(ShapeError, match=r"depth_m: expected shape \(36, 44\)"):
        render(clean, depth[:-1], p)
    bad = depth.copy()
    bad[0, 0] = 0
    with pytest.raises(ValueError, match="depth_m: expected finite depth > 0 everywhere"):
        render(clean, bad, p)
    with pytest.raises(TypeError, match="clean: expected a float image"):
        render((clean * 255).astype(np.uint8), depth, p)


def test_a_depth_range_given_once_renders_the_same_bits(scene: tuple[np.ndarray, np.ndarray]) -> None:
    """The runner checks an image's depth once and passes its range to every variant (issue 29)."""
    clean, depth = scene
    span = depth_range(depth)
    assert span == (float(depth.min()), float(depth.max()))
    for seed in range(6):
        for mode in ("normalized", "metric"):
            p = sample_variant(seed, merge(SynthConfig(), {"medium": {"distance_mode": mode}}))
            a, b = render(clean, depth, p), render(clean, depth, p, depth_range_m=span)
            assert a.degraded.tobytes() == b.degraded.tobytes() and a.dist_m.tobytes() == b.dist_m.tobytes()
            assert a.dist_range_m == b.dist_range_m == (float(a.dist_m.min()), float(a.dist_m.max()))
    p = sample_variant(0, SynthConfig())
    for span_bad in ((0.0, 2.0), (3.0, 2.0), (1.0, np.inf), (np.nan, 2.0)):
        with pytest.raises(ValueError, match="depth_range_m: expected 0 < min <= max < inf"):
            render(clean, depth, p, depth_range_m=span_bad)
    for bad in (0.0, -1.0, np.nan, np.inf):
        broken = depth.copy()
        broken[3, 4] = bad
        with pytest.raises(ValueError, match="depth_m: expected finite depth > 0 everywhere"):
            depth_range(broken)


@pytest.mark.parametrize("stages", [("basic", "forward_scatter"), ("basic", "forward_scatter", "marine_snow")])
def test_torch_batch_equals_numpy_within_one_level(scene: tuple[np.ndarray, np.ndarray], stages: tuple) -> None:
    clean, depth = scene
    bank = load_bank(default_snow_bank())
    cfg = merge(SynthConfig(), {"stages": list(stages)})
    sampler = (lambda g: sample_snow(g, bank)) if "marine_snow" in stages else None
    params = [sample_variant(s, cfg, snow_sampler=sampler) for s in range(4)]
    out = render_batch_torch(
        torch.from_numpy(clean).permute(2, 0, 1)[None].repeat(4, 1, 1, 1),
        torch.from_numpy(depth)[None, None].repeat(4, 1, 1, 1),
        params,
        bank=bank,
    )
    for i, p in enumerate(params):
        ref = render(clean, depth, p, bank=bank)
        assert np.abs(out.degraded[i].permute(1, 2, 0).numpy() - ref.degraded).max() < 1 / 255
        if ref.snow_alpha is not None:
            assert np.abs(out.snow_alpha[i, 0].numpy() - ref.snow_alpha).max() < 1 / 255


def test_torch_batch_errors(scene: tuple[np.ndarray, np.ndarray]) -> None:
    clean, depth = scene
    c = torch.from_numpy(clean).permute(2, 0, 1)[None]
    d = torch.from_numpy(depth)[None, None]
    p = sample_variant(0, SynthConfig())
    with pytest.raises(ValueError, match="params: expected 1 variants"):
        render_batch_torch(c, d, [p, p])
    with pytest.raises(ShapeError, match="depth_m: expected"):
        render_batch_torch(c, d[..., :-1], [p])
    q = sample_variant(0, merge(SynthConfig(), {"stages": ["basic"]}))
    with pytest.raises(ValueError, match="must enable the same stages"):
        render_batch_torch(c.repeat(2, 1, 1, 1), d.repeat(2, 1, 1, 1), [p, q])
