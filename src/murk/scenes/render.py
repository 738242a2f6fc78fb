"""Render sampled scenes to clean RGB + exact line-of-sight distance: numpy (one scene) and torch (a batch).

Both renderers cast one ray per pixel centre from the camera centre, intersect it analytically with every
primitive (:mod:`murk.scenes.geometry`), keep the nearest hit (z-buffer), and shade it
(:mod:`murk.scenes.shading`). ``dist_m`` is the distance from the camera centre to the hit along the ray (NOT
the z-depth; ``z = dist * cos(angle to the optical axis)``), clamped to ``[near_m, far_m]``; rays that hit
nothing within ``far_m`` get ``far_m`` and show the open-water background.

Both renderers cull: a primitive is only intersected with the pixels inside the exact screen rectangles of
its bounding spheres (one sphere, or a chain of them along a long frustum). The numpy renderer loops over
primitives and then shades pixels compacted by material; the torch renderer bins (scene, tile, primitive)
pairs and processes each primitive type in one batched call, which suits a GPU. Both call the same kernels
and the same shading formula, so their outputs agree to float32 rounding (a test pins this).

No equation of the paper is implemented here; the output is the clean input of Eq. (1).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from murk.scenes import geometry as geo
from murk.scenes.geometry import clamp
from murk.scenes.params import Box, Frustum, Net, SceneParams, Sphere
from murk.scenes.shading import MATERIAL_FIELDS, light_row, material_table, shade
from murk.scenes.textures import IMAGE_TEXTURE_PX, TILE_PX, lookup_numpy, lookup_torch, noise_tile, wrap_coords

KINDS = ("box", "frustum", "sphere", "net")
_FIELDS = {"box": geo.BOX_FIELDS, "frustum": geo.FRUSTUM_FIELDS, "sphere": geo.SPHERE_FIELDS, "net": geo.NET_FIELDS}
_PACK: dict[type, tuple[str, Callable[..., np.ndarray]]] = {
    Box: ("box", geo.pack_box),
    Frustum: ("frustum", geo.pack_frustum),
    Sphere: ("sphere", geo.pack_sphere),
}
_PACK[Net] = ("net", geo.pack_net)
T_CAP_FACTOR = 1.0
"""Hits are searched up to this many times ``far_m`` (beyond ``far_m`` a surface is background anyway)."""


@dataclass(frozen=True)
class CameraFrame:
    """Camera basis (world frame) and intrinsics for one image size."""

    position: np.ndarray
    forward: np.ndarray
    right: np.ndarray
    down: np.ndarray
    focal_px: float
    width: int
    height: int

    @property
    def px_angle(self) -> float:
        """Angular size of a pixel at the image centre (rad)."""
        return 1.0 / self.focal_px


def camera_frame(params: SceneParams, size: tuple[int, int]) -> CameraFrame:
    """The camera basis and focal length of ``params`` for an image of ``size`` = (width, height)."""
    c = params.camera
    yaw, pitch, roll = (math.radians(a) for a in (c.yaw_deg, c.pitch_deg, c.roll_deg))
    fwd = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch)])
    right0 = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    up0 = np.array(
        [
            right0[1] * fwd[2] - right0[2] * fwd[1],
            right0[2] * fwd[0] - right0[0] * fwd[2],
            right0[0] * fwd[1] - right0[1] * fwd[0],
        ]
    )
    right = math.cos(roll) * right0 + math.sin(roll) * up0
    up = -math.sin(roll) * right0 + math.cos(roll) * up0
    width, height = size
    focal = (width / 2.0) / math.tan(math.radians(c.hfov_deg) / 2.0)
    return CameraFrame(np.asarray(c.position_m, dtype=np.float64), fwd, right, -up, focal, width, height)


def intrinsics(params: SceneParams, size: tuple[int, int]) -> dict[str, float]:
    """Pinhole intrinsics in the OpenCV convention (pixel centres at integer coordinates)."""
    f = camera_frame(params, size).focal_px
    return {"fx": f, "fy": f, "cx": (size[0] - 1) / 2.0, "cy": (size[1] - 1) / 2.0}


@dataclass(frozen=True)
class PackedScene:
    """Camera-relative float64 constants of one scene (the renderers' input)."""

    frame: CameraFrame
    seabed: np.ndarray
    prims: list[tuple[str, np.ndarray]]
    material_of_id: np.ndarray
    materials: np.ndarray
    light: np.ndarray
    near_m: float
    far_m: float


def pack_scene(params: SceneParams, size: tuple[int, int], texture_names: Sequence[str] = ()) -> PackedScene:
    """Precompute everything per scene that does not depend on the pixel (see :mod:`murk.scenes.geometry`)."""
    frame = camera_frame(params, size)
    cam = frame.position
    prims: list[tuple[str, np.ndarray]] = []
    mats = [params.seabed.material]
    for p in params.primitives():
        kind, fn = _PACK[type(p)]
        prims.append((kind, fn(p, cam)))
        mats.append(p.material)
    n_mat = len(params.materials)
    if not all(0 <= m < n_mat for m in mats):
        raise ValueError(f"scene: a primitive refers to a material outside 0..{n_mat - 1}")
    names = list(texture_names)
    for m in params.materials:
        if m.texture is not None and m.texture not in names:
            raise ValueError(f"textures: the scene uses image texture {m.texture!r}, which was not given")
    return PackedScene(
        frame=frame,
        seabed=geo.pack_seabed(params.seabed, cam),
        prims=prims,
        material_of_id=np.asarray(mats, dtype=np.intp),
        materials=material_table(params.materials, names),
        light=np.asarray(light_row(params.lighting, params.far_m, frame.px_angle), dtype=np.float64),
        near_m=params.near_m,
        far_m=params.far_m,
    )


def _check_size(size: Any) -> tuple[int, int]:
    try:
        w, h = size
    except (TypeError, ValueError):
        raise TypeError(f"size: expected (width, height), got {size!r}") from None
    if isinstance(w, bool) or isinstance(h, bool) or not isinstance(w, (int, np.integer)):
        raise TypeError(f"size: expected two ints (width, height), got {size!r}")
    if not isinstance(h, (int, np.integer)) or w < 8 or h < 8 or w > 16384 or h > 16384:
        raise ValueError(f"size: expected (width, height) with 8 <= each <= 16384, got {size!r}")
    return int(w), int(h)


def _check_textures(textures: Mapping[str, np.ndarray] | None) -> dict[str, np.ndarray]:
    if textures is None:
        return {}
    if not isinstance(textures, Mapping):
        raise TypeError(f"textures: expected a mapping name -> image, got {type(textures).__name__}")
    out = {}
    for name, img in textures.items():
        if not isinstance(img, np.ndarray) or img.shape != (IMAGE_TEXTURE_PX, IMAGE_TEXTURE_PX, 3):
            got = img.shape if isinstance(img, np.ndarray) else type(img).__name__
            raise ValueError(
                f"textures[{name!r}]: expected a ({IMAGE_TEXTURE_PX}, {IMAGE_TEXTURE_PX}, 3) float32 array "
                f"from prepare_image_texture, got {got}"
            )
        out[str(name)] = np.ascontiguousarray(img, dtype=np.float32)
    return out


# ---------------------------------------------------------------------------------------------- numpy renderer


def _rays_numpy(frame: CameraFrame) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    w, h = frame.width, frame.height
    inv_f = 1.0 / frame.focal_px
    xn = (np.arange(w, dtype=np.float32) + (0.5 - w / 2.0)) * inv_f
    yn = (np.arange(h, dtype=np.float32) + (0.5 - h / 2.0)) * inv_f
    inv_norm = 1.0 / np.sqrt((1.0 + xn * xn)[None, :] + (yn * yn)[:, None])
    d = []
    for i in range(3):
        f, r, dn = float(frame.forward[i]), float(frame.right[i]), float(frame.down[i])
        d.append(((f + xn * r)[None, :] + (yn * dn)[:, None]) * inv_norm)
    return (d[0], d[1], d[2]), inv_norm


def _axis_range(a: float, z: float, radius: float, focal: float, centre: float, n: int) -> tuple[int, int]:
    """Pixel index range [lo, hi) whose rays can hit a sphere, along one image axis.

    ``a`` and ``z`` are the sphere centre's coordinates along that image axis and the optical axis; the
    bounds come from the two planes through the camera centre that touch the sphere.
    """
    rho = math.hypot(a, z)
    if rho <= radius * 1.0001:
        return 0, n
    phi = math.atan2(a, z)
    delta = math.asin(radius / rho)
    lo_ang, hi_ang = phi - delta, phi + delta
    if lo_ang >= math.pi / 2 or hi_ang <= -math.pi / 2:
        return 0, 0
    lo = -math.inf if lo_ang <= -math.pi / 2 + 1e-9 else focal * math.tan(lo_ang)
    hi = math.inf if hi_ang >= math.pi / 2 - 1e-9 else focal * math.tan(hi_ang)
    # Pixel j's ray has coordinate (j + 0.5 - centre); one pixel of margin covers float32 rounding.
    j_lo = max(0, math.floor(lo + centre - 0.5) - 1) if math.isfinite(lo) else 0
    j_hi = min(n, math.ceil(hi + centre - 0.5) + 2) if math.isfinite(hi) else n
    return j_lo, max(j_lo, j_hi)


def screen_rect(frame: CameraFrame, centre: np.ndarray, radius: float) -> tuple[int, int, int, int]:
    """(row0, row1, col0, col1): the pixels whose rays can hit the sphere (``centre`` camera-relative)."""
    cx, cy, cz = float(centre[0]), float(centre[1]), float(centre[2])
    f, r, dn = frame.forward, frame.right, frame.down
    z = cx * f[0] + cy * f[1] + cz * f[2]
    x = cx * r[0] + cy * r[1] + cz * r[2]
    y = cx * dn[0] + cy * dn[1] + cz * dn[2]
    c0, c1 = _axis_range(x, z, radius, frame.focal_px, frame.width / 2.0, frame.width)
    r0, r1 = _axis_range(y, z, radius, frame.focal_px, frame.height / 2.0, frame.height)
    return r0, r1, c0, c1


def _bounds(kind: str, row: np.ndarray) -> tuple[np.ndarray, float]:
    f = _FIELDS[kind]
    return row[f - 4 : f - 1], float(row[f - 1])


MAX_PIECES = 24


def _seabed_numpy(d: tuple[np.ndarray, np.ndarray, np.ndarray], k: list[float], t_cap: float) -> np.ndarray:
    """:func:`geometry.seabed_t` on one band of rays, as float32."""
    return geo.seabed_t(np, d, k, t_cap).astype(np.float32, copy=False)


def _cull_spheres(kind: str, row: np.ndarray) -> list[tuple[np.ndarray, float]]:
    """Bounding spheres whose union contains the primitive: one, or for a long frustum (a pile, a pipe, a
    rebar) up to :data:`MAX_PIECES` spheres along its axis, so that its screen rectangles stay thin."""
    centre, radius = _bounds(kind, row)
    if kind != "frustum":
        return [(centre, radius)]
    a, w, length = row[0:3], row[3:6], float(row[6])
    r_max = max(float(row[7]), float(row[7] + row[8] * length))
    n = min(MAX_PIECES, max(1, math.ceil(length / max(4.0 * r_max, 1e-6))))
    if n == 1:
        return [(centre, radius)]
    piece = length / n
    r_piece = math.hypot(0.5 * piece, r_max) * 1.001
    return [(a + (i + 0.5) * piece * w, r_piece) for i in range(n)]


def _cull_rects(frame: CameraFrame, kind: str, row: np.ndarray) -> list[tuple[slice, slice]]:
    """Pixel rectangles covering every ray that can hit the primitive (overlaps are harmless)."""
    spheres = _cull_spheres(kind, row)
    if len(spheres) == 1:
        r0, r1, c0, c1 = screen_rect(frame, *spheres[0])
        return [(slice(r0, r1), slice(c0, c1))] if r1 > r0 and c1 > c0 else []
    centres = np.array([c for c, _ in spheres])
    radii = np.array([r for _, r in spheres])
    rects = screen_rects(frame, centres, radii)
    return [(slice(r0, r1), slice(c0, c1)) for r0, r1, c0, c1 in rects.tolist() if r1 > r0 and c1 > c0]


def _axis_ranges(a: np.ndarray, z: np.ndarray, radius: np.ndarray, focal: float, centre: float, n: int) -> np.ndarray:
    """Vectorised :func:`_axis_range` for many spheres; returns (K, 2) int pixel ranges [lo, hi)."""
    rho = np.hypot(a, z)
    inside = rho <= radius * 1.0001
    phi = np.arctan2(a, z)
    delta = np.arcsin(np.minimum(radius / np.maximum(rho, 1e-12), 1.0))
    lo_ang, hi_ang = phi - delta, phi + delta
    hidden = (lo_ang >= math.pi / 2) | (hi_ang <= -math.pi / 2)
    lo_open = lo_ang <= -math.pi / 2 + 1e-9
    hi_open = hi_ang >= math.pi / 2 - 1e-9
    with np.errstate(invalid="ignore", over="ignore"):
        lo = np.floor(focal * np.tan(np.clip(lo_ang, -1.5, 1.5)) + centre - 0.5) - 1
        hi = np.ceil(focal * np.tan(np.clip(hi_ang, -1.5, 1.5)) + centre - 0.5) + 2
    lo = np.where(lo_open | inside, 0, np.clip(lo, 0, n))
    hi = np.where(hi_open | inside, n, np.clip(hi, 0, n))
    hi = np.where(hidden & ~inside, lo, np.maximum(lo, hi))
    return np.stack([lo, hi], axis=1).astype(np.int64)


def screen_rects(frame: CameraFrame, centres: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(K, 4) rows (row0, row1, col0, col1) of :func:`screen_rect` for K spheres at once."""
    z = centres @ frame.forward
    x = centres @ frame.right
    y = centres @ frame.down
    cols = _axis_ranges(x, z, radii, frame.focal_px, frame.width / 2.0, frame.width)
    rows = _axis_ranges(y, z, radii, frame.focal_px, frame.height / 2.0, frame.height)
    return np.concatenate([rows, cols], axis=1)


def _t_kernel(kind: str, xp: Any, d: Any, k: Any, px_angle: Any) -> Any:
    if kind == "box":
        return geo.box_t(xp, d, k)
    if kind == "frustum":
        return geo.frustum_t(xp, d, k)
    if kind == "sphere":
        return geo.sphere_t(xp, d, k)
    return geo.net_t(xp, d, k, px_angle)


def _surface_kernel(kind: str, xp: Any, d: Any, t: Any, k: Any) -> tuple[Any, ...]:
    if kind == "box":
        return geo.box_surface(xp, d, t, k)
    if kind == "frustum":
        return geo.frustum_surface(xp, d, t, k)
    if kind == "sphere":
        return geo.sphere_surface(xp, d, t, k)
    return geo.net_surface(xp, d, t, k)


BAND_ROWS = 48
"""Full-frame numpy passes (seabed, its shading) run on bands of this many rows, which stay in cache."""


def render_packed_numpy(
    packed: PackedScene, textures: Sequence[np.ndarray] = (), *, cull: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """Render a :class:`PackedScene` with numpy; ``cull=False`` intersects every primitive with every pixel
    (same result, slower: the baseline of ``benchmarks/bench_scenes.py``)."""
    frame = packed.frame
    h, w = frame.height, frame.width
    d, cos_axis = _rays_numpy(frame)
    far = packed.far_m
    t_cap = T_CAP_FACTOR * far
    sb = packed.seabed.tolist()

    # Visibility: the seabed (by bands), then every primitive inside its screen rectangle.
    t_buf = np.full((h, w), np.inf, dtype=np.float32)
    for r in range(0, h, BAND_ROWS):
        band = slice(r, r + BAND_ROWS)
        db = (d[0][band], d[1][band], d[2][band])
        if float((db[2] - sb[1] * db[0] - sb[2] * db[1]).min()) < -1e-6:
            t_buf[band] = _seabed_numpy(db, sb, t_cap)
    id_buf = np.where(t_buf < np.inf, 0, -1).astype(np.int32)
    px_angle = frame.px_angle
    full = [(slice(0, h), slice(0, w))]
    for gid, (kind, row) in enumerate(packed.prims, start=1):
        mine = _cull_rects(frame, kind, row) if cull else full
        k = row.tolist()
        for sl in mine:
            t = _t_kernel(kind, np, (d[0][sl], d[1][sl], d[2][sl]), k, px_angle)
            tb = t_buf[sl]
            np.copyto(id_buf[sl], gid, where=t < tb)  # strictly nearer: the earlier primitive wins a tie
            np.minimum(tb, t, out=tb)

    image = _shade_numpy(packed, textures, d, cos_axis, t_buf, id_buf)
    dist = np.clip(t_buf, packed.near_m, far).astype(np.float32, copy=False)
    return image, dist


CHUNK = 16384
"""Compacted per-pixel passes run on chunks of this many pixels (they stay in cache)."""
_KIND_CODE = {"seabed": 0, "box": 1, "frustum": 2, "sphere": 3, "net": 4}
_SURFACE_FIELDS = {"box": 15, "frustum": 15, "sphere": 4, "net": 12}
"""Leading packed constants that the ``*_surface`` kernels read (the rest are culling bounds)."""


def _shade_numpy(
    packed: PackedScene,
    textures: Sequence[np.ndarray],
    d: tuple[np.ndarray, np.ndarray, np.ndarray],
    cos_axis: np.ndarray,
    t_buf: np.ndarray,
    id_buf: np.ndarray,
) -> np.ndarray:
    """Surface attributes and shading of every pixel, on pixels compacted by (material, primitive kind)."""
    frame = packed.frame
    h, w = frame.height, frame.width
    light = packed.light.tolist()
    t_cap = T_CAP_FACTOR * packed.far_m
    cam_xy = (float(frame.position[0]), float(frame.position[1]))
    tile = noise_tile()

    def lookup(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return lookup_numpy(tile, x, y)

    # Group primitives by (material, kind); sort pixels by group with a one-byte stable (radix) sort.
    kinds = ["seabed"] + [k for k, _ in packed.prims]
    mats = packed.material_of_id.tolist()
    groups = sorted({(m, _KIND_CODE[k]) for m, k in zip(mats, kinds, strict=True)})
    if len(groups) > 126:
        raise ValueError(f"scene: at most 126 (material, primitive kind) pairs are supported, got {len(groups)}")
    group_of = {g: i for i, g in enumerate(groups)}
    key_lut = np.empty(len(mats) + 1, dtype=np.int8)
    key_lut[0] = len(groups)  # misses sort last
    local_lut = np.zeros(len(mats) + 1, dtype=np.intp)
    members: list[list[int]] = [[] for _ in groups]
    for gid, (m, k) in enumerate(zip(mats, kinds, strict=True)):
        grp = group_of[(m, _KIND_CODE[k])]
        key_lut[gid + 1] = grp
        local_lut[gid + 1] = len(members[grp])
        members[grp].append(gid)
    id_flat = id_buf.ravel() + 1
    keys = np.take(key_lut, id_flat)
    order = np.argsort(keys, kind="stable")
    starts = np.searchsorted(np.take(keys, order), np.arange(len(groups) + 1), side="left").tolist()
    idx = order[: starts[-1]]

    # Open water everywhere first (the background gradient that shade() fades to at far_m); hits overwrite it.
    up = clamp(np, 0.5 + 1.2 * d[2].ravel(), 0.0, 1.0)
    planes = [light[15 + i] + (light[18 + i] - light[15 + i]) * up for i in range(3)]
    if idx.size:
        t_flat, cos_flat = t_buf.ravel(), cos_axis.ravel()
        d_flat = [a.ravel() for a in d]
        cap = np.float32(t_cap)
        for grp, (m, _kcode) in enumerate(groups):
            lo, hi = starts[grp], starts[grp + 1]
            if hi <= lo:
                continue
            gids = members[grp]
            kind = kinds[gids[0]]
            if kind == "seabed":
                consts: list[Any] = packed.seabed.tolist()
                per_pixel = False
            elif len(gids) == 1:
                consts = packed.prims[gids[0] - 1][1].tolist()
                per_pixel = False
            else:
                table = np.stack([packed.prims[g - 1][1] for g in gids]).astype(np.float32)
                local = np.take(local_lut, np.take(id_flat, idx[lo:hi]))
                consts = [np.take(table[:, j], local) for j in range(_SURFACE_FIELDS[kind])]
                per_pixel = True
            coeffs = packed.materials[m].tolist()
            tex = textures[int(coeffs[23])] if coeffs[23] >= 0 else None
            for a in range(lo, hi, CHUNK):
                b = min(hi, a + CHUNK)
                ii = idx[a:b]
                t = np.minimum(np.take(t_flat, ii), cap)
                dd = (np.take(d_flat[0], ii), np.take(d_flat[1], ii), np.take(d_flat[2], ii))
                kk = [c[a - lo : b - lo] for c in consts] if per_pixel else consts
                if kind == "seabed":
                    nx, ny, nz, u, v = geo.seabed_surface(np, dd, t, kk, cam_xy)
                else:
                    nx, ny, nz, u, v = _surface_kernel(kind, np, dd, t, kk)
                image_rgb = None if tex is None else _image_texture_numpy(tex, coeffs, (u, v))
                rgb = shade(np, t, dd, (nx, ny, nz), (u, v), np.take(cos_flat, ii), coeffs, light, lookup, image_rgb)
                for plane, src in zip(planes, rgb, strict=True):
                    plane[ii] = src
    return np.stack([p.reshape(h, w) for p in planes], axis=-1)


def _image_texture_numpy(
    texture: np.ndarray, coeffs: list[float], uv: tuple[np.ndarray, np.ndarray]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    scale = coeffs[20] * float(IMAGE_TEXTURE_PX)
    x = wrap_coords(np, uv[0] * scale + coeffs[21], IMAGE_TEXTURE_PX)
    y = wrap_coords(np, uv[1] * scale + coeffs[22], IMAGE_TEXTURE_PX)
    out = lookup_numpy(texture, x, y)
    return out[..., 0], out[..., 1], out[..., 2]


def render_scene(
    params: SceneParams, size: tuple[int, int], *, textures: Mapping[str, np.ndarray] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Render one scene on the CPU (numpy, deterministic).

    Args:
        params: a scene from :func:`murk.scenes.sample_scene` (or :func:`murk.scenes.scene_from_dict`).
        size: (width, height) in pixels.
        textures: image textures by name (each from :func:`murk.scenes.prepare_image_texture`); needed when a
            material of the scene names one.

    Returns:
        ``(rgb, dist_m)``: float32 (H, W, 3) in [0, 1] and float32 (H, W) line-of-sight distance in metres
        along each pixel's ray (not z-depth), in ``[params.near_m, params.far_m]``.

    Raises:
        TypeError: ``params`` is not a SceneParams or ``size`` is not a pair of ints.
        ValueError: a size outside 8..16384, a missing or malformed texture, a bad material index.
    """
    if not isinstance(params, SceneParams):
        raise TypeError(f"params: expected SceneParams, got {type(params).__name__}")
    size = _check_size(size)
    tex = _check_textures(textures)
    names = sorted(tex)
    packed = pack_scene(params, size, names)
    return render_packed_numpy(packed, [tex[n] for n in names])


# ---------------------------------------------------------------------------------------------- torch renderer


TILE = 16
"""The torch renderer bins work into TILE x TILE pixel tiles."""
PAIR_CHUNK_PX = 1 << 22
"""At most this many (pair, pixel) elements are processed at once by the torch renderer (bounds memory)."""


def _tile_pairs(packed: PackedScene, tiles_x: int) -> tuple[np.ndarray, np.ndarray]:
    """(primitive index in packed.prims, tile index) for every tile that a primitive's culling rectangles
    touch, duplicates removed; two int64 arrays."""
    frame = packed.frame
    spheres, owner = [], []
    for i, (kind, row) in enumerate(packed.prims):
        for c, r in _cull_spheres(kind, row):
            spheres.append((c, r))
            owner.append(i)
    empty = np.zeros(0, dtype=np.int64)
    if not spheres:
        return empty, empty
    rects = screen_rects(frame, np.array([c for c, _ in spheres]), np.array([r for _, r in spheres]))
    r0, r1, c0, c1 = rects.T
    ok = (r1 > r0) & (c1 > c0)
    ty0, ty1 = r0 // TILE, -(-r1 // TILE)
    tx0, tx1 = c0 // TILE, -(-c1 // TILE)
    ny = np.where(ok, ty1 - ty0, 0)
    nx = np.where(ok, tx1 - tx0, 0)
    count = ny * nx
    total = int(count.sum())
    if total == 0:
        return empty, empty
    sphere = np.repeat(np.arange(len(spheres)), count)
    offset = np.arange(total) - np.repeat(np.cumsum(count) - count, count)
    ty = ty0[sphere] + offset // nx[sphere]
    tx = tx0[sphere] + offset % nx[sphere]
    prim = np.asarray(owner, dtype=np.int64)[sphere]
    keys = np.unique(prim * (1 << 24) + ty * tiles_x + tx)
    return keys >> 24, keys & ((1 << 24) - 1)


def render_scenes_torch(
    scenes: Sequence[SceneParams],
    size: tuple[int, int],
    device: Any = "cpu",
    *,
    textures: Mapping[str, np.ndarray] | None = None,
) -> tuple[Any, Any]:
    """Render a batch of scenes with torch (CPU or CUDA, float32), the twin of :func:`render_scene`.

    The image is cut into 16x16 tiles; every (scene, tile, primitive) pair whose culling rectangle touches the
    tile is intersected in one batched call per primitive type, and the nearest hit of each pixel is kept with
    a ``scatter_reduce(amin)`` on a key that packs the distance's float bits with the primitive id, so ties
    go to the earlier primitive exactly as in :func:`render_scene`. The seabed and the shading run on every
    pixel of the batch.

    Args:
        scenes: the scenes to render (any number >= 1).
        size: (width, height) in pixels.
        device: a torch device or its name.
        textures: as for :func:`render_scene`.

    Returns:
        ``(rgb, dist_m)``: float32 ``(B, 3, H, W)`` in [0, 1] and ``(B, 1, H, W)`` line-of-sight distance in
        metres, on ``device``.

    Raises:
        TypeError: ``scenes`` is not a non-empty sequence of SceneParams.
        ValueError: as for :func:`render_scene`.
    """
    import torch

    if isinstance(scenes, SceneParams) or not isinstance(scenes, Sequence) or len(scenes) == 0:
        raise TypeError("scenes: expected a non-empty sequence of SceneParams")
    for i, s in enumerate(scenes):
        if not isinstance(s, SceneParams):
            raise TypeError(f"scenes[{i}]: expected SceneParams, got {type(s).__name__}")
    width, height = _check_size(size)
    tex = _check_textures(textures)
    names = sorted(tex)
    dtype = torch.float32
    dev = torch.device(device)
    packs = [pack_scene(s, (width, height), names) for s in scenes]
    b = len(packs)
    tiles_y, tiles_x = -(-height // TILE), -(-width // TILE)
    hp, wp = tiles_y * TILE, tiles_x * TILE
    n_tiles = tiles_y * tiles_x

    def tensor(a: np.ndarray) -> Any:
        return torch.as_tensor(np.ascontiguousarray(a, dtype=np.float32), device=dev).to(dtype)

    def cols(t: Any) -> list[Any]:
        return [t[:, j : j + 1] for j in range(t.shape[1])]

    def tiled(x: Any) -> Any:
        """(B, Hp, Wp) -> (B * tiles, TILE * TILE): the pixels of each tile contiguous."""
        x = x.reshape(b, tiles_y, TILE, tiles_x, TILE).permute(0, 1, 3, 2, 4)
        return x.reshape(b * n_tiles, TILE * TILE)

    # Rays of the padded image (same intrinsics; the padding is cropped at the end), tiled layout.
    fr = tensor(
        np.array([np.concatenate([p.frame.forward, p.frame.right, p.frame.down, [p.frame.px_angle]]) for p in packs])
    )
    inv_f = fr[:, 9:10]
    xn = (torch.arange(wp, device=dev, dtype=dtype) + (0.5 - width / 2.0))[None, :] * inv_f
    yn = (torch.arange(hp, device=dev, dtype=dtype) + (0.5 - height / 2.0))[None, :] * inv_f
    inv_norm = 1.0 / torch.sqrt((1.0 + xn * xn)[:, None, :] + (yn * yn)[:, :, None])
    d_img = [
        ((fr[:, i : i + 1] + xn * fr[:, 3 + i : 4 + i])[:, None, :] + (yn * fr[:, 6 + i : 7 + i])[:, :, None])
        * inv_norm
        for i in range(3)
    ]
    dirs = tuple(tiled(x) for x in d_img)
    cos_axis = tiled(inv_norm)
    per_tile = torch.arange(b, device=dev).repeat_interleave(n_tiles)[:, None]  # scene of each tile row
    far = tensor(np.array([[p.far_m] for p in packs]))[per_tile[:, 0]]
    near = tensor(np.array([[p.near_m] for p in packs]))[per_tile[:, 0]]
    t_cap = T_CAP_FACTOR * max(p.far_m for p in packs)

    # Seabed on every pixel; then the primitives on their tiles, nearest hit via a packed (t, id) key.
    sb = cols(tensor(np.stack([p.seabed for p in packs]))[per_tile[:, 0]])
    t_bed = geo.seabed_t(torch, dirs, sb, t_cap)
    t_bed = torch.where(t_bed < T_CAP_FACTOR * far, t_bed, torch.inf).to(torch.float32)
    miss_id = (1 << 31) - 1
    key = (t_bed.view(torch.int32).to(torch.int64) << 32) | torch.where(torch.isfinite(t_bed), 0, miss_id)
    key = key.reshape(-1)
    px_of_tile = torch.arange(TILE * TILE, device=dev)[None, :]
    work: list[tuple[str, Any, Any, Any, Any]] = []  # kind, tile rows, constants, gid, px angle
    pairs = [_tile_pairs(p, tiles_x) for p in packs]
    for kind in KINDS:
        rows, tiles_g, gids = [], [], []
        for s_i, (p, (prim, tile)) in enumerate(zip(packs, pairs, strict=True)):
            of_kind = np.array([kd == kind for kd, _ in p.prims], dtype=bool)
            if not of_kind.any() or prim.size == 0:
                continue
            sel = of_kind[prim]
            table = np.stack([row for kd, row in p.prims if kd == kind])
            local = np.cumsum(of_kind) - 1  # row of each primitive of this kind in `table`
            rows.append(table[local[prim[sel]]])
            tiles_g.append(s_i * n_tiles + tile[sel])
            gids.append(prim[sel] + 1)
        n_pairs = sum(len(g) for g in gids)
        if n_pairs == 0:
            continue
        consts = tensor(np.concatenate(rows))
        tile_t = torch.as_tensor(np.concatenate(tiles_g), device=dev)
        gid_t = torch.as_tensor(np.concatenate(gids), device=dev)[:, None]
        step = max(1, PAIR_CHUNK_PX // (TILE * TILE))
        for a in range(0, n_pairs, step):
            sl = slice(a, a + step)
            tl = tile_t[sl]
            k = cols(consts[sl])
            pa = inv_f[per_tile[tl, 0]]
            work.append((kind, tl, k, gid_t[sl], pa))
            dd = tuple(x[tl] for x in dirs)
            t = _t_kernel(kind, torch, dd, k, pa).to(torch.float32)
            pair_key = (t.view(torch.int32).to(torch.int64) << 32) | gid_t[sl]
            idx = (tl[:, None] * (TILE * TILE) + px_of_tile).reshape(-1)
            key.scatter_reduce_(0, idx, pair_key.reshape(-1), reduce="amin")
    key = key.reshape(b * n_tiles, TILE * TILE)
    t_buf = (key >> 32).to(torch.int32).view(torch.float32).to(dtype)
    id_buf = key & 0xFFFFFFFF
    id_buf = torch.where(id_buf == miss_id, -1, id_buf)

    # Surface attributes: the seabed everywhere, then each pair over the pixels its primitive won.
    cam = tensor(np.stack([p.frame.position for p in packs]))[per_tile[:, 0]]
    t_fin = torch.clamp(t_buf, max=t_cap)
    attrs = list(geo.seabed_surface(torch, dirs, t_fin, sb, (cam[:, 0:1], cam[:, 1:2])))
    flat_attrs = [a.reshape(-1).clone() for a in attrs]
    for kind, tl, k, gid, _pa in work:
        dd = tuple(x[tl] for x in dirs)
        mine = id_buf[tl] == gid
        if not bool(mine.any()):
            continue
        vals = _surface_kernel(kind, torch, dd, t_fin[tl], k)
        idx = (tl[:, None] * (TILE * TILE) + px_of_tile)[mine]
        for dst, val in zip(flat_attrs, vals, strict=True):
            dst[idx] = val[mine]
    nx, ny, nz, u, v = (a.reshape(b * n_tiles, TILE * TILE) for a in flat_attrs)
    miss = id_buf < 0
    nx, ny, u, v = (torch.where(miss, 0.0, a) for a in (nx, ny, u, v))
    nz = torch.where(miss, 1.0, nz)

    # Materials per pixel, then the shading formula shared with numpy.
    gmax = max(len(p.material_of_id) for p in packs)
    mmax = max(p.materials.shape[0] for p in packs)
    mat_of_id = np.zeros((b, gmax), dtype=np.int64)
    tables = np.zeros((b, mmax, MATERIAL_FIELDS), dtype=np.float32)
    for s_i, p in enumerate(packs):
        mat_of_id[s_i, : len(p.material_of_id)] = p.material_of_id + s_i * mmax
        tables[s_i, : p.materials.shape[0]] = p.materials
    mid = torch.as_tensor(mat_of_id, device=dev).reshape(-1)[per_tile * gmax + id_buf.clamp(min=0)]
    rows_m = tensor(tables.reshape(b * mmax, MATERIAL_FIELDS))[mid.reshape(-1)]
    rows_m = rows_m.reshape(b * n_tiles, TILE * TILE, MATERIAL_FIELDS)
    mat = [rows_m[..., j] for j in range(MATERIAL_FIELDS)]
    tile_tex = tensor(np.array(noise_tile()))

    def lookup(x: Any, y: Any) -> Any:
        return lookup_torch(tile_tex, x, y)

    image_rgb = None
    if names:
        image_rgb = _image_texture_torch([tex[n] for n in names], mat, (u, v), dev, dtype)
    light = cols(tensor(np.stack([p.light for p in packs]))[per_tile[:, 0]])
    r, g, bl = shade(torch, t_buf, dirs, (nx, ny, nz), (u, v), cos_axis, mat, light, lookup, image_rgb)
    dist = torch.minimum(torch.maximum(t_buf, near), far)

    def untile(x: Any) -> Any:
        x = x.reshape(b, tiles_y, tiles_x, TILE, TILE).permute(0, 1, 3, 2, 4).reshape(b, hp, wp)
        return x[:, :height, :width]

    rgb = torch.stack([untile(r), untile(g), untile(bl)], dim=1)
    return rgb, untile(dist)[:, None]


def _image_texture_torch(
    textures: Sequence[np.ndarray], mat: list[Any], uv: tuple[Any, Any], dev: Any, dtype: Any
) -> tuple[Any, Any, Any]:
    import torch

    idx = mat[23]
    su = uv[0] * (mat[20] * float(IMAGE_TEXTURE_PX))
    sv = uv[1] * (mat[20] * float(IMAGE_TEXTURE_PX))
    x = wrap_coords(torch, su + mat[21], IMAGE_TEXTURE_PX)
    y = wrap_coords(torch, sv + mat[22], IMAGE_TEXTURE_PX)
    out = torch.zeros((*idx.shape, 3), device=dev, dtype=dtype)
    for i, tex in enumerate(textures):
        sel = idx == i
        if bool(sel.any()):
            table = torch.as_tensor(tex, device=dev).to(dtype)
            out = torch.where(sel[..., None], lookup_torch(table, x, y), out)
    return out[..., 0], out[..., 1], out[..., 2]


__all__ = [
    "TILE_PX",
    "CameraFrame",
    "PackedScene",
    "camera_frame",
    "intrinsics",
    "pack_scene",
    "render_packed_numpy",
    "render_scene",
    "render_scenes_torch",
    "screen_rect",
]
