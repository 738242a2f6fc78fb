"""Training-data options of the scenes source: scene_saturation and scene_water_background."""

from __future__ import annotations

import numpy as np
import pytest

from murk.scenes import SceneConfig, sample_scene
from murk.train.config import DataConfig
from murk.train.scenes_source import SceneDataset, scale_contrast, scale_saturation


def test_scale_saturation_keeps_luma_and_scales_chroma() -> None:
    rgb = np.array([[[0.5, 0.4, 0.3]]], np.float32)
    y = float(rgb[0, 0] @ np.array([0.299, 0.587, 0.114], np.float32))
    out = scale_saturation(rgb, 1.5)
    np.testing.assert_allclose(out[0, 0], y + 1.5 * (rgb[0, 0] - y), atol=1e-6)
    np.testing.assert_allclose(scale_saturation(rgb, 1.0), rgb, atol=1e-7)


def test_scale_contrast_stretches_around_the_mean_luma() -> None:
    rgb = np.array([[[0.2, 0.3, 0.4], [0.6, 0.5, 0.4]]], np.float32)
    m = float((rgb @ np.array([0.299, 0.587, 0.114], np.float32)).mean())
    np.testing.assert_allclose(scale_contrast(rgb, 1.5), np.clip(m + 1.5 * (rgb - m), 0, 1), atol=1e-6)
    np.testing.assert_allclose(scale_contrast(rgb, 1.0), rgb, atol=1e-7)


def test_contrast_raises_the_luma_spread_of_a_scene() -> None:
    plain = SceneDataset([2], (32, 64), seed=1)[0]["clean"].numpy()
    stretched = SceneDataset([2], (32, 64), seed=1, contrast=(1.6, 1.6))[0]["clean"].numpy()
    assert stretched.std() > 1.3 * plain.std()


def test_saturation_is_fixed_per_scene_and_off_by_default() -> None:
    plain = SceneDataset([3], (32, 64), seed=1)[0]["clean"]
    vivid = SceneDataset([3], (32, 64), seed=1, saturation=(1.5, 1.5))[0]["clean"]
    again = SceneDataset([3], (32, 64), seed=1, saturation=(1.5, 1.5))[0]["clean"]
    assert not np.allclose(plain.numpy(), vivid.numpy()) and np.array_equal(vivid.numpy(), again.numpy())
    assert plain.std(dim=0).mean() < vivid.std(dim=0).mean()  # channels further apart: more saturated


def test_water_background_draws_come_last_and_colour_the_open_water() -> None:
    for seed in range(8):
        grey = sample_scene(seed, SceneConfig())
        water = sample_scene(seed, SceneConfig(water_background=1.0))
        assert grey.objects == water.objects and grey.camera == water.camera  # nothing else moves
        lo, hi = water.lighting.background_low_rgb, water.lighting.background_high_rgb
        assert hi[2] > hi[0] and hi[1] > hi[0]  # blue-green water, red absorbed
        assert all(a < b for a, b in zip(lo, hi, strict=True))
    assert sample_scene(4, SceneConfig(water_background=0.0)) == sample_scene(4, SceneConfig())


def test_bad_option_values_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="water_background"):
        SceneConfig(water_background=2.0)
    with pytest.raises(ValueError, match="scene_saturation"):
        DataConfig(source="scenes", crop_hw=(32, 64), scene_saturation=(2.0, 1.0))
    with pytest.raises(ValueError, match="scene_contrast"):
        DataConfig(source="scenes", crop_hw=(32, 64), scene_contrast=(0.5, -1.0))
    with pytest.raises(ValueError, match="scene_water_background"):
        DataConfig(source="scenes", crop_hw=(32, 64), scene_water_background=-0.5)
