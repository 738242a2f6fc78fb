"""Sampling of procedural construction-site scenes (the random half of sample-then-render).

:func:`sample_scene` draws a seabed, a camera, lighting, materials and a site layout (a caisson quay, a
tetrapod breakwater, pile rows or a mix) into a frozen :class:`~murk.scenes.params.SceneParams`. It uses only
the generator it is given, in a fixed order, so one seed always gives the same scene; the CLI seeds scene
``i`` with ``murk.rng.derive_seed(seed, i)`` so that results never depend on the number of workers.

Objects are placed where the camera sees them (on the seabed footprint of the view, or standing up into it),
and every object closer to the camera than ``near_m`` (plus a margin) is dropped, so the depth map never
needs clamping at the near end.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from murk.rng import RngLike, as_generator
from murk.scenes.config import SceneConfig
from murk.scenes.geometry import N_WAVES, net_axes, rotation_matrix, rotation_rows
from murk.scenes.params import (
    RGB,
    Box,
    Camera,
    Frustum,
    Lighting,
    Material,
    MaterialKind,
    Net,
    Primitive,
    SceneObject,
    SceneParams,
    Seabed,
    Sphere,
    Vec3,
    Wave,
)

CLEARANCE_M = 0.05
"""Extra distance beyond ``near_m`` kept between the camera and every object."""
_TETRA_POLAR = math.acos(-1.0 / 3.0)  # angle between the upward leg and each of the three lower legs


def seabed_height(bed: Seabed, x: float | np.ndarray, y: float | np.ndarray) -> float | np.ndarray:
    """Height (m) of the seabed at world ``(x, y)``: ``z0 + sx x + sy y + sum(a sin(kx x + ky y + phase))``."""
    z = bed.z0_m + bed.slope[0] * x + bed.slope[1] * y
    for w in bed.waves:
        z = z + w.amplitude_m * np.sin(w.wavevector_per_m[0] * x + w.wavevector_per_m[1] * y + w.phase_rad)
    return z


def _u(rng: np.random.Generator, lo: float, hi: float) -> float:
    """A uniform draw from [lo, hi]; an empty range (hi < lo, possible at extreme camera poses) gives lo."""
    return float(rng.uniform(lo, max(lo, hi)))


def _count(rng: np.random.Generator, lo: int, hi: int, density: float) -> int:
    """An object count in [lo, hi] scaled by ``density`` (rounded stochastically)."""
    n = int(rng.integers(lo, hi + 1)) * density
    return math.floor(n + rng.random())


def _rgb(rng: np.random.Generator, rgb: RGB, jitter: float, gain: tuple[float, float] = (0.85, 1.15)) -> RGB:
    g = _u(rng, *gain)
    vals = [min(1.0, max(0.0, c * g + _u(rng, -jitter, jitter))) for c in rgb]
    return (round(vals[0], 4), round(vals[1], 4), round(vals[2], 4))


@dataclass
class _Site:
    """Mutable state while one scene is assembled."""

    rng: np.random.Generator
    cfg: SceneConfig
    bed: Seabed
    cam: np.ndarray
    yaw: float
    tan_half: float
    r_lo: float
    r_hi: float
    growth: float
    materials: list[Material] = field(default_factory=list)
    objects: list[SceneObject] = field(default_factory=list)
    footprints: list[tuple[float, float, float]] = field(default_factory=list)
    gravel_index: int | None = None

    def gravel(self) -> int:
        """The scene's gravel material (rubble-mound caps): the seabed's colours, coarser and darker."""
        if self.gravel_index is None:
            bed = self.materials[0]
            dark = _u(self.rng, 0.85, 0.97)
            self.gravel_index = self.material(
                dataclasses.replace(
                    bed,
                    kind="rock",
                    rgb_a=tuple(round(c * dark, 4) for c in bed.rgb_a),  # type: ignore[arg-type]
                    rgb_b=tuple(round(c * dark * 0.85, 4) for c in bed.rgb_b),  # type: ignore[arg-type]
                    contrast=min(1.5, bed.contrast * 1.3),
                    speckle=min(0.6, bed.speckle + 0.15),
                    growth=bed.growth * 0.5,
                    ripple=0.0,
                    scale_m=_u(self.rng, 0.4, 0.8),
                    offset=(_u(self.rng, 0, 1), _u(self.rng, 0, 1)),
                )
            )
        return self.gravel_index

    def material(self, m: Material) -> int:
        self.materials.append(m)
        return len(self.materials) - 1

    def ground(self, x: float, y: float) -> float:
        return float(seabed_height(self.bed, x, y))

    def point(self, r: float, lateral: float) -> tuple[float, float]:
        """World (x, y) at range ``r`` along the view and ``lateral`` (fraction of the half view width)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        off = lateral * r * self.tan_half
        return float(self.cam[0] + r * c - off * s), float(self.cam[1] + r * s + off * c)

    def free(self, x: float, y: float, radius: float) -> bool:
        return all(math.hypot(x - fx, y - fy) >= radius + fr for fx, fy, fr in self.footprints)

    def add(self, kind: str, prims: list[Primitive], footprint: tuple[float, float, float] | None = None) -> bool:
        """Add an object unless a primitive comes within near_m + clearance of the camera."""
        if not prims or min(_distance(p, self.cam) for p in prims) < self.cfg.near_m + CLEARANCE_M:
            return False
        self.objects.append(SceneObject(kind, tuple(prims)))  # type: ignore[arg-type]
        if footprint is not None:
            self.footprints.append(footprint)
        return True


