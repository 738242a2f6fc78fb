"""The 8-bit paths of issue 48 against the float32 paths they replace: ``lite`` on uint8 frames
(:mod:`murk.enhance.lite_u8`), :func:`murk.enhance.frames_u8.restore_frames` (every method, chains), the strip
path of ``post`` (:func:`murk.enhance.post.post_process_strips`), and ``murk enhance`` writing every frame in
order. Reference: the float32 path of this repository before issue 48 (``to_uint(restore(to_float(frame)))``),
which these tests call directly."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import torch.nn.functional as F

from murk.data import sample_underwater_images
from murk.enhance import lite_u8
from murk.enhance.frames_u8 import alone_takes_u8, restore_frames, to_u8
from murk.enhance.job_common import restore_batch
from murk.enhance.post import POST_PRESETS, PostParams, post_process, post_process_strips
from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.io.images import to_float, to_uint
from murk.restore_ops.balance import apply_levels, balance_levels

SIZES = [(640, 480), (1280, 720), (1920, 1080)]


def _frame(w: int, h: int, k: int = 0) -> np.ndarray:
    """A real underwater photograph as a uint8 frame of w x h."""
    image = read_rgb(sample_underwater_images()[k])
    return to_uint(cv2.resize(image, (w, h), interpolation=cv2.INTER_AREA), 8)


def _old(restorer: object, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The float32 path (before issue 48): float output and its uint8 conversion."""
    out = restore_batch(restorer, to_float(frames)).images  # type: ignore[arg-type]
    return out, to_uint(out, 8)


@pytest.fixture(scope="module")
def lite() -> object:
    return create("lite")


@pytest.mark.parametrize(("w", "h"), SIZES)
def test_lite_u8_within_one_grey_level_of_the_float_path(lite: object, w: int, h: int) -> None:
    frames = np.stack([_frame(w, h, 0), _frame(w, h, 3)])
    old_f, old_u8 = _old(lite, frames)
    new_u8 = lite.restore_u8(frames)  # type: ignore[attr-defined]
    new_f = lite.restore_u8(frames, np.float32)  # type: ignore[attr-defined]
    assert new_u8.dtype == np.uint8 and new_u8.shape == frames.shape
    assert np.abs(new_u8.astype(np.int16) - old_u8).max() <= 1
    assert np.mean(new_u8 != old_u8) < 1e-4  # only values within float rounding of a tie differ
    assert np.abs(new_f - old_f).max() < 1e-4
    # lite alone takes the 8-bit path from ALONE_MIN_PX up (or on one torch thread), the float32 path below
    expected = new_u8 if alone_takes_u8(w * h) else old_u8
    assert np.array_equal(restore_frames(lite, frames).images, expected)  # type: ignore[arg-type]


def test_lite_u8_declines_what_it_does_not_cover(lite: object) -> None:
    small = _frame(160, 120)  # the network sees the frame itself
    assert lite.restore_u8(small[None]) is None  # type: ignore[attr-defined]
    assert lite.restore_u8(to_uint(to_float(_frame(640, 480)), 16)[None]) is None  # type: ignore[attr-defined]
    refined = create("lite?refine=0.125")
    assert refined.restore_u8(_frame(640, 480)[None]) is None  # type: ignore[attr-defined]
    # restore_frames then takes the float32 path: the same frames as before
    _, old_u8 = _old(lite, small[None])
    assert np.array_equal(restore_frames(lite, small[None]).images, old_u8)  # type: ignore[arg-type]


def test_lite_u8_averages_over_time_as_the_float_path() -> None:
    frames = [_frame(640, 480, k) for k in (0, 1, 0)]
    old, new = create("lite?temporal=0.6"), create("lite?temporal=0.6")
    with old.sequence(), new.sequence():
        for f in frames:
            a = _old(old, f[None])[1]
            b = restore_frames(new, f[None]).images
            assert np.abs(b.astype(np.int16) - a).max() <= 1


def test_balance_table_is_bit_for_bit_the_float_balance() -> None:
    frame = _frame(1280, 720, 2)
    levels = balance_levels(to_float(frame), 0.5, 0.5)
    assert np.array_equal(lite_u8.frame_levels(frame, 0.5), levels)
    assert np.array_equal(cv2.LUT(frame, lite_u8.balance_table(levels)), apply_levels(to_float(frame), levels))
    assert np.array_equal(cv2.LUT(frame, lite_u8.balance_table(None)), to_float(frame))


