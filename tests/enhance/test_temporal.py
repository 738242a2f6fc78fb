"""Temporal averaging of per-frame estimates over the frames of a video (``--temporal``): ``post``'s equalisation
tables and ``lite``'s coefficient maps."""

from __future__ import annotations

import itertools
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from murk.enhance.equalize import equalize_lut
from murk.enhance.frame_job import enhance_frames
from murk.enhance.job_common import OutputOptions
from murk.enhance.post import PostRestorer, post_process, post_process_torch
from murk.enhance.restorer import create
from murk.enhance.temporal import FrameEMA

from ._enhance_helpers import FakeSource

TWIN_ATOL = 1e-6  # as tests/enhance/test_post.py: equalisation bitwise equal, LoG sums in another order


def _scene(rng: np.random.Generator, h: int = 48, w: int = 64) -> np.ndarray:
    img = cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 2.0)
    img = (img - img.min()) / (img.max() - img.min())
    return (0.15 + 0.5 * img).astype(np.float32)


def _steady_scene_with_a_passing_object(n: int) -> list[np.ndarray]:
    """A still, low-contrast scene; a bright disc grows and shrinks in a corner (a fish, a diver's torch). The
    histogram shifts, so per-frame equalisation changes the brightness of the whole unchanged background."""
    base = _scene(np.random.default_rng(5))
    frames = []
    for i in range(n):
        f = base.copy()
        radius = int(4 + 14 * abs(np.sin(np.pi * i / 8)))
        cv2.circle(f, (50, 12), radius, (0.95, 0.95, 0.95), -1)
        frames.append(f)
    return frames


def _background_means(frames: list[np.ndarray]) -> np.ndarray:
    return np.array([f[24:, :32].mean() for f in frames])  # far from the disc


def test_smoother_follows_the_recursion_and_starts_at_the_first_table(rng: np.random.Generator) -> None:
    s = FrameEMA(0.75)
    luts = [equalize_lut(rng.integers(0, 50, 256))[None] for _ in range(4)]
    out = [s(lut).copy() for lut in luts]
    np.testing.assert_array_equal(out[0], luts[0])
    for t in range(1, 4):
        np.testing.assert_allclose(out[t], 0.75 * out[t - 1] + 0.25 * luts[t], rtol=1e-6)
    assert np.all(np.diff(out[3], axis=-1) >= 0)  # a mix of monotone tables stays monotone
    s.reset()
    np.testing.assert_array_equal(s(luts[2]), luts[2])


def test_smoother_numpy_and_torch_twins_are_equal(rng: np.random.Generator) -> None:
    luts = np.stack([equalize_lut(rng.integers(0, 50, 256))[None] for _ in range(5)])  # (5 frames, 1, 256)
    a, b = FrameEMA(0.8), FrameEMA(0.8)
    one_by_one = np.stack([a(lut) for lut in luts])
    batched = b(torch.from_numpy(luts)).numpy()  # a batch holds consecutive frames, oldest first
    np.testing.assert_array_equal(one_by_one, batched)


def test_smoothing_weight_is_validated() -> None:
    for bad in (-0.1, 1.0, 2.0, True):
        with pytest.raises(ValueError, match="temporal"):
            FrameEMA(bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="CLAHE"):
        create("post", he="clahe", temporal=0.5)


def test_an_identity_hook_changes_nothing(rng: np.random.Generator) -> None:
    img = _scene(rng)
    for he in ("y", "rgb"):
        np.testing.assert_array_equal(post_process(img, he=he, tables=lambda t: t), post_process(img, he=he))
        x = torch.from_numpy(img).permute(2, 0, 1)[None]
        torch.testing.assert_close(
            post_process_torch(x, he=he, tables=lambda t: t), post_process_torch(x, he=he), rtol=0, atol=0
        )


