from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from murk._config import merge
from murk.errors import InputFileError
from murk.io import DepthOptions, discover
from murk.synth.config import SynthConfig
from murk.synth.render import render
from murk.synth.runner import run_synthesis
from murk.train.augment import (
    AugmentConfig,
    AugmentParams,
    apply_augment,
    augment_map,
    centre_crop,
    sample_augment,
)
from murk.train.data import (
    CleanRGBDDataset,
    OnlineDegrader,
    PairDataset,
    items_from_list,
    items_from_synth_folder,
    split_by_stem,
)


def _batch(b: int = 2, h: int = 32, w: int = 48) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(0)
    return (
        torch.rand(b, 3, h, w, generator=g),
        torch.rand(b, 3, h, w, generator=g),
        torch.rand(b, 1, h, w, generator=g) * 5 + 1,
    )


def _params(b: int, angle: float = 0.0, flip: bool = False, color: bool = False) -> AugmentParams:
    return AugmentParams(
        torch.full((b,), angle, dtype=torch.float64),
        torch.full((b,), flip),
        torch.full((b,), color),
        torch.full((b,), 0.5, dtype=torch.float64),
        torch.ones(b, 3, dtype=torch.float64),
    )


def test_identity_flip_and_colour_only_on_input() -> None:
    x, y, d = _batch()
    cfg = AugmentConfig()
    a, b, c = apply_augment(x, y, d, _params(2), cfg)
    torch.testing.assert_close(a, x, atol=1e-5, rtol=0)
    torch.testing.assert_close(c, d)
    a, b, c = apply_augment(x, y, d, _params(2, flip=True), cfg)
    torch.testing.assert_close(a, x.flip(-1), atol=1e-5, rtol=0)
    torch.testing.assert_close(c, d.flip(-1))
    a, b, _ = apply_augment(x, y, d, _params(2, color=True), cfg)
    torch.testing.assert_close(a, (x * 0.5), atol=1e-5, rtol=0)
    torch.testing.assert_close(b, y, atol=1e-5, rtol=0)  # the target keeps its colours


def test_rotation_zeroes_corners_and_keeps_depth_values() -> None:
    x, y, d = _batch()
    d = torch.randint(1, 5, d.shape).float()
    _, _, c = apply_augment(x, y, d, _params(2, angle=3.5), AugmentConfig())
    assert float(c[0, 0, 0, 0]) == 0.0  # corner becomes invalid
    assert set(torch.unique(c).tolist()) <= {0.0, 1.0, 2.0, 3.0, 4.0}  # nearest: no blended depths


def test_sampling_is_reproducible_and_in_range() -> None:
    cfg = AugmentConfig()
    p1 = sample_augment(500, cfg, torch.Generator().manual_seed(3))
    p2 = sample_augment(500, cfg, torch.Generator().manual_seed(3))
    assert torch.equal(p1.angle_deg, p2.angle_deg) and torch.equal(p1.gain, p2.gain)
    assert float(p1.angle_deg.abs().max()) <= 3.5 and 0.4 < float(p1.flip.double().mean()) < 0.6
    assert 0.6 < float(p1.color.double().mean()) < 0.8
    assert 0.5 <= float(p1.brightness.min()) and float(p1.brightness.max()) <= 1.1


def test_depth_over_600_m_is_invalid() -> None:
    x, y, d = _batch(1)
    d[..., 0, 0] = 700.0
    _, _, c = apply_augment(x, y, d, _params(1), AugmentConfig())
    assert float(c[0, 0, 0, 0]) == 0.0


def test_centre_crop() -> None:
    a = np.arange(60).reshape(6, 10)
    (c,) = centre_crop([a], (2, 4))
    assert c.tolist() == [[23, 24, 25, 26], [33, 34, 35, 36]]
    with pytest.raises(ValueError, match=r"x\.png: image 10x6 is smaller than the training size 12x2"):
        centre_crop([a], (2, 12), source="x.png")


def test_synth_folder_and_list_sources(small_rgbd: Path, tmp_path: Path) -> None:
    sources, _ = discover(small_rgbd)
    run_synthesis(sources, tmp_path, SynthConfig(variants=2))
    items = items_from_synth_folder(tmp_path)
    assert len(items) == 4 and items[0].stem == "a"
    same = items_from_list(tmp_path / "train.txt")
    assert [(i.input_path, i.depth_scale) for i in same] == [(i.input_path, 1000.0) for i in items]
    ds = PairDataset(items, (32, 48))
    s = ds[1]
    assert s["input"].shape == (3, 32, 48) and s["depth"].shape == (1, 32, 48) and float(s["depth"].min()) > 0
    (tmp_path / "bad.txt").write_text("a.png b.png c.png\n")
    with pytest.raises(
        InputFileError, match=r"bad\.txt: line 1: expected '<input> <enhanced_gt> <depth_gt> <depth_scale>'"
    ):
        items_from_list(tmp_path / "bad.txt")
    with pytest.raises(InputFileError, match=r"no manifest\.jsonl"):
        items_from_synth_folder(small_rgbd)


def test_split_by_stem_keeps_variants_together() -> None:
    stems = [f"s{i // 8}" for i in range(80)]
    tr, va = split_by_stem(stems, 0.2, seed=0)
    assert len(va) == 16 and not ({stems[i] for i in tr} & {stems[i] for i in va})
    assert split_by_stem(stems, 0.2, seed=0) == (tr, va)
    assert split_by_stem(stems, 0.0, seed=0) == (list(range(80)), [])


