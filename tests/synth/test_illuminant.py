"""medium.illuminant: the scene lit by daylight that came down through the water (drawn only when switched on)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from murk._config import merge
from murk.physics.jerlov import residual_ratio
from murk.synth.config import MediumConfig, SynthConfig
from murk.synth.params import sample_illuminant, sample_medium, sample_variant, variant_from_dict, variant_to_dict
from murk.synth.render import render, render_batch_torch


def test_off_by_default_and_switching_it_on_moves_no_other_draw() -> None:
    stages = {"stages": ["basic", "forward_scatter", "camera"]}
    for seed in range(6):
        plain = sample_variant(seed, merge(SynthConfig(), stages))
        lit = sample_variant(seed, merge(SynthConfig(), {**stages, "medium": {"illuminant": [0.5, 1.0]}}))
        assert plain.medium is not None and lit.medium is not None and plain.medium.illuminant_rgb is None
        assert lit.medium.illuminant_rgb is not None
        assert dataclasses.replace(lit.medium, illuminant_rgb=None) == plain.medium
        assert lit.camera == plain.camera and lit.forward_scatter == plain.forward_scatter


def test_the_light_is_the_downwelling_colour_at_depth_to_a_power() -> None:
    cfg = MediumConfig(water_types=("3C",), illuminant=(1.0, 1.0))
    m = sample_illuminant(0, cfg, sample_medium(np.random.default_rng(3), cfg))
    down = residual_ratio("3C") ** m.vertical_depth_m
    np.testing.assert_allclose(m.illuminant_rgb, down / down.max(), rtol=1e-12)
    assert max(m.illuminant_rgb) == pytest.approx(1.0)  # type: ignore[arg-type]
    half = sample_illuminant(0, MediumConfig(water_types=("3C",), illuminant=(0.5, 0.5)), m)
    np.testing.assert_allclose(half.illuminant_rgb, np.sqrt(down / down.max()), rtol=1e-12)
    off = sample_medium(np.random.default_rng(3), MediumConfig(water_types=("3C",)))
    assert sample_illuminant(0, MediumConfig(water_types=("3C",)), off) is off  # off: nothing drawn or changed
    assert MediumConfig(illuminant=[0.2, 0.4]).illuminant == (0.2, 0.4)  # type: ignore[arg-type]


def test_render_lights_the_clean_scene_before_eq1_in_both_twins() -> None:
    cfg = merge(SynthConfig(), {"stages": ["basic"], "medium": {"illuminant": [1.0, 1.0], "water_types": ["5C"]}})
    p = sample_variant(11, cfg)
    assert variant_from_dict(variant_to_dict(p)) == p
    rng = np.random.default_rng(0)
    clean = rng.random((24, 32, 3)).astype(np.float32)
    depth = (1.0 + rng.random((24, 32))).astype(np.float32)
    m = p.medium
    assert m is not None and m.illuminant_rgb is not None
    off = merge(cfg, {"medium": {"illuminant": [0.0, 0.0]}})
    white = render(clean * np.asarray(m.illuminant_rgb, np.float32), depth, sample_variant(11, off)).degraded
    lit = render(clean, depth, p).degraded
    np.testing.assert_allclose(lit, white, atol=1e-6)  # lighting the scene = rendering a scene lit so
    batch = render_batch_torch(
        torch.from_numpy(clean).permute(2, 0, 1)[None], torch.from_numpy(depth)[None, None], [p]
    ).degraded
    np.testing.assert_allclose(batch[0].permute(1, 2, 0).numpy(), lit, atol=1 / 255)


def test_bad_ranges_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="illuminant"):
        MediumConfig(illuminant=(0.5, 2.0))
    with pytest.raises(ValueError, match="illuminant"):
        MediumConfig(illuminant=(0.8, 0.2))
    with pytest.raises(ValueError, match="ambient_override"):
        MediumConfig(illuminant=(0.0, 1.0), ambient_override=(0.1, 0.2, 0.3))
