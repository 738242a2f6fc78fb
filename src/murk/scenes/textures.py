"""Procedural texture tables and their lookups (numpy via OpenCV ``remap``, torch twin with the same sampling).

Surfaces are textured by looking up a precomputed, periodic multi-octave value-noise tile (a constant,
generated once per process from a fixed seed; no global RNG), so the per-pixel cost is one bilinear fetch of
four channels instead of per-pixel noise evaluation:

- channel 0: fBm, octaves of 8-128 cells per tile (mid-scale colour variation);
- channel 1: coarse blotches, 2-8 cells per tile (stains);
- channel 2: speckle, 64-256 cells per tile (aggregate, pores);
- channel 3: patches, 4-32 cells per tile, an independent draw (marine growth).

Each channel is rank-normalised to a uniform distribution on [0, 1], so a threshold ``q`` covers a fraction
``1 - q`` of a surface. Image textures (``--textures``) are resized to :data:`IMAGE_TEXTURE_PX` squares.

The numpy lookup is ``cv2.remap`` (bilinear, wrap-around). OpenCV 4 snaps map coordinates to 1/32 texel
(``INTER_BITS = 5``) while OpenCV 5 interpolates float maps exactly; :func:`opencv_snaps` probes the installed
OpenCV once and the torch twin snaps exactly when OpenCV does, so both sample the same texels with the same
weights.
"""

from __future__ import annotations

import functools
from typing import Any

import cv2
import numpy as np

from murk._checks import check_rgb

TILE_PX = 256
"""Side of the noise tile in texels."""
IMAGE_TEXTURE_PX = 256
"""Side of an image texture after :func:`prepare_image_texture`."""
NOISE_SEED = 20261123
_SUBPIXEL = 32  # OpenCV's INTER_TAB_SIZE (1 << INTER_BITS)
_REMAP_CHUNK = 32000


def _value_noise(rng: np.random.Generator, size: int, cells: int) -> np.ndarray:
    """One periodic octave of value noise: random lattice values, smoothstep-interpolated (float64)."""
    lattice = rng.random((cells, cells))
    g = np.arange(size, dtype=np.float64) * (cells / size)
    i0 = np.floor(g).astype(np.intp)
    f = g - i0
    f = f * f * (3.0 - 2.0 * f)
    i1 = (i0 + 1) % cells
    rows = lattice[i0][:, i0] * (1 - f)[None, :] + lattice[i0][:, i1] * f[None, :]
    rows1 = lattice[i1][:, i0] * (1 - f)[None, :] + lattice[i1][:, i1] * f[None, :]
    return rows * (1 - f)[:, None] + rows1 * f[:, None]


def _fbm(rng: np.random.Generator, size: int, cells: tuple[int, ...], gain: float) -> np.ndarray:
    out = np.zeros((size, size))
    amp = 1.0
    for c in cells:
        out += amp * _value_noise(rng, size, c)
        amp *= gain
    return out


def _rank_normalise(x: np.ndarray) -> np.ndarray:
    order = np.argsort(x, axis=None, kind="stable")
    ranks = np.empty(x.size, dtype=np.float64)
    ranks[order] = np.arange(x.size, dtype=np.float64) / (x.size - 1)
    return ranks.reshape(x.shape)


@functools.lru_cache(maxsize=1)
def noise_tile() -> np.ndarray:
    """The (TILE_PX, TILE_PX, 4) float32 noise tile (read-only; see the module docstring for the channels)."""
    rng = np.random.default_rng(NOISE_SEED)
    s = TILE_PX
    chans = [
        _fbm(rng, s, (8, 16, 32, 64, 128), 0.55),
        _fbm(rng, s, (2, 4, 8), 0.5),
        _fbm(rng, s, (64, 128, 256), 0.8),
        _fbm(rng, s, (4, 8, 16, 32), 0.5),
    ]
    tile = np.stack([_rank_normalise(c) for c in chans], axis=-1).astype(np.float32)
    tile.setflags(write=False)
    return tile