def test_smoothing_acts_only_inside_a_sequence_and_steadies_the_background() -> None:
    frames = _steady_scene_with_a_passing_object(16)
    batch = np.stack(frames)
    plain = PostRestorer().restore(batch).images
    smooth = PostRestorer(temporal=0.8)
    np.testing.assert_array_equal(smooth.restore(batch).images, plain)  # stills: each image on its own
    with smooth.sequence():
        steady = smooth.restore(batch).images
    np.testing.assert_array_equal(steady[0], plain[0])  # the first frame of a video has no history
    flicker_plain = np.abs(np.diff(_background_means(list(plain)))).mean()
    flicker_steady = np.abs(np.diff(_background_means(list(steady)))).mean()
    assert flicker_plain > 2e-3  # the unchanged background does flicker with per-frame equalisation
    assert flicker_steady < 0.4 * flicker_plain
    with smooth.sequence():  # a new video starts afresh
        np.testing.assert_array_equal(smooth.restore(batch[:1]).images[0], plain[0])


@pytest.mark.parametrize("he", ["y", "rgb"])
def test_sequence_numpy_frames_and_torch_batch_agree(he: str) -> None:
    frames = np.stack(_steady_scene_with_a_passing_object(6))
    one = create("post", he=he, temporal=0.7)
    two = create("post", he=he, temporal=0.7)
    with one.sequence():
        by_frame = np.concatenate([one.restore(f[None]).images for f in frames])
    with two.sequence():
        by_batch = two.restore_tensor(torch.from_numpy(frames).permute(0, 3, 1, 2)).images
    np.testing.assert_allclose(by_batch.permute(0, 2, 3, 1).numpy(), by_frame, atol=TWIN_ATOL)


def test_enhance_frames_smooths_each_video_from_its_own_first_frame(tmp_path: Path) -> None:
    frames = [(f * 255).round().astype(np.uint8) for f in _steady_scene_with_a_passing_object(10)]
    restorer = create("post?preset=paper,temporal=0.8")  # compared with PostRestorer's defaults (Eq. 9) below
    opts = OutputOptions(format="png")
    for run in ("a", "b"):  # the same restorer for two inputs: the second starts afresh
        enhance_frames(FakeSource(frames, live=False), restorer, tmp_path / run, opts, batch=3)
    out_a = sorted((tmp_path / "a").glob("*.png"))
    out_b = sorted((tmp_path / "b").glob("*.png"))
    assert len(out_a) == len(out_b) == 10
    for pa, pb in zip(out_a, out_b, strict=True):
        np.testing.assert_array_equal(cv2.imread(str(pa)), cv2.imread(str(pb)))
    reference = PostRestorer(temporal=0.8)
    with reference.sequence():
        expected = reference.restore(np.stack([f.astype(np.float32) / 255 for f in frames])).images
    got = np.stack([cv2.imread(str(p))[:, :, ::-1] for p in out_a]).astype(np.float32) / 255
    assert np.abs(got - expected).max() <= 0.5 / 255 + 1e-6  # 8-bit rounding only
    plain = PostRestorer().restore(np.stack([f.astype(np.float32) / 255 for f in frames])).images
    assert np.abs(got[1:] - plain[1:]).max() > 2 / 255  # the smoothing did act on later frames


@pytest.mark.parametrize("method", ["post?temporal=0.8", "lite+post?temporal=0.8"])
def test_a_resumed_video_job_gives_the_frames_of_an_uninterrupted_one(tmp_path: Path, method: str) -> None:
    frames = [(f * 255).round().astype(np.uint8) for f in _pan(12, 96, 128)]
    opts = OutputOptions(format="png")
    # batch 1: lite's convolutions sum in another order for another batch size (float rounding, not state)
    enhance_frames(FakeSource(frames, live=False), create(method), tmp_path / "whole", opts, batch=1)
    first = enhance_frames(
        FakeSource(frames, live=False), create(method), tmp_path / "resumed", opts, batch=1, max_frames=5
    )
    assert first.processed == 5
    rest = enhance_frames(FakeSource(frames, live=False), create(method), tmp_path / "resumed", opts, batch=1)
    assert (rest.processed, rest.skipped) == (7, 5)
    whole = sorted((tmp_path / "whole").glob("*.png"))
    resumed = sorted((tmp_path / "resumed").glob("*.png"))
    assert [p.name for p in whole] == [p.name for p in resumed] and len(whole) == 12
    for pa, pb in zip(whole, resumed, strict=True):  # byte for byte: the skipped frames fed the running average
        assert pa.read_bytes() == pb.read_bytes(), pa.name
    # Without the replay, frame 5 would start a fresh average: far from the uninterrupted frame.
    fresh = create(method)
    with fresh.sequence():
        restarted = fresh.restore(np.stack([f.astype(np.float32) / 255 for f in frames[5:6]])).images[0]
    got = cv2.imread(str(whole[5]))[:, :, ::-1].astype(np.float32) / 255
    assert np.abs(got - restarted).mean() > 1 / 255