def _distance(p: Primitive, cam: np.ndarray) -> float:
    """A lower bound of the distance from ``cam`` to primitive ``p`` (exact for boxes and spheres)."""
    cx, cy, cz = float(cam[0]), float(cam[1]), float(cam[2])
    if isinstance(p, Box):
        qx, qy, qz = cx - p.center_m[0], cy - p.center_m[1], cz - p.center_m[2]
        r = rotation_rows(*p.rotation_deg)
        # Camera in the box frame: R^T q, i.e. the dot products of q with R's columns.
        out = 0.0
        for j in range(3):
            lj = qx * r[0][j] + qy * r[1][j] + qz * r[2][j]
            e = abs(lj) - p.half_size_m[j]
            out += e * e if e > 0 else 0.0
        return math.sqrt(out)
    if isinstance(p, Sphere):
        return math.dist((cx, cy, cz), p.center_m) - p.radius_m
    if isinstance(p, Frustum):
        a, b = p.start_m, p.end_m
        ab = (b[0] - a[0], b[1] - a[1], b[2] - a[2])
        aq = (cx - a[0], cy - a[1], cz - a[2])
        s = (aq[0] * ab[0] + aq[1] * ab[1] + aq[2] * ab[2]) / (ab[0] ** 2 + ab[1] ** 2 + ab[2] ** 2)
        s = min(1.0, max(0.0, s))
        near = (a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2])
        return math.dist((cx, cy, cz), near) - max(p.radius_start_m, p.radius_end_m)
    u, v, n = net_axes(*p.rotation_deg)
    q = cam - np.asarray(p.center_m)
    local = np.abs(np.array([q @ u, q @ v, q @ n])) - np.array([*p.half_size_m, 0.02])
    return float(np.linalg.norm(np.maximum(local, 0.0)))


def _v(x: float, y: float, z: float) -> Vec3:
    return (round(x, 5), round(y, 5), round(z, 5))


# ------------------------------------------------------------------------------------------------ materials


def _sand(s: _Site) -> Material:
    rng = s.rng
    kind = rng.choice(["sand", "sand", "mud", "gravel"])
    if kind == "sand":
        a, b, ripple = (0.72, 0.66, 0.52), (0.55, 0.50, 0.40), _u(rng, 0.0, 0.06)
    elif kind == "mud":
        a, b, ripple = (0.50, 0.47, 0.40), (0.38, 0.36, 0.31), 0.0
    else:
        a, b, ripple = (0.58, 0.56, 0.52), (0.36, 0.34, 0.32), 0.0
    return Material(
        kind="rock" if kind == "gravel" else "sand",
        rgb_a=_rgb(rng, a, 0.03),
        rgb_b=_rgb(rng, b, 0.03),
        contrast=_u(rng, 0.5, 1.0),
        speckle=_u(rng, 0.1, 0.3) if kind != "gravel" else _u(rng, 0.3, 0.5),
        stain=_u(rng, 0.05, 0.3),
        stain_rgb=_rgb(rng, (0.32, 0.30, 0.25), 0.03),
        growth=_u(rng, 0.0, 0.3) * s.growth,
        growth_rgb=_rgb(rng, (0.34, 0.35, 0.26), 0.03),
        ripple=ripple,
        ripple_wavelength_m=_u(rng, 0.08, 0.25),
        joint_spacing_m=0.0,
        scale_m=_u(rng, 1.0, 2.5),
        offset=(_u(rng, 0, 1), _u(rng, 0, 1)),
        texture=_texture(s),
    )


def _growth_rgb(rng: np.random.Generator) -> RGB:
    choice = int(rng.choice([0, 0, 1, 1, 2, 3]))
    base = [(0.36, 0.38, 0.26), (0.28, 0.31, 0.22), (0.20, 0.19, 0.16), (0.55, 0.54, 0.49)][choice]
    return _rgb(rng, base, 0.04)


def _concrete(s: _Site, joints: bool) -> Material:
    rng = s.rng
    grey = _u(rng, 0.5, 0.72)
    warm = _u(rng, -0.03, 0.04)
    a = (grey + warm, grey + 0.5 * warm, grey - warm)
    return Material(
        kind="concrete",
        rgb_a=_rgb(rng, a, 0.02, (0.98, 1.02)),
        rgb_b=_rgb(rng, (a[0] * 0.78, a[1] * 0.78, a[2] * 0.78), 0.02, (0.98, 1.02)),
        contrast=_u(rng, 0.35, 0.8),
        speckle=_u(rng, 0.1, 0.3),
        stain=_u(rng, 0.1, 0.45),
        stain_rgb=_rgb(rng, (0.40, 0.33, 0.25), 0.05),
        growth=_u(rng, 0.1, 1.0) * s.growth,
        growth_rgb=_growth_rgb(rng),
        ripple=0.0,
        ripple_wavelength_m=1.0,
        joint_spacing_m=_u(rng, 1.0, 2.5) if joints else 0.0,
        scale_m=_u(rng, 0.8, 2.0),
        offset=(_u(rng, 0, 1), _u(rng, 0, 1)),
        texture=_texture(s),
    )


