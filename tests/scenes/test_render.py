"""Renderer contract: shapes/dtypes/ranges, determinism, numpy == torch, textures, errors."""

from __future__ import annotations

import numpy as np
import pytest

from murk.rng import derive_seed
from murk.scenes import (
    IMAGE_TEXTURE_PX,
    SceneConfig,
    prepare_image_texture,
    render_scene,
    render_scenes_torch,
    sample_scene,
)

from .conftest import make_scene

SIZE = (80, 60)


@pytest.fixture(scope="module")
def scenes():
    return [sample_scene(derive_seed(2026, i)) for i in range(12)]


def test_output_contract_and_depth_range(scenes) -> None:
    lows, highs = [], []
    for p in scenes:
        rgb, dist = render_scene(p, SIZE)
        assert rgb.shape == (60, 80, 3) and rgb.dtype == np.float32
        assert dist.shape == (60, 80) and dist.dtype == np.float32
        assert np.isfinite(rgb).all() and rgb.min() >= 0.0 and rgb.max() <= 1.0
        assert np.isfinite(dist).all()
        assert dist.min() >= p.near_m and dist.max() <= p.far_m
        assert rgb.std() > 0.02  # not a flat image
        lows.append(float(dist.min()))
        highs.append(float(dist.max()))
    # Across scenes the distances span the range of the synthesis (0.3-15 m): close views and open water.
    assert min(lows) < 1.5
    assert max(highs) == 15.0


def test_same_seed_same_bytes() -> None:
    a = sample_scene(derive_seed(5, 3))
    b = sample_scene(derive_seed(5, 3))
    assert a == b
    rgb_a, dist_a = render_scene(a, SIZE)
    rgb_b, dist_b = render_scene(b, SIZE)
    assert rgb_a.tobytes() == rgb_b.tobytes() and dist_a.tobytes() == dist_b.tobytes()
    c = sample_scene(derive_seed(5, 4))
    assert c != a
    assert not np.array_equal(render_scene(c, SIZE)[1], dist_a)


def test_numpy_equals_torch(scenes, torch_cpu) -> None:
    # One batch of differently-shaped scenes (padding per primitive type) against the numpy renderer.
    scenes = scenes[:6]
    rgb_t, dist_t = render_scenes_torch(scenes, SIZE, "cpu")
    assert rgb_t.shape == (len(scenes), 3, 60, 80) and dist_t.shape == (len(scenes), 1, 60, 80)
    assert rgb_t.dtype == torch_cpu.float32 and dist_t.dtype == torch_cpu.float32
    for i, p in enumerate(scenes):
        rgb, dist = render_scene(p, SIZE)
        dt = dist_t[i, 0].numpy()
        rt = rgb_t[i].permute(1, 2, 0).numpy()
        close = np.abs(dt - dist) <= 1e-4 * np.maximum(dist, 1.0)
        # Float32 rounding can flip the winner of a tie at a few silhouette pixels, nothing more.
        assert close.mean() > 0.998, (i, close.mean())
        diff = np.abs(rt - rgb).max(axis=-1)
        assert np.median(diff) < 1e-5
        assert (diff[close] > 2e-3).mean() < 0.002, i


def test_torch_matches_single_scene_batches(scenes, torch_cpu) -> None:
    both_rgb, both_dist = render_scenes_torch([scenes[2], scenes[3]], SIZE, "cpu")
    one_rgb, one_dist = render_scenes_torch([scenes[3]], SIZE, "cpu")
    torch_cpu.testing.assert_close(both_dist[1:2], one_dist, rtol=1e-6, atol=1e-6)
    torch_cpu.testing.assert_close(both_rgb[1:2], one_rgb, rtol=1e-5, atol=1e-5)


@pytest.mark.gpu
def test_torch_cuda_equals_cpu(scenes) -> None:
    torch = pytest.importorskip("torch")
    if not torch.cuda.is_available():
        pytest.skip("no CUDA device")
    rgb_c, dist_c = render_scenes_torch(scenes, SIZE, "cpu")
    rgb_g, dist_g = render_scenes_torch(scenes, SIZE, "cuda")
    assert dist_g.device.type == "cuda"
    close = (dist_g.cpu() - dist_c).abs() <= 1e-4
    assert close.float().mean() > 0.998
    assert (rgb_g.cpu() - rgb_c).abs().median() < 1e-5


def test_image_textures_are_used() -> None:
    rng = np.random.default_rng(0)
    img = rng.random((300, 400, 3)).astype(np.float32)
    tex = prepare_image_texture(img)
    assert tex.shape == (IMAGE_TEXTURE_PX, IMAGE_TEXTURE_PX, 3)
    cfg = SceneConfig(texture_names=("noise.png",), texture_probability=1.0)
    p = sample_scene(7, cfg)
    assert any(m.texture == "noise.png" for m in p.materials)
    rgb, _ = render_scene(p, SIZE, textures={"noise.png": tex})
    plain = sample_scene(7, SceneConfig(texture_names=("noise.png",), texture_probability=0.0))
    assert all(m.texture is None for m in plain.materials)
    assert np.isfinite(rgb).all()
    with pytest.raises(ValueError, match=r"textures: the scene uses image texture 'noise\.png'"):
        render_scene(p, SIZE)
    with pytest.raises(ValueError, match=r"textures\['noise\.png'\]: expected a \(256, 256, 3\)"):
        render_scene(p, SIZE, textures={"noise.png": img})


def test_image_textures_numpy_equals_torch(torch_cpu) -> None:
    tex = prepare_image_texture(np.random.default_rng(1).random((64, 64, 3)).astype(np.float32))
    cfg = SceneConfig(texture_names=("t.png",), texture_probability=1.0)
    p = sample_scene(3, cfg)
    rgb, _ = render_scene(p, SIZE, textures={"t.png": tex})
    rgb_t, _ = render_scenes_torch([p], SIZE, "cpu", textures={"t.png": tex})
    diff = np.abs(rgb_t[0].permute(1, 2, 0).numpy() - rgb).max(axis=-1)
    assert np.median(diff) < 1e-5 and (diff > 2e-3).mean() < 0.005


def test_clear_air_lighting_is_plausible(scenes) -> None:
    # No water in the clean image: colours stay balanced (no blue-green cast) and mid-toned on average.
    means = np.array([render_scene(p, SIZE)[0].reshape(-1, 3).mean(axis=0) for p in scenes])
    assert 0.2 < means.mean() < 0.75
    assert np.abs(means[:, 2] - means[:, 0]).mean() < 0.12


def test_errors() -> None:
    p = make_scene()
    with pytest.raises(TypeError, match="params: expected SceneParams"):
        render_scene({"camera": 1}, SIZE)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"size: expected \(width, height\)"):
        render_scene(p, 64)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="size: expected two ints"):
        render_scene(p, (64.0, 48))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"size: expected \(width, height\) with 8 <= each <= 16384"):
        render_scene(p, (4, 48))
    with pytest.raises(TypeError, match="textures: expected a mapping"):
        render_scene(p, SIZE, textures=[1])  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="scenes: expected a non-empty sequence"):
        render_scenes_torch([], SIZE)
    with pytest.raises(TypeError, match=r"scenes\[1\]: expected SceneParams"):
        render_scenes_torch([p, "x"], SIZE)  # type: ignore[list-item]
