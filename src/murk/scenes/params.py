"""Scene parameters: a frozen, JSON-serialisable description of one procedural construction-site scene.

A scene is sampled once (:func:`murk.scenes.sample_scene`) and then rendered deterministically
(:func:`murk.scenes.render_scene`), following DESIGN.md rule 3. Everything the renderer needs is in
:class:`SceneParams`; :meth:`SceneParams.to_dict` gives the ``scene`` object of a ``scenes.jsonl`` line and
:func:`scene_from_dict` reads it back, so any scene can be re-rendered exactly from its line.

World frame: metres, right-handed, ``z`` up. The seabed is the height field of :class:`Seabed`; the camera
looks along yaw/pitch (see :class:`Camera`). Depth convention: the renderer returns the line-of-sight
DISTANCE from the camera centre to the surface along each pixel's ray (what Eq. (1) of the paper needs,
``T = exp(-beta d)`` over the path length), not the z-depth.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, ClassVar, Literal

Vec3 = tuple[float, float, float]
RGB = tuple[float, float, float]

SCENE_FORMAT_VERSION = 1
"""Version of the scene description; bumped when the meaning of a field or of the renderer changes."""

ObjectKind = Literal["caisson", "block", "tetrapod", "pile", "pipe", "rubble", "net", "rebar"]
MaterialKind = Literal["sand", "rock", "concrete", "steel", "rust", "rope", "image"]


@dataclass(frozen=True)
class Camera:
    """A pinhole camera. ``yaw_deg`` turns from +x towards +y, ``pitch_deg`` > 0 looks up, ``roll_deg``
    turns the image clockwise about the viewing axis. ``hfov_deg`` is the horizontal field of view; pixels
    are square, the principal point is the image centre."""

    position_m: Vec3
    yaw_deg: float
    pitch_deg: float
    roll_deg: float
    hfov_deg: float


@dataclass(frozen=True)
class Lighting:
    """Clear-air lighting: a hemispherical ambient term, one directional light and an optional lamp cone.

    ``sun_direction`` points from the scene towards the light (unit vector). The lamp sits at the camera and
    points along its axis; ``lamp_rgb`` is its intensity at ``lamp_ref_m`` (inverse-square falloff), zero to
    switch it off. Rays that hit nothing show the open-water background, a vertical gradient from
    ``background_low_rgb`` (looking down) to ``background_high_rgb`` (looking up).
    """

    sun_direction: Vec3
    sun_rgb: RGB
    ambient_rgb: RGB
    lamp_rgb: RGB
    lamp_cone_deg: float
    lamp_soft_deg: float
    lamp_ref_m: float
    background_low_rgb: RGB
    background_high_rgb: RGB


@dataclass(frozen=True)
class Material:
    """Coefficients of the procedural surface shader (one formula for every material, see shading.py).

    Colours are RGB in [0, 1]. ``scale_m`` is the size of one noise tile on the surface; ``offset`` shifts
    the noise (in tiles) so that two objects of the same material differ. ``texture`` names an image texture
    (from ``--textures``) that replaces the procedural base colour; None uses the procedural one.
    """

    kind: MaterialKind
    rgb_a: RGB
    rgb_b: RGB
    contrast: float
    speckle: float
    stain: float
    stain_rgb: RGB
    growth: float
    growth_rgb: RGB
    ripple: float
    ripple_wavelength_m: float
    joint_spacing_m: float
    scale_m: float
    offset: tuple[float, float]
    texture: str | None = None


@dataclass(frozen=True)
class Wave:
    """One sinusoidal undulation of the seabed: ``amplitude_m * sin(kx x + ky y + phase_rad)``."""

    amplitude_m: float
    wavevector_per_m: tuple[float, float]
    phase_rad: float


@dataclass(frozen=True)
class Seabed:
    """The seabed height field ``z(x, y) = z0_m + sx x + sy y + sum(waves)`` (a sloped, undulating plane)."""

    z0_m: float
    slope: tuple[float, float]
    waves: tuple[Wave, ...]
    material: int


@dataclass(frozen=True)
class Box:
    """An oriented box: centre, half extents along its local axes, rotation (yaw about z, then pitch about
    the local y, then roll about the local x; local-to-world ``R = Rz(yaw) Ry(pitch) Rx(roll)``)."""

    shape: ClassVar[str] = "box"
    center_m: Vec3
    half_size_m: Vec3
    rotation_deg: Vec3
    material: int


@dataclass(frozen=True)
class Frustum:
    """A capped cone frustum from ``start_m`` to ``end_m`` (a cylinder when both radii are equal)."""

    shape: ClassVar[str] = "frustum"
    start_m: Vec3
    end_m: Vec3
    radius_start_m: float
    radius_end_m: float
    material: int


@dataclass(frozen=True)
class Sphere:
    """A sphere (the hub of a tetrapod)."""

    shape: ClassVar[str] = "sphere"
    center_m: Vec3
    radius_m: float
    material: int


@dataclass(frozen=True)
class Net:
    """A rectangular net panel: a square grid of threads in a plane, with a border rope.

    The panel spans ``+-half_size_m`` along its local u (horizontal) and v axes; ``rotation_deg`` = (yaw,
    tilt) turns it about z, then tilts it about its u axis. ``thread_m`` is the thread width; seen from far
    away a thread is drawn at least one pixel wide (and its depth is reported where it is drawn).
    """

    shape: ClassVar[str] = "net"
    center_m: Vec3
    half_size_m: tuple[float, float]
    rotation_deg: tuple[float, float]
    spacing_m: float
    thread_m: float
    material: int


Primitive = Box | Frustum | Sphere | Net
_PRIMITIVES: dict[str, type] = {c.shape: c for c in (Box, Frustum, Sphere, Net)}


@dataclass(frozen=True)
class SceneObject:
    """One object of the site (a caisson, a tetrapod, a rubble mound, ...) and the primitives it is made of."""

    kind: ObjectKind
    primitives: tuple[Primitive, ...]


@dataclass(frozen=True)
class SceneParams:
    """Everything needed to render one scene. ``dist_m`` of the render lies in [near_m, far_m]; rays that
    hit nothing within ``far_m`` get ``far_m``. ``seed`` is the int the scene was sampled from (None when
    :func:`murk.scenes.sample_scene` got a Generator)."""

    seed: int | None
    camera: Camera
    lighting: Lighting
    seabed: Seabed
    materials: tuple[Material, ...]
    objects: tuple[SceneObject, ...]
    near_m: float = 0.3
    far_m: float = 15.0
    version: int = field(default=SCENE_FORMAT_VERSION)

    def to_dict(self) -> dict[str, Any]:
        """A JSON-serialisable dict (tuples become lists; primitives carry a ``shape`` tag)."""
        return _to_jsonable(self)

    def primitives(self) -> list[Primitive]:
        """All primitives in drawing order (object order, then primitive order)."""
        return [p for o in self.objects for p in o.primitives]


def _to_jsonable(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        out: dict[str, Any] = {}
        cls: Any = type(value)
        if hasattr(cls, "shape"):
            out["shape"] = cls.shape
        for f in dataclasses.fields(value):
            out[f.name] = _to_jsonable(getattr(value, f.name))
        return out
    if isinstance(value, (tuple, list)):
        return [_to_jsonable(v) for v in value]
    return value


def _vec(v: Any) -> tuple:
    return tuple(float(x) for x in v)


def _material(d: dict[str, Any]) -> Material:
    return Material(
        kind=d["kind"],
        rgb_a=_vec(d["rgb_a"]),
        rgb_b=_vec(d["rgb_b"]),
        contrast=float(d["contrast"]),
        speckle=float(d["speckle"]),
        stain=float(d["stain"]),
        stain_rgb=_vec(d["stain_rgb"]),
        growth=float(d["growth"]),
        growth_rgb=_vec(d["growth_rgb"]),
        ripple=float(d["ripple"]),
        ripple_wavelength_m=float(d["ripple_wavelength_m"]),
        joint_spacing_m=float(d["joint_spacing_m"]),
        scale_m=float(d["scale_m"]),
        offset=_vec(d["offset"]),
        texture=d.get("texture"),
    )


def _lighting(d: dict[str, Any]) -> Lighting:
    """Lists become vectors, the rest floats; ``Lighting`` itself refuses a missing or unknown key."""
    kwargs: dict[str, Any] = {k: (_vec(v) if isinstance(v, list) else float(v)) for k, v in d.items()}
    return Lighting(**kwargs)


def _primitive(d: dict[str, Any]) -> Primitive:
    shape = d.get("shape")
    if shape not in _PRIMITIVES:
        raise ValueError(f"scene: expected a primitive shape in {sorted(_PRIMITIVES)}, got {shape!r}")
    cls = _PRIMITIVES[shape]
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        v = d[f.name]
        kwargs[f.name] = int(v) if f.name == "material" else (_vec(v) if isinstance(v, list) else float(v))
    return cls(**kwargs)


def scene_from_dict(d: dict[str, Any]) -> SceneParams:
    """Rebuild :class:`SceneParams` from :meth:`SceneParams.to_dict` (e.g. the ``scene`` of a scenes.jsonl line).

    Raises:
        ValueError: the dict was written by another scene format version, or a field is missing/unknown.
    """
    if not isinstance(d, dict):
        raise TypeError(f"scene: expected a dict, got {type(d).__name__}")
    version = d.get("version")
    if version != SCENE_FORMAT_VERSION:
        raise ValueError(f"scene: expected format version {SCENE_FORMAT_VERSION}, got {version!r}")
    try:
        cam = d["camera"]
        lit = d["lighting"]
        bed = d["seabed"]
        return SceneParams(
            seed=None if d["seed"] is None else int(d["seed"]),
            camera=Camera(
                position_m=_vec(cam["position_m"]),
                yaw_deg=float(cam["yaw_deg"]),
                pitch_deg=float(cam["pitch_deg"]),
                roll_deg=float(cam["roll_deg"]),
                hfov_deg=float(cam["hfov_deg"]),
            ),
            lighting=_lighting(lit),
            seabed=Seabed(
                z0_m=float(bed["z0_m"]),
                slope=_vec(bed["slope"]),
                waves=tuple(
                    Wave(float(w["amplitude_m"]), _vec(w["wavevector_per_m"]), float(w["phase_rad"]))
                    for w in bed["waves"]
                ),
                material=int(bed["material"]),
            ),
            materials=tuple(_material(m) for m in d["materials"]),
            objects=tuple(
                SceneObject(kind=o["kind"], primitives=tuple(_primitive(p) for p in o["primitives"]))
                for o in d["objects"]
            ),
            near_m=float(d["near_m"]),
            far_m=float(d["far_m"]),
            version=int(version),
        )
    except KeyError as exc:
        raise ValueError(f"scene: missing field {exc.args[0]!r}") from None