def _rust(s: _Site, painted: bool = False) -> Material:
    rng = s.rng
    kind: MaterialKind
    if painted:
        base = [(0.30, 0.30, 0.32), (0.55, 0.47, 0.22), (0.22, 0.26, 0.30)][int(rng.integers(0, 3))]
        a, b, kind = base, (base[0] * 0.7, base[1] * 0.7, base[2] * 0.7), "steel"
        stain, stain_rgb = _u(rng, 0.3, 0.7), (0.42, 0.24, 0.12)
    else:
        a, b, kind = (0.46, 0.27, 0.15), (0.28, 0.16, 0.10), "rust"
        stain, stain_rgb = _u(rng, 0.2, 0.5), (0.16, 0.12, 0.10)
    return Material(
        kind=kind,
        rgb_a=_rgb(rng, a, 0.03),
        rgb_b=_rgb(rng, b, 0.03),
        contrast=_u(rng, 0.5, 1.0),
        speckle=_u(rng, 0.1, 0.3),
        stain=stain,
        stain_rgb=_rgb(rng, stain_rgb, 0.03),
        growth=_u(rng, 0.0, 0.8) * s.growth,
        growth_rgb=_growth_rgb(rng),
        ripple=0.0,
        ripple_wavelength_m=1.0,
        joint_spacing_m=0.0,
        scale_m=_u(rng, 0.5, 1.5),
        offset=(_u(rng, 0, 1), _u(rng, 0, 1)),
    )


def _rock(s: _Site) -> Material:
    rng = s.rng
    g = _u(rng, 0.38, 0.62)
    tint = _u(rng, -0.05, 0.05)
    return Material(
        kind="rock",
        rgb_a=_rgb(rng, (g + tint, g, g - tint), 0.03),
        rgb_b=_rgb(rng, (0.55 * g + tint, 0.55 * g, 0.55 * g - tint), 0.03),
        contrast=_u(rng, 0.8, 1.4),
        speckle=_u(rng, 0.2, 0.45),
        stain=_u(rng, 0.1, 0.4),
        stain_rgb=_rgb(rng, (0.25, 0.24, 0.20), 0.03),
        growth=_u(rng, 0.0, 1.0) * s.growth,
        growth_rgb=_growth_rgb(rng),
        ripple=0.0,
        ripple_wavelength_m=1.0,
        joint_spacing_m=0.0,
        scale_m=_u(rng, 0.3, 0.8),
        offset=(_u(rng, 0, 1), _u(rng, 0, 1)),
        texture=_texture(s),
    )


def _rope(s: _Site) -> Material:
    rng = s.rng
    base = [(0.12, 0.14, 0.11), (0.20, 0.24, 0.16), (0.70, 0.45, 0.12), (0.55, 0.55, 0.50)][int(rng.integers(0, 4))]
    return Material(
        kind="rope",
        rgb_a=_rgb(rng, base, 0.02),
        rgb_b=_rgb(rng, (base[0] * 0.7, base[1] * 0.7, base[2] * 0.7), 0.02),
        contrast=0.5,
        speckle=0.0,
        stain=0.0,
        stain_rgb=(0.0, 0.0, 0.0),
        growth=_u(rng, 0.0, 0.5) * s.growth,
        growth_rgb=_growth_rgb(rng),
        ripple=0.0,
        ripple_wavelength_m=1.0,
        joint_spacing_m=0.0,
        scale_m=1.0,
        offset=(_u(rng, 0, 1), _u(rng, 0, 1)),
    )


def _texture(s: _Site) -> str | None:
    names = s.cfg.texture_names
    if not names:
        return None
    if s.rng.random() >= s.cfg.texture_probability:
        return None
    return str(names[int(s.rng.integers(0, len(names)))])


# ------------------------------------------------------------------------------------------------ objects


def _box_on_ground(s: _Site, x: float, y: float, half: Vec3, yaw: float, tilt: float, sink: float) -> Box:
    z = s.ground(x, y) + half[2] - sink
    rot = (yaw, _u(s.rng, -tilt, tilt), _u(s.rng, -tilt, tilt))
    return Box(_v(x, y, z), half, (round(rot[0], 3), round(rot[1], 3), round(rot[2], 3)), 0)


def _with_material(prims: list[Primitive], material: int) -> list[Primitive]:
    return [dataclasses.replace(p, material=material) for p in prims]