@pytest.mark.parametrize(("h", "w", "size"), [(1080, 1920, (112, 192)), (721, 1283, (112, 192)), (97, 130, (16, 32))])
def test_area_pool_equals_torch_area_interpolation(h: int, w: int, size: tuple[int, int]) -> None:
    frame = np.random.default_rng(h).integers(0, 256, (h, w, 3), dtype=np.uint8)
    table = lite_u8.balance_table(np.array([[0.1, 0.05, 0.2], [0.9, 0.8, 0.95]], np.float32))
    x = torch.from_numpy(cv2.LUT(frame, table)).permute(2, 0, 1)[None]
    ref = F.interpolate(x, size=size, mode="area")[0].permute(1, 2, 0).numpy()
    assert np.abs(lite_u8.area_pool(frame, table, size) - ref).max() < 1e-5


@pytest.mark.parametrize("method", ["lite+post", "post", "greyworld", "colorbalance", "post?preset=paper"])
@pytest.mark.parametrize(("w", "h"), [(640, 480), (1920, 1080)])
def test_every_method_within_one_grey_level(method: str, w: int, h: int) -> None:
    frames = _frame(w, h, 1)[None]
    restorer = create(method)
    _, old_u8 = _old(restorer, frames)
    new = restore_frames(restorer, frames)
    assert new.images.dtype == np.uint8
    assert np.abs(new.images.astype(np.int16) - old_u8).max() <= 1


def test_to_u8_is_to_uint() -> None:
    x = np.random.default_rng(0).uniform(-0.2, 1.2, (3, 41, 67, 3)).astype(np.float32)
    assert np.array_equal(to_u8(x), to_uint(x, 8))
    ties = (np.arange(256, dtype=np.float32) + 0.5) / 255  # k + 0.5 after scaling (up to float rounding)
    assert np.array_equal(to_u8(ties), to_uint(ties, 8))
    assert to_u8(np.array([-1.0, 2.0], np.float32)).tolist() == [0, 255]


@pytest.mark.parametrize(("w", "h"), [(1920, 1080), (640, 480), (333, 97), (50, 3)])
@pytest.mark.parametrize("params", [POST_PRESETS["real"], POST_PRESETS["paper"], PostParams(lam=0.0)])
def test_post_strips_equal_post_process(w: int, h: int, params: PostParams) -> None:
    image = to_float(_frame(w, h, 2)) * np.float32(1.1) - np.float32(0.05)  # values outside [0, 1] too
    ref = post_process(image, **params._kwargs())
    assert np.array_equal(post_process_strips(image, params), ref)


def test_post_strips_use_the_tables_hook() -> None:
    image = to_float(_frame(640, 480, 2))
    flat = np.tile(np.arange(256, dtype=np.float32), (1, 1))

    def identity(tables: np.ndarray) -> np.ndarray:
        return flat

    ref = post_process(image, **POST_PRESETS["real"]._kwargs(), tables=identity)
    assert np.array_equal(post_process_strips(image, POST_PRESETS["real"], identity), ref)
    with pytest.raises(ValueError, match=r"params\.he"):
        post_process_strips(image, PostParams(he="rgb"))


def test_enhance_writes_every_frame_in_order(tmp_path: Path) -> None:
    """File to file: every frame restored from its own input, none lost or reordered (lossless PNG outputs)."""
    from murk.enhance.api import OutputOptions, enhance_frames
    from murk.io.video import CaptureSource

    clip = tmp_path / "clip.avi"
    base = cv2.resize(cv2.imread(str(sample_underwater_images()[0])), (700, 480), interpolation=cv2.INTER_AREA)
    writer = cv2.VideoWriter(str(clip), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (640, 480))
    for i in range(12):
        writer.write(np.ascontiguousarray(base[:, 5 * i : 5 * i + 640]))
    writer.release()
    lite = create("lite+post")
    with CaptureSource(clip) as source:
        report = enhance_frames(source, lite, tmp_path / "out", OutputOptions(format="png"))
    assert report.processed == 12 and report.failed == 0
    with CaptureSource(clip) as source:
        inputs = [f.image for f in source]
    for i, frame in enumerate(inputs):
        written = cv2.imread(str(tmp_path / "out" / f"clip_{i:06d}.png"))[:, :, ::-1]
        assert np.array_equal(written, restore_frames(lite, frame[None]).images[0])  # type: ignore[index]