def prepare_image_texture(image: np.ndarray) -> np.ndarray:
    """Resize a float RGB image in [0, 1] to the (IMAGE_TEXTURE_PX, IMAGE_TEXTURE_PX, 3) texture format
    (centre square crop, area interpolation). Textures wrap around, so seams may show on tiled surfaces."""
    image = check_rgb("image", image)
    h, w = image.shape[:2]
    side = min(h, w)
    y0, x0 = (h - side) // 2, (w - side) // 2
    crop = np.ascontiguousarray(image[y0 : y0 + side, x0 : x0 + side])
    out = cv2.resize(crop, (IMAGE_TEXTURE_PX, IMAGE_TEXTURE_PX), interpolation=cv2.INTER_AREA)
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def wrap_coords(xp: Any, x: Any, size: int) -> Any:
    """``x mod size`` for numpy arrays or torch tensors (texel coordinates of a periodic tile)."""
    return x - xp.floor(x * (1.0 / size)) * float(size)


def snap(xp: Any, x: Any) -> Any:
    """Round texel coordinates to a multiple of 1/32 (OpenCV's sub-texel grid)."""
    return xp.round(x * float(_SUBPIXEL)) * (1.0 / _SUBPIXEL)


@functools.lru_cache(maxsize=1)
def opencv_snaps() -> bool:
    """True when the installed OpenCV rounds float remap coordinates to 1/32 pixel (OpenCV 4 does)."""
    ramp = np.array([[0.0, 1.0, 1.0, 0.0]] * 4, dtype=np.float32)
    out = cv2.remap(ramp, np.array([[0.01]], np.float32), np.array([[1.0]], np.float32), cv2.INTER_LINEAR)
    return abs(float(out[0, 0])) < 1e-6


def lookup_numpy(table: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Bilinear wrap-around lookup of ``table`` (S, S, C) at texel coordinates ``x``, ``y`` in [0, S) (float32
    arrays of one shape, 1-D or 2-D); returns shape ``x.shape + (C,)``."""
    if x.ndim == 2:
        return cv2.remap(table, x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP).reshape(*x.shape, -1)
    # OpenCV maps must have fewer than 32767 columns: look up 1-D arrays in chunks of one row.
    n = x.shape[0]
    out = np.empty((n, table.shape[2]), dtype=np.float32)
    for i in range(0, n, _REMAP_CHUNK):
        j = min(n, i + _REMAP_CHUNK)
        res = cv2.remap(table, x[None, i:j], y[None, i:j], cv2.INTER_LINEAR, borderMode=cv2.BORDER_WRAP)
        out[i:j] = res.reshape(j - i, -1)
    return out


def lookup_torch(table: Any, x: Any, y: Any) -> Any:
    """Torch twin of :func:`lookup_numpy`: ``table`` (S, S, C) tensor, ``x``, ``y`` texel coordinates in
    [0, S) (snapped to 1/32 texel when OpenCV does so, see :func:`opencv_snaps`), bilinear weights.
    Returns ``x.shape + (C,)``."""
    import torch

    s = table.shape[0]
    xs, ys = (snap(torch, x), snap(torch, y)) if opencv_snaps() else (x, y)
    x0f = torch.floor(xs)
    y0f = torch.floor(ys)
    fx = xs - x0f
    fy = ys - y0f
    x0 = x0f.long() % s
    y0 = y0f.long() % s
    x1 = (x0 + 1) % s
    y1 = (y0 + 1) % s
    flat = table.reshape(s * s, -1)

    def fetch(yy: Any, xx: Any) -> Any:
        return flat[(yy * s + xx).reshape(-1)].reshape(*x.shape, flat.shape[1])

    fx = fx.unsqueeze(-1)
    fy = fy.unsqueeze(-1)
    top = fetch(y0, x0) * (1 - fx) + fetch(y0, x1) * fx
    bottom = fetch(y1, x0) * (1 - fx) + fetch(y1, x1) * fx
    return top * (1 - fy) + bottom * fy