def _block(s: _Site, x: float, y: float, mat: int, size: tuple[float, float] = (0.8, 2.2)) -> bool:
    rng = s.rng
    a = _u(rng, *size)
    half = (round(a / 2, 4), round(a * _u(rng, 0.5, 1.0), 4), round(a * _u(rng, 0.35, 0.6), 4))
    radius = math.hypot(half[0], half[1])
    if not s.free(x, y, radius):
        return False
    box = _box_on_ground(s, x, y, half, _u(rng, 0, 360), 8.0, _u(rng, 0.05, 0.3) * half[2])
    prims: list[Primitive] = [box]
    if rng.random() < 0.3:  # a second block stacked on top
        top = box.center_m[2] + half[2]
        half2 = (round(half[0] * 0.8, 4), round(half[1] * 0.8, 4), round(half[2] * 0.9, 4))
        prims.append(Box(_v(x, y, top + half2[2] - 0.01), half2, (box.rotation_deg[0] + _u(rng, -20, 20), 0, 0), 0))
    return s.add("block", _with_material(prims, mat), (x, y, radius))


def _tetrapod(s: _Site, x: float, y: float, leg_m: float, mat: int, lift_m: float, tumbled: bool) -> bool:
    rng = s.rng
    r_base, r_tip, r_hub = 0.36 * leg_m, 0.22 * leg_m, 0.42 * leg_m
    if tumbled:
        rot = rotation_matrix(_u(rng, 0, 360), _u(rng, -90, 90), _u(rng, -180, 180))
        z = s.ground(x, y) + lift_m + 0.25 * leg_m
    else:
        rot = rotation_matrix(_u(rng, 0, 360), _u(rng, -6, 6), _u(rng, -6, 6))
        z = s.ground(x, y) + lift_m + leg_m * math.cos(math.pi - _TETRA_POLAR) + 0.4 * r_tip
    legs = [np.array([0.0, 0.0, 1.0])]
    for k in range(3):
        az = 2.0 * math.pi * k / 3.0
        legs.append(
            np.array(
                [math.sin(_TETRA_POLAR) * math.cos(az), math.sin(_TETRA_POLAR) * math.sin(az), math.cos(_TETRA_POLAR)]
            )
        )
    c = np.array([x, y, z])
    prims: list[Primitive] = [Sphere(_v(*c), round(r_hub, 4), mat)]
    for leg in legs:
        tip = c + leg_m * (rot @ leg)
        prims.append(Frustum(_v(*c), _v(*tip), round(r_base, 4), round(r_tip, 4), mat))
    return s.add("tetrapod", prims, (x, y, 0.8 * leg_m))


def _mound(s: _Site, x: float, y: float, radius: float, height: float) -> tuple[float, float, float]:
    """(centre z, sphere radius, ground z) of a rubble mound: a buried sphere whose cap has ``radius`` and
    ``height`` above the seabed at (x, y)."""
    big = (radius * radius + height * height) / (2.0 * height)
    g = s.ground(x, y)
    return g + height - big, big, g


def _mound_top(s: _Site, x: float, y: float, cx: float, cy: float, mound: tuple[float, float, float]) -> float:
    """Height of the rubble mound (or the seabed, whichever is higher) at (x, y)."""
    cz, big, _ = mound
    rho2 = (x - cx) ** 2 + (y - cy) ** 2
    top = cz + math.sqrt(big * big - rho2) if rho2 < big * big else -math.inf
    return max(top, s.ground(x, y))


def _rubble(
    s: _Site, x: float, y: float, radius: float, n: int, mats: list[int], height: float | None = None
) -> tuple[float, float, float] | None:
    """A rubble mound (a low gravel cap) with ``n`` loose stones on it; returns the mound (see _mound)."""
    rng = s.rng
    height = _u(rng, 0.08, 0.25) * radius if height is None else height
    mound = _mound(s, x, y, radius, height)
    prims: list[Primitive] = []
    cap = Sphere(_v(x, y, mound[0]), round(mound[1], 4), s.gravel())
    if _distance(cap, s.cam) >= s.cfg.near_m + CLEARANCE_M:
        prims.append(cap)
    for i in range(n):
        # Half of the stones line the rim, where the gravel cap meets the seabed.
        rho = radius * (_u(rng, 0.85, 1.1) if i % 2 == 0 else math.sqrt(rng.random()))
        ang = _u(rng, 0, 2 * math.pi)
        px, py = x + rho * math.cos(ang), y + rho * math.sin(ang)
        a = _u(rng, 0.08, 0.3)
        half = (round(a, 4), round(a * _u(rng, 0.6, 1.0), 4), round(a * _u(rng, 0.4, 0.8), 4))
        z = _mound_top(s, px, py, x, y, mound) + 0.3 * half[2]
        rot = (round(_u(rng, 0, 360), 3), round(_u(rng, -35, 35), 3), round(_u(rng, -35, 35), 3))
        mat = mats[int(rng.integers(0, len(mats)))]
        box = Box(_v(px, py, z), half, rot, mat)
        if _distance(box, s.cam) >= s.cfg.near_m + CLEARANCE_M:
            prims.append(box)
    return mound if s.add("rubble", prims) else None


