"""Noise tile and texture lookups (numpy via OpenCV remap, torch twin)."""

from __future__ import annotations

import numpy as np
import pytest

from murk.scenes.textures import (
    TILE_PX,
    lookup_numpy,
    noise_tile,
    prepare_image_texture,
    wrap_coords,
)


def test_noise_tile_channels_are_uniform_and_constant() -> None:
    tile = noise_tile()
    assert tile.shape == (TILE_PX, TILE_PX, 4) and tile.dtype == np.float32
    assert not tile.flags.writeable
    assert tile.min() == 0.0 and tile.max() == 1.0
    for c in range(4):
        # Rank-normalised: uniform on [0, 1], so a threshold q covers a fraction 1 - q of a surface.
        assert abs(float((tile[..., c] > 0.8).mean()) - 0.2) < 1e-3
    # Channels differ in scale: speckle (2) varies much faster than the blotches (1).
    grad = [float(np.abs(np.diff(tile[..., c], axis=1)).mean()) for c in range(4)]
    assert grad[2] > 4 * grad[1]
    assert noise_tile() is tile  # generated once per process


def test_lookup_wraps_and_interpolates() -> None:
    tile = noise_tile()
    x = np.array([[3.0, 10.5, 255.5]], dtype=np.float32)
    y = np.array([[7.0, 20.0, 0.0]], dtype=np.float32)
    out = lookup_numpy(tile, x, y)
    assert out.shape == (1, 3, 4)
    np.testing.assert_allclose(out[0, 0], tile[7, 3], atol=1e-6)
    np.testing.assert_allclose(out[0, 1], 0.5 * (tile[20, 10] + tile[20, 11]), atol=1e-6)
    np.testing.assert_allclose(out[0, 2], 0.5 * (tile[0, 255] + tile[0, 0]), atol=1e-6)  # wraps around
    one_d = lookup_numpy(tile, x[0], y[0])
    np.testing.assert_allclose(one_d, out[0], atol=0)
    big = np.linspace(0.0, 255.0, 70000, dtype=np.float32)  # > 32767: looked up in chunks
    assert lookup_numpy(tile, big, big).shape == (70000, 4)
    w = wrap_coords(np, np.array([-1.0, 256.0, 300.25], dtype=np.float32), TILE_PX)
    np.testing.assert_allclose(w, [255.0, 0.0, 44.25])


def test_prepare_image_texture() -> None:
    img = np.zeros((100, 300, 3), np.float32)
    img[:, 100:200] = 1.0  # the centre square is white
    tex = prepare_image_texture(img)
    assert tex.shape == (256, 256, 3) and tex.dtype == np.float32
    assert tex.min() > 0.99
    with pytest.raises(TypeError, match="image: expected a float image"):
        prepare_image_texture(np.zeros((10, 10, 3), np.uint8))
