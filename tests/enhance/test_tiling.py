"""Padding to multiples of 32 (reflect, never resize) and tiled inference with blended seams."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch

from murk.enhance.tiling import Padding, pad_to_multiple, padding_for, tile_starts, tiled_apply
from murk.errors import ShapeError


def test_padding_for_is_symmetric_with_the_extra_pixel_last():
    assert padding_for(45, 70) == Padding(top=9, bottom=10, left=13, right=13)  # 19 and 26 rows/columns added
    assert padding_for(64, 96) == Padding(0, 0, 0, 0)
    with pytest.raises(ValueError, match="positive height and width"):
        padding_for(0, 5)
    with pytest.raises(ValueError, match="multiple"):
        padding_for(5, 5, multiple=0)


@pytest.mark.parametrize("hw", [(45, 70), (5, 7), (2, 33), (64, 96)])
def test_reflect_padding_equals_numpy_reflect_and_crops_back_exactly(hw):
    # Reference: numpy.pad(mode="reflect"), which also repeats the reflection for pads larger than the image.
    x = torch.rand(2, 3, *hw, generator=torch.Generator().manual_seed(0))
    padded, pad = pad_to_multiple(x, 32)
    assert padded.shape[2] % 32 == 0 and padded.shape[3] % 32 == 0
    assert padded.shape[2] - hw[0] < 32 and padded.shape[3] - hw[1] < 32
    ref = np.pad(x.numpy(), ((0, 0), (0, 0), (pad.top, pad.bottom), (pad.left, pad.right)), mode="reflect")
    np.testing.assert_array_equal(padded.numpy(), ref)
    assert torch.equal(pad.crop(padded), x)


@pytest.mark.parametrize("hw", [(45, 70), (5, 7), (2, 33), (1, 3), (64, 96)])
@pytest.mark.parametrize("multiple", [16, 32])
def test_reflect_index_gathers_what_reflect_padding_makes(hw, multiple):
    # The tensor-arithmetic twin that ONNX graphs use (murk.models.padding.reflect_index) against the padding.
    from murk.models.padding import reflect_index

    x = torch.rand(1, 2, *hw, generator=torch.Generator().manual_seed(1))
    padded, pad = pad_to_multiple(x, multiple)
    rows = reflect_index(torch.arange(padded.shape[2]) - pad.top, torch.tensor(hw[0]))
    cols = reflect_index(torch.arange(padded.shape[3]) - pad.left, hw[1])
    assert torch.equal(x[:, :, rows][:, :, :, cols], padded)


def test_single_pixel_axes_are_replicated():
    x = torch.arange(3.0).reshape(1, 1, 1, 3)
    padded, pad = pad_to_multiple(x, 32)
    assert padded.shape == (1, 1, 32, 32)
    assert torch.equal(padded[0, 0, :, pad.left : pad.left + 3], x[0, 0].expand(32, 3))
    assert torch.equal(pad.crop(padded), x)


def test_replicate_mode_and_errors():
    x = torch.rand(1, 1, 3, 3)
    padded, pad = pad_to_multiple(x, 8, mode="replicate")
    assert torch.equal(padded[0, 0, 0, 0], x[0, 0, 0, 0]) and torch.equal(pad.crop(padded), x)
    with pytest.raises(ShapeError, match=r"\(B, C, H, W\)"):
        pad_to_multiple(torch.zeros(3, 4, 4))
    with pytest.raises(ValueError, match="mode"):
        pad_to_multiple(x, 8, mode="wrap")


@pytest.mark.parametrize(("size", "tile", "overlap"), [(1000, 256, 64), (257, 256, 64), (512, 128, 0), (96, 96, 32)])
def test_tile_starts_cover_the_axis_with_at_least_the_overlap(size, tile, overlap):
    starts = tile_starts(size, tile, overlap)
    assert starts[0] == 0 and starts[-1] == max(0, size - tile) and starts == sorted(starts)
    covered = np.zeros(size, bool)
    for s in starts:
        covered[s : s + tile] = True
    assert covered.all()
    assert all(b - a <= tile - overlap for a, b in itertools.pairwise(starts))


def test_tile_starts_rejects_bad_arguments():
    with pytest.raises(ValueError, match="tile: expected a positive"):
        tile_starts(100, 0, 0)
    with pytest.raises(ValueError, match="overlap"):
        tile_starts(100, 32, 32)


def test_tiled_pointwise_function_equals_whole_image():
    x = torch.rand(2, 3, 320, 480, generator=torch.Generator().manual_seed(1))

    def fn(t):
        return torch.sigmoid(2 * t), t.mean(1, keepdim=True)

    out = tiled_apply(fn, x, tile=128, overlap=32)
    whole = fn(x)
    assert [o.shape for o in out] == [(2, 3, 320, 480), (2, 1, 320, 480)]
    for a, b in zip(out, whole, strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=1e-6)


def test_tiles_are_placed_where_they_belong():
    # A function that writes each tile's own mean would blur everything; one that returns its input must not
    # shift anything: a horizontal ramp stays the same ramp (catches swapped or off-by-one tile offsets).
    yy, xx = torch.meshgrid(torch.arange(256.0), torch.arange(384.0), indexing="ij")
    x = (xx + 1000 * yy)[None, None]
    (out,) = tiled_apply(lambda t: (t,), x, tile=96, overlap=32)
    torch.testing.assert_close(out, x, rtol=1e-6, atol=1e-3)


def test_grouped_tiles_give_the_same_result_and_one_tile_is_a_plain_call():
    x = torch.rand(2, 3, 192, 256, generator=torch.Generator().manual_seed(2))
    calls = []

    def fn(t):
        calls.append(t.shape[0])
        return (t * 3 - 1,)

    a = tiled_apply(fn, x, tile=96, overlap=32)[0]
    n_single = len(calls)
    b = tiled_apply(fn, x, tile=96, overlap=32, max_batch=8)[0]
    assert torch.equal(a, b) and len(calls) - n_single < n_single and max(calls) == 8
    calls.clear()
    c = tiled_apply(fn, x, tile=512, overlap=64)[0]
    assert calls == [2] and torch.equal(c, x * 3 - 1)


def test_tiled_apply_validates_its_arguments():
    x = torch.zeros(1, 3, 64, 64)
    with pytest.raises(ShapeError, match="multiples of 32"):
        tiled_apply(lambda t: (t,), torch.zeros(1, 3, 60, 64), tile=32, overlap=0)
    with pytest.raises(ValueError, match="tile: expected a positive multiple of 32"):
        tiled_apply(lambda t: (t,), x, tile=48, overlap=0)
    with pytest.raises(ValueError, match="overlap"):
        tiled_apply(lambda t: (t,), x, tile=32, overlap=32)
    with pytest.raises(ValueError, match="max_batch"):
        tiled_apply(lambda t: (t,), x, tile=32, overlap=0, max_batch=0)
    with pytest.raises(ValueError, match="spatial size"):
        tiled_apply(lambda t: (t[..., :16, :16],), x, tile=32, overlap=0)