def _pile(s: _Site, x: float, y: float, radius: float, height: float, mat: int, tilt: float = 3.0) -> bool:
    if not s.free(x, y, radius + 0.1):
        return False
    g = s.ground(x, y)
    tx, ty = math.tan(math.radians(_u(s.rng, -tilt, tilt))), math.tan(math.radians(_u(s.rng, -tilt, tilt)))
    top = (x + tx * height, y + ty * height, g + height)
    prim = Frustum(_v(x - tx, y - ty, g - 1.0), _v(*top), round(radius, 4), round(radius, 4), mat)
    return s.add("pile", [prim], (x, y, radius))


def _pipe(s: _Site, x: float, y: float, mat: int) -> bool:
    rng = s.rng
    radius, length, yaw = _u(rng, 0.1, 0.5), _u(rng, 2.5, 9.0), _u(rng, 0, 2 * math.pi)
    dx, dy = 0.5 * length * math.cos(yaw), 0.5 * length * math.sin(yaw)
    sink = _u(rng, 0.1, 0.5) * radius
    a = (x - dx, y - dy, s.ground(x - dx, y - dy) + radius - sink)
    b = (x + dx, y + dy, s.ground(x + dx, y + dy) + radius - sink)
    return s.add("pipe", [Frustum(_v(*a), _v(*b), round(radius, 4), round(radius, 4), mat)])


def _rebar(s: _Site, x: float, y: float, z: float, spread: float, mat: int) -> bool:
    rng = s.rng
    prims: list[Primitive] = []
    for _ in range(int(rng.integers(3, 11))):
        px, py = x + _u(rng, -spread, spread), y + _u(rng, -spread, spread)
        length = _u(rng, 0.3, 1.4)
        tilt, az = math.radians(_u(rng, 0, 35)), _u(rng, 0, 2 * math.pi)
        top = (px + length * math.sin(tilt) * math.cos(az), py + length * math.sin(tilt) * math.sin(az))
        radius = round(_u(rng, 0.008, 0.018), 4)
        prims.append(Frustum(_v(px, py, z - 0.1), _v(*top, z + length * math.cos(tilt)), radius, radius, mat))
    return s.add("rebar", prims)


def _net(s: _Site, x: float, y: float, rope: int, post: int) -> bool:
    rng = s.rng
    hu, hv = _u(rng, 1.2, 4.0), _u(rng, 0.6, 1.5)
    yaw = math.degrees(s.yaw) + 90.0 + _u(rng, -50, 50)
    z = s.ground(x, y) + hv + _u(rng, 0.0, 0.3)
    rotation = (round(yaw, 3), round(_u(rng, -8, 8), 3))
    spacing, thread = round(_u(rng, 0.05, 0.25), 4), round(_u(rng, 0.003, 0.01), 4)
    net = Net(_v(x, y, z), (round(hu, 4), round(hv, 4)), rotation, spacing, thread, rope)
    u_axis, _, _ = net_axes(yaw, 0.0)
    prims: list[Primitive] = [net]
    r_post = round(_u(rng, 0.03, 0.07), 4)
    for side in (-1.0, 1.0):
        px, py = x + side * hu * u_axis[0], y + side * hu * u_axis[1]
        g = s.ground(px, py)
        prims.append(Frustum(_v(px, py, g - 0.3), _v(px, py, z + hv + 0.15), r_post, r_post, post))
    return s.add("net", prims, None)


def _caisson_wall(s: _Site, r: float, behind: float = 0.0) -> tuple[float, float, float] | None:
    """A row of 1-3 caissons; returns (x, y, wall yaw in rad) of the wall's middle, or None."""
    rng = s.rng
    mat = s.material(_concrete(s, joints=True))
    x0, y0 = s.point(r + behind, _u(rng, -0.3, 0.3))
    wall_yaw = s.yaw + math.pi / 2 + math.radians(_u(rng, -35, 35))
    ux, uy = math.cos(wall_yaw), math.sin(wall_yaw)
    # Unit normal of the wall pointing away from the camera.
    nx, ny = -uy, ux
    if (x0 - s.cam[0]) * nx + (y0 - s.cam[1]) * ny < 0:
        nx, ny = -nx, -ny
    n = int(rng.integers(1, 4))
    length, depth, height = _u(rng, 5, 10), _u(rng, 4, 8), _u(rng, 3, 9)
    gap = _u(rng, 0.05, 0.4)
    added = False
    for k in range(n):
        off = (k - (n - 1) / 2) * (length + gap)
        cx, cy = x0 + off * ux + 0.5 * depth * nx, y0 + off * uy + 0.5 * depth * ny
        g = s.ground(cx, cy)
        half = (round(length / 2, 4), round(depth / 2, 4), round(height / 2 + 0.25, 4))
        box = Box(_v(cx, cy, g + half[2] - 0.5), half, (round(math.degrees(wall_yaw), 3), 0.0, 0.0), mat)
        added |= s.add("caisson", [box], (cx, cy, 0.5 * math.hypot(length, depth)))
    return (x0, y0, wall_yaw) if added else None