@pytest.mark.parametrize("stages", [["basic", "forward_scatter"], ["basic", "forward_scatter", "marine_snow"]])
def test_online_batches_equal_numpy_synthesis(small_rgbd: Path, stages: list[str]) -> None:
    sources, _ = discover(small_rgbd)
    cfg = merge(SynthConfig(), {"stages": stages})
    ds = CleanRGBDDataset(sources, (40, 56), DepthOptions())
    batch = [ds[0], ds[1]]
    clean = torch.stack([b["clean"] for b in batch])
    depth = torch.stack([b["depth_filled"] for b in batch])
    deg = OnlineDegrader(cfg, seed=11)
    out = deg(clean, depth, epoch=3, indices=[0, 1])
    for i, p in enumerate(deg.params(3, [0, 1])):
        ref = render(clean[i].permute(1, 2, 0).numpy(), depth[i, 0].numpy(), p, bank=deg.bank).degraded
        assert np.abs(out[i].permute(1, 2, 0).numpy() - ref).max() < 1 / 255
    assert deg.params(3, [0]) == deg.params(3, [0]) and deg.params(4, [0]) != deg.params(3, [0])


def test_cached_scenes_equal_rendered_scenes() -> None:
    """data.cache_scenes renders each scene once; what it returns equals a fresh render and is a copy."""
    from murk.train.scenes_source import SceneDataset

    fresh = SceneDataset([3, 5], (32, 64), seed=1)
    cached = SceneDataset([3, 5], (32, 64), seed=1, cache=True)
    for i in (0, 1, 0):
        a, b = fresh[i], cached[i]
        for k in ("clean", "depth", "depth_filled"):
            assert torch.equal(a[k], b[k])
    cached[0]["clean"].zero_()  # callers may modify what they get
    assert torch.equal(cached[0]["clean"], fresh[0]["clean"])


def test_scene_scale_windows_are_fixed_per_scene_and_inside_the_render() -> None:
    """data.scene_scale: render s x larger, cut a crop-sized window; (1, 1) is the old centre crop."""
    from murk.rng import derive_seed
    from murk.scenes import render_scene, sample_scene
    from murk.train.scenes_source import SceneDataset, render_size, scene_window

    crop = (32, 64)
    w, h = render_size(crop)
    assert scene_window(1, 3, crop, (1.0, 1.0)) == ((w, h), ((h - 32) // 2, (w - 64) // 2))
    sizes = set()
    for index in range(20):
        (ws, hs), (y0, x0) = scene_window(1, index, crop, (1.5, 2.5))
        assert scene_window(1, index, crop, (1.5, 2.5)) == ((ws, hs), (y0, x0))  # fixed per scene
        assert 1.5 * w - 1 <= ws <= 2.5 * w + 1 and 1.5 * h - 1 <= hs <= 2.5 * h + 1
        assert 0 <= y0 <= hs - 32 and 0 <= x0 <= ws - 64
        sizes.add(ws)
    assert len(sizes) > 10  # the scale varies between scenes

    ds = SceneDataset([3], crop, seed=1, scale=(1.5, 2.5))
    (ws, hs), (y0, x0) = scene_window(1, 3, crop, (1.5, 2.5))
    rgb, dist = render_scene(sample_scene(derive_seed(1, 3)), (ws, hs))
    item = ds[0]
    assert item["clean"].shape == (3, 32, 64) and item["depth"].shape == (1, 32, 64)
    np.testing.assert_array_equal(item["clean"].numpy(), rgb[y0 : y0 + 32, x0 : x0 + 64].transpose(2, 0, 1))
    np.testing.assert_array_equal(item["depth"][0].numpy(), dist[y0 : y0 + 32, x0 : x0 + 64])


def test_scene_scale_is_validated() -> None:
    from murk.train.config import DataConfig

    with pytest.raises(ValueError, match="scene_scale"):
        DataConfig(scene_scale=(0.5, 2.0))
    with pytest.raises(ValueError, match="scene_scale"):
        DataConfig(scene_scale=(2.0, 1.5))


def test_vflip_flips_input_target_and_depth_up_down_and_draws_last() -> None:
    x, y, d = _batch()
    cfg = AugmentConfig(color_p=0.0)
    params = replace(_params(2), vflip=torch.tensor([True, False]))
    a, b, c = apply_augment(x, y, d, params, cfg)
    torch.testing.assert_close(a[0], x[0].flip(-2), atol=1e-5, rtol=0)
    torch.testing.assert_close(b[0], y[0].flip(-2), atol=1e-5, rtol=0)
    torch.testing.assert_close(c[0], d[0].flip(-2))
    torch.testing.assert_close(a[1], x[1], atol=1e-5, rtol=0)
    drawn = {p: sample_augment(64, AugmentConfig(vflip_p=p), torch.Generator().manual_seed(5)) for p in (0.0, 1.0)}
    assert not drawn[0.0].vflip.any() and drawn[1.0].vflip.all()
    torch.testing.assert_close(augment_map(d, params, cfg)[0], d[0].flip(-2))  # the snow alpha follows the images
    g = torch.Generator().manual_seed(5)  # the other draws are those of the draw order before it existed
    old = [torch.rand(64, generator=g, dtype=torch.float64) for _ in range(4)]
    gain = 0.9 + 0.2 * torch.rand(64, 3, generator=g, dtype=torch.float64)
    torch.testing.assert_close(drawn[0.0].angle_deg, -3.5 + 7.0 * old[0])
    torch.testing.assert_close(drawn[0.0].gain, gain)
    for name in ("flip_p", "color_p", "vflip_p"):
        with pytest.raises(ValueError, match=name):
            AugmentConfig(**{name: 1.5})