# --- lite: the low-resolution maps --------------------------------------------------------------------------


def _pan(n: int, h: int = 150, w: int = 200) -> np.ndarray:
    """A slow pan (3 px right, 2 px down per frame) over a shipped real image."""
    from murk.data import sample_underwater_images
    from murk.io import read_rgb

    img = read_rgb(sample_underwater_images()[0])
    return np.stack([img[2 * t : 2 * t + h, 3 * t : 3 * t + w] for t in range(n)]).astype(np.float32)


def _aligned_flicker(out: np.ndarray) -> float:
    return float(np.mean([np.abs(a[2:, 3:] - b[:-2, :-3]).mean() for a, b in itertools.pairwise(out)]))


def test_lite_averages_its_maps_inside_a_sequence_only() -> None:
    import torch.nn.functional as F

    from murk.models.lite.network import apply_maps, work_image
    from murk.restore_ops.balance import apply_levels_torch, balance_levels_torch

    frames = _pan(8)  # 150x200: larger than the working area, so the maps come from a downsampled image
    plain = create("lite").restore(frames).images
    lite = create("lite", temporal=0.8)
    np.testing.assert_array_equal(lite.restore(frames).images, plain)  # stills: each frame on its own
    with lite.sequence():
        steady = np.concatenate([lite.restore(f[None]).images for f in frames])  # frame by frame, as a stream
    # The first frame has no history; batch of one vs batch of eight: the convolutions sum in another order.
    np.testing.assert_allclose(steady[0], plain[0], atol=1e-5)
    # The same as LiteNet's own forward with the maps averaged by hand (the torch formula the CUDA path runs), after
    # the input balance of the shipped weights with its levels averaged likewise (issue 27, stage 4).
    x = torch.from_numpy(frames).permute(0, 3, 1, 2)
    pct = lite.input_balance_pct
    assert pct is not None
    levels = balance_levels_torch(x, pct, pct)
    for t in range(1, len(levels)):
        levels[t] = 0.8 * levels[t - 1] + 0.2 * levels[t]
    x = apply_levels_torch(x, levels)
    with torch.no_grad():
        maps = lite.model.maps(work_image(x, lite.work_area_px))
        for t in range(1, len(maps)):
            maps[t] = 0.8 * maps[t - 1] + 0.2 * maps[t]
        ref = apply_maps(F.interpolate(maps, size=x.shape[-2:], mode="bilinear"), x).clamp(0, 1)
    np.testing.assert_allclose(steady, ref.permute(0, 2, 3, 1).numpy(), atol=5e-5)
    assert _aligned_flicker(steady) < 0.7 * _aligned_flicker(plain)
    with lite.sequence():  # a new video starts afresh; a batch of consecutive frames equals frame by frame
        np.testing.assert_allclose(lite.restore(frames).images, steady, atol=1e-5)  # batched convs: float order


def test_one_flag_reaches_both_stages_of_a_chain() -> None:
    chain = create("lite+post", shared={"temporal": 0.7})
    assert [s.temporal_state.weight for s in chain.stages] == [0.7, 0.7]
    with pytest.raises(ValueError, match="temporal"):
        create("jointid", temporal=0.5)