# ------------------------------------------------------------------------------------------------ layouts


def _layout_quay(s: _Site) -> None:
    rng, dens = s.rng, s.cfg.density
    r = _u(rng, max(s.r_lo + 1.0, 2.5), max(s.r_lo + 2.0, min(12.0, s.r_hi + 2.0)))
    wall = _caisson_wall(s, r)
    if wall is None:
        return
    x0, y0, wy = wall
    ux, uy = math.cos(wy), math.sin(wy)
    nx, ny = s.cam[0] - x0, s.cam[1] - y0
    norm = math.hypot(nx, ny) or 1.0
    nx, ny = nx / norm, ny / norm
    blocks = s.material(_concrete(s, joints=False))
    rock = [s.material(_rock(s)) for _ in range(int(rng.integers(1, 3)))]
    rust = s.material(_rust(s))
    for _ in range(_count(rng, 2, 6, dens)):
        along, out = _u(rng, -6, 6), _u(rng, 1.0, 3.0)
        bx, by = x0 + along * ux + out * nx, y0 + along * uy + out * ny
        if _block(s, bx, by, blocks, (0.8, 1.8)) and rng.random() < 0.35:
            top = s.objects[-1].primitives[-1]
            assert isinstance(top, Box)
            _rebar(s, bx, by, top.center_m[2] + top.half_size_m[2], 0.4 * top.half_size_m[0], rust)
    for _ in range(_count(rng, 1, 2, dens)):
        along = _u(rng, -5, 5)
        _rubble(s, x0 + along * ux + 0.8 * nx, y0 + along * uy + 0.8 * ny, _u(rng, 1.0, 2.5), 25, rock)


def _layout_breakwater(s: _Site) -> None:
    rng, dens = s.rng, s.cfg.density
    r = _u(rng, max(s.r_lo + 1.5, 2.5), max(s.r_lo + 2.5, min(10.0, s.r_hi + 2.0)))
    hx, hy = s.point(r, _u(rng, -0.4, 0.4))
    heap_r = _u(rng, 2.0, 4.5)
    mound = _u(rng, 0.3, 1.5)
    rock = [s.material(_rock(s)) for _ in range(int(rng.integers(1, 3)))]
    conc = s.material(_concrete(s, joints=False))
    if rng.random() < 0.4:
        _caisson_wall(s, r, behind=heap_r + 1.0)
    cap = _rubble(s, hx, hy, heap_r * 1.2, 30, rock, height=mound)
    leg = _u(rng, 0.6, 1.3)
    for _ in range(_count(rng, 4, 12, dens)):
        rho, ang = heap_r * math.sqrt(rng.random()), _u(rng, 0, 2 * math.pi)
        tx, ty = hx + rho * math.cos(ang), hy + rho * math.sin(ang)
        lift = _mound_top(s, tx, ty, hx, hy, cap) - s.ground(tx, ty) if cap is not None else 0.0
        _tetrapod(s, tx, ty, leg * _u(rng, 0.9, 1.1), conc, lift, tumbled=rng.random() < 0.6)


def _layout_piles(s: _Site) -> None:
    rng, dens = s.rng, s.cfg.density
    for _ in range(int(rng.integers(1, 3))):
        steel = rng.random() < 0.7
        mat = s.material(_rust(s, painted=rng.random() < 0.4) if steel else _concrete(s, joints=False))
        r = _u(rng, max(s.r_lo + 1.0, 2.0), max(s.r_lo + 2.0, min(11.0, s.r_hi + 2.0)))
        x0, y0 = s.point(r, _u(rng, -0.5, 0.5))
        row_yaw = s.yaw + math.radians(_u(rng, 20, 160))
        spacing, radius, height = _u(rng, 1.8, 4.0), _u(rng, 0.25, 0.6), _u(rng, 4.0, 14.0)
        n = _count(rng, 3, 8, dens)
        for k in range(n):
            off = (k - (n - 1) / 2) * spacing
            _pile(s, x0 + off * math.cos(row_yaw), y0 + off * math.sin(row_yaw), radius, height, mat)
    pipe_mat = s.material(
        _rust(s) if rng.random() < 0.5 else _rope(s) if rng.random() < 0.5 else _concrete(s, joints=False)
    )
    for _ in range(_count(rng, 0, 3, dens)):
        _pipe(s, *s.point(_u(rng, s.r_lo + 0.5, max(s.r_lo + 1.0, s.r_hi)), _u(rng, -0.8, 0.8)), pipe_mat)
    if rng.random() < 0.6 * min(1.0, dens):
        rope, post = s.material(_rope(s)), s.material(_rust(s))
        _net(s, *s.point(_u(rng, max(1.5, s.r_lo), max(2.0, min(8.0, s.r_hi))), _u(rng, -0.4, 0.4)), rope, post)
    if rng.random() < 0.5:
        rock = [s.material(_rock(s))]
        _rubble(s, *s.point(_u(rng, s.r_lo, max(s.r_lo + 0.5, s.r_hi)), _u(rng, -0.6, 0.6)), 1.5, 20, rock)


