"""The simplest colour balance (Limare et al. 2011): what it saturates, and that it inverts Eq. (1) at one
distance for a scene that spans the range in every channel (why murk uses it on water)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from murk.restore_ops.balance import FLAT_RANGE, color_balance


def _full_range_scene(rng: np.random.Generator, h: int = 60, w: int = 80) -> np.ndarray:
    j = cv2.GaussianBlur(rng.random((h, w, 3)).astype(np.float32), (0, 0), 2.0)
    lo, hi = j.reshape(-1, 3).min(0), j.reshape(-1, 3).max(0)
    return ((j - lo) / (hi - lo)).astype(np.float32)


@pytest.mark.parametrize(("low", "high"), [(1.0, 1.0), (0.5, 3.0), (0.0, 0.0)])
def test_the_named_shares_of_each_channel_saturate(low: float, high: float) -> None:
    img = (np.random.default_rng(0).random((100, 120, 3)) * 0.4 + 0.3).astype(np.float32)
    out = color_balance(img, low, high)
    flat = out.reshape(-1, 3)
    for c in range(3):
        assert abs(100.0 * np.mean(flat[:, c] <= 0.0) - low) < 0.05 + (0.01 if low == 0 else 0)
        assert abs(100.0 * np.mean(flat[:, c] >= 1.0) - high) < 0.05 + (0.01 if high == 0 else 0)
    assert flat.min() == 0.0 and flat.max() == 1.0


def test_it_inverts_the_image_formation_model_at_one_distance() -> None:
    """I = J t + B (1 - t) per channel is affine in J: the balance of I equals the balance of J."""
    j = _full_range_scene(np.random.default_rng(1))
    t = np.array([0.15, 0.55, 0.6], np.float32)  # red absorbed most, as in green water
    b = np.array([0.05, 0.45, 0.4], np.float32)
    img = j * t + b * (1 - t)
    np.testing.assert_allclose(color_balance(img, 0.0, 0.0), j, atol=2e-5)
    np.testing.assert_allclose(color_balance(img, 1.0, 1.0), color_balance(j, 1.0, 1.0), atol=2e-5)
    assert np.abs(img - j).mean() > 0.15  # the water changed the image a lot


def test_a_flat_channel_is_left_as_it_is() -> None:
    img = np.full((20, 30, 3), 0.5, np.float32)
    img[..., 0] += np.float32(0.5 * FLAT_RANGE) * np.random.default_rng(2).random((20, 30)).astype(np.float32)
    img[..., 2] = np.linspace(0.2, 0.8, 30, dtype=np.float32)  # a channel with a range: stretched
    out = color_balance(img)
    assert np.array_equal(out[..., :2], img[..., :2])  # not blown up, not set to 0
    assert out[..., 2].min() == 0.0 and out[..., 2].max() == 1.0
    import torch

    from murk.restore_ops.balance import color_balance_torch

    for frame in (np.zeros((8, 8, 3)), np.ones((8, 8, 3)), np.tile([0.0, 0.0, 1.0], (8, 8, 1))):
        frame = frame.astype(np.float32)  # a lens cap, a lamp's clipped white, a pure colour: kept
        assert np.array_equal(color_balance(frame), frame)
        torch_out = color_balance_torch(torch.from_numpy(frame).permute(2, 0, 1)[None])[0].permute(1, 2, 0).numpy()
        assert np.array_equal(torch_out, frame)


def test_the_numpy_levels_equal_the_torch_twins_bit_for_bit() -> None:
    """``lite`` takes the levels on the CPU from the numpy twin and elsewhere from the torch twin: the same
    values, for frames of any layout (NCHW or channels-last views) and sizes on both sides of the sampling stride."""
    import torch

    from murk.restore_ops.balance import balance_levels, balance_levels_torch

    rng = np.random.default_rng(8)
    for h, w in ((1, 1), (7, 5), (97, 131), (480, 640), (720, 1280)):
        hwc = rng.random((2, h, w, 3), dtype=np.float32) ** rng.uniform(0.3, 3.0)
        for x in (torch.from_numpy(hwc).permute(0, 3, 1, 2), torch.from_numpy(hwc).permute(0, 3, 1, 2).contiguous()):
            for pct in (0.5, 1.0, 2.5):
                ref = balance_levels_torch(x, pct, pct).numpy()
                got = np.stack([balance_levels(f.permute(1, 2, 0).numpy(), pct, pct) for f in x])
                np.testing.assert_array_equal(got, ref)


def test_the_export_graphs_balance_equals_the_numpy_twin_flat_channels_included() -> None:
    import torch

    from murk.models.balance_graph import color_balance_graph

    rng = np.random.default_rng(4)
    photo = rng.random((24, 32, 3), dtype=np.float32) * np.float32(0.6) + np.float32(0.2)
    flat = photo.copy()
    flat[..., 1] = 1.0  # a channel clipped everywhere
    for frame in (photo, flat, np.zeros((24, 32, 3), np.float32)):
        graph = color_balance_graph(torch.from_numpy(frame).permute(2, 0, 1)[None], 1.0, 1.0)
        np.testing.assert_allclose(graph[0].permute(1, 2, 0).numpy(), color_balance(frame), atol=1e-6)
    assert np.array_equal(color_balance(flat)[..., 1], flat[..., 1])


def test_the_twins_agree_bit_for_bit_on_a_frame_with_one_flat_channel() -> None:
    import torch

    from murk.restore_ops.balance import color_balance_torch

    rng = np.random.default_rng(9)
    frame = (rng.random((30, 40, 3), dtype=np.float32) * np.float32(0.7) + np.float32(0.1)).astype(np.float32)
    frame[..., 0] = np.float32(3 / 255)  # deep water: red one grey level everywhere; green and blue stretched
    out = color_balance(frame)
    twin = color_balance_torch(torch.from_numpy(frame).permute(2, 0, 1)[None])[0].permute(1, 2, 0).numpy()
    assert np.array_equal(out, twin)
    assert np.array_equal(out[..., 0], frame[..., 0]) and out[..., 1].max() == 1.0