def _layout_mixed(s: _Site) -> None:
    rng, dens = s.rng, s.cfg.density
    conc = s.material(_concrete(s, joints=False))
    rock = [s.material(_rock(s))]
    rust = s.material(_rust(s))

    def somewhere(lo: float = 0.0) -> tuple[float, float]:
        return s.point(_u(rng, max(s.r_lo, lo), max(s.r_lo + 1.0, s.r_hi)), _u(rng, -0.9, 0.9))

    if rng.random() < 0.35:
        _caisson_wall(s, _u(rng, max(5.0, s.r_lo + 3.0), 12.0))
    for _ in range(_count(rng, 1, 5, dens)):
        x, y = somewhere(1.0)
        if _block(s, x, y, conc) and rng.random() < 0.3:
            top = s.objects[-1].primitives[-1]
            assert isinstance(top, Box)
            _rebar(s, x, y, top.center_m[2] + top.half_size_m[2], 0.4 * top.half_size_m[0], rust)
    for _ in range(_count(rng, 0, 3, dens)):
        x, y = somewhere(1.5)
        _tetrapod(s, x, y, _u(rng, 0.6, 1.2), conc, 0.0, tumbled=rng.random() < 0.3)
    pile_mat = s.material(_rust(s, painted=rng.random() < 0.5))
    for _ in range(_count(rng, 0, 3, dens)):
        _pile(s, *somewhere(2.0), _u(rng, 0.25, 0.5), _u(rng, 3.0, 12.0), pile_mat)
    for _ in range(_count(rng, 0, 2, dens)):
        _pipe(s, *somewhere(), rust)
    for _ in range(_count(rng, 0, 2, dens)):
        _rubble(s, *somewhere(), _u(rng, 0.6, 2.0), int(rng.integers(10, 30)), rock)
    if rng.random() < 0.3 * min(1.0, dens):
        _net(s, *somewhere(1.5), s.material(_rope(s)), rust)
    if rng.random() < 0.3 * min(1.0, dens):
        x, y = somewhere()
        _rebar(s, x, y, s.ground(x, y), 0.5, rust)


def _near_object(s: _Site) -> None:
    """Something close to the camera (0.5-2.5 m) so that short distances occur."""
    rng = s.rng
    x, y = s.point(_u(rng, 0.5, 2.5) + 0.5 * (s.r_lo if s.r_lo < 3 else 0.0), _u(rng, -0.8, 0.8))
    choice = int(rng.integers(0, 3))
    if choice == 0:
        _block(s, x, y, s.material(_concrete(s, joints=False)), (0.5, 1.2))
    elif choice == 1:
        _rubble(s, x, y, _u(rng, 0.4, 1.0), int(rng.integers(6, 16)), [s.material(_rock(s))])
    else:
        _tetrapod(s, x, y, _u(rng, 0.5, 0.9), s.material(_concrete(s, joints=False)), 0.0, tumbled=False)


_LAYOUTS = {"quay": _layout_quay, "breakwater": _layout_breakwater, "piles": _layout_piles, "mixed": _layout_mixed}


# ------------------------------------------------------------------------------------------------ the scene


def _seabed(rng: np.random.Generator, cfg: SceneConfig) -> tuple[float, float, tuple[Wave, ...]]:
    slope = _u(rng, 0.0, cfg.slope_max)
    ang = _u(rng, 0.0, 2.0 * math.pi)
    total = _u(rng, *cfg.undulation_m)
    waves = []
    share = _u(rng, 0.3, 0.7)
    for i in range(N_WAVES):
        wavelength = _u(rng, 3.0, 12.0)
        k = 2.0 * math.pi / wavelength
        amp = min(total * (share if i == 0 else 1.0 - share), 0.2 / k)  # gradient of each wave <= 0.2
        wd = _u(rng, 0.0, 2.0 * math.pi)
        waves.append(
            Wave(round(amp, 5), (round(k * math.cos(wd), 5), round(k * math.sin(wd), 5)), round(_u(rng, 0, 6.28), 5))
        )
    return slope * math.cos(ang), slope * math.sin(ang), tuple(waves)


def sample_scene(rng: RngLike, config: SceneConfig | None = None) -> SceneParams:
    """Draw one construction-site scene.

    Args:
        rng: a numpy Generator, an int seed, or None for fresh entropy. With an int the seed is recorded in
            the result's ``seed``; otherwise ``seed`` is None.
        config: sampling ranges (default :class:`SceneConfig()`).

    Returns:
        A frozen :class:`SceneParams` for :func:`murk.scenes.render_scene` / ``render_scenes_torch``.

    Raises:
        TypeError: ``rng`` or ``config`` has the wrong type.
    """
    seed = int(rng) if isinstance(rng, (int, np.integer)) and not isinstance(rng, bool) else None
    gen = as_generator(rng)
    cfg = SceneConfig() if config is None else config
    if not isinstance(cfg, SceneConfig):
        raise TypeError(f"config: expected SceneConfig, got {type(cfg).__name__}")

    sx, sy, waves = _seabed(gen, cfg)
    probe = Seabed(0.0, (sx, sy), waves, 0)
    cam_xy = (0.0, 0.0)
    height = _u(gen, *cfg.camera_height_m)
    cam_z = float(seabed_height(probe, *cam_xy)) + height
    yaw = _u(gen, -180.0, 180.0)
    pitch = _u(gen, *cfg.pitch_deg)
    roll = _u(gen, *cfg.roll_deg)
    hfov = _u(gen, *cfg.hfov_deg)
    camera = Camera(_v(*cam_xy, cam_z), round(yaw, 4), round(pitch, 4), round(roll, 4), round(hfov, 4))

    tan_half = math.tan(math.radians(hfov) / 2.0)
    half_v = math.atan(0.75 * tan_half)  # placement assumes a 4:3 image
    below_bottom = math.radians(-pitch) + half_v
    below_top = math.radians(-pitch) - half_v
    r_lo = max(0.6, height / math.tan(below_bottom)) if below_bottom > 0.01 else 0.6
    r_lo = min(r_lo, 0.5 * cfg.far_m)
    r_hi = height / math.tan(below_top) if below_top > 0.02 else cfg.far_m
    r_hi = max(min(r_hi, 0.8 * cfg.far_m), r_lo + 1.0)
    site = _Site(
        rng=gen,
        cfg=cfg,
        bed=probe,
        cam=np.array([cam_xy[0], cam_xy[1], cam_z]),
        yaw=math.radians(yaw),
        tan_half=tan_half,
        r_lo=r_lo,
        r_hi=r_hi,
        growth=cfg.growth_max,
    )
    bed_mat = site.material(_sand(site))
    seabed = Seabed(0.0, (round(sx, 6), round(sy, 6)), waves, bed_mat)
    site.bed = seabed
    layout = cfg.layouts[int(gen.integers(0, len(cfg.layouts)))]
    if cfg.density > 0:
        _LAYOUTS[layout](site)
        if gen.random() < 0.35:
            _near_object(site)
    lighting = _lighting(gen, cfg, yaw)
    return SceneParams(
        seed=seed,
        camera=camera,
        lighting=lighting,
        seabed=seabed,
        materials=tuple(site.materials),
        objects=tuple(site.objects),
        near_m=cfg.near_m,
        far_m=cfg.far_m,
    )


def _lighting(rng: np.random.Generator, cfg: SceneConfig, yaw_deg: float) -> Lighting:
    elev = math.radians(_u(rng, 35.0, 75.0))
    az = math.radians(yaw_deg + 180.0 + _u(rng, -100.0, 100.0))
    sun_dir = (math.cos(elev) * math.cos(az), math.cos(elev) * math.sin(az), math.sin(elev))
    lamp = rng.random() < cfg.lamp_probability
    dim = _u(rng, 0.6, 0.9) if lamp else 1.0
    sun = _u(rng, 0.3, 0.6) * dim
    amb = _u(rng, 0.6, 0.8) * dim
    lamp_level = _u(rng, 0.25, 0.6) if lamp else 0.0
    warm = _u(rng, 0.0, 0.08)
    low = _u(rng, 0.22, 0.35)
    high = _u(rng, 0.45, 0.65)

    def r3(v: tuple[float, float, float]) -> tuple[float, float, float]:
        return (round(v[0], 5), round(v[1], 5), round(v[2], 5))

    bg_low, bg_high = (low * 0.9, low, low * 1.05), (high * 0.88, high, high * 1.05)
    if cfg.water_background > 0 and rng.random() < cfg.water_background:
        bg_low, bg_high = _water_background(rng)
    return Lighting(
        sun_direction=r3(sun_dir),
        sun_rgb=r3((sun * (1 + warm), sun, sun * (1 - warm))),
        ambient_rgb=r3((amb * 0.92, amb, amb * 1.08)),
        lamp_rgb=r3((lamp_level, lamp_level * 0.97, lamp_level * 0.9)),
        lamp_cone_deg=round(_u(rng, 18.0, 40.0), 3),
        lamp_soft_deg=round(_u(rng, 5.0, 20.0), 3),
        lamp_ref_m=round(_u(rng, 1.5, 3.0), 3),
        background_low_rgb=r3(bg_low),
        background_high_rgb=r3(bg_high),
    )


def _water_background(rng: np.random.Generator) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
    """Clear-water background colours (looking down, looking up): blue (``tint`` 0) to cyan-green (1), red low,
    the downward colour 35-65 % of the upward one."""
    tint = _u(rng, 0.0, 1.0)
    level = _u(rng, 0.6, 1.0)
    high = (_u(rng, 0.04, 0.25) * level, (0.40 + 0.25 * tint) * level, (0.80 - 0.25 * tint) * level)
    k = _u(rng, 0.35, 0.65)
    return (high[0] * k, high[1] * k, high[2] * k), high
