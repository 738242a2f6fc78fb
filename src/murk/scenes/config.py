"""Configuration of the scene sampler (a frozen dataclass, validated on construction, loadable from YAML)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Literal, get_args

from murk._checks import check_interval, check_positive, check_range
from murk._config import from_dict

Layout = Literal["quay", "breakwater", "piles", "mixed"]
LAYOUTS: tuple[Layout, ...] = get_args(Layout)


@dataclass(frozen=True)
class SceneConfig:
    """Ranges the scene sampler draws from. Angles in degrees, lengths in metres.

    Attributes:
        near_m: smallest distance reported in the depth map; objects are never placed closer to the camera.
        far_m: far clipping distance; rays that hit nothing within it get ``far_m``.
        camera_height_m: camera height above the seabed below it.
        pitch_deg: camera pitch (negative looks down).
        roll_deg: camera roll.
        hfov_deg: horizontal field of view.
        slope_max: largest seabed gradient (rise over run).
        undulation_m: range of the total amplitude of the seabed undulation.
        layouts: site layouts to draw from (uniformly): ``quay`` (a caisson wall with foot blocks, rubble and
            rebar), ``breakwater`` (a tetrapod heap on a rubble mound), ``piles`` (pile rows, pipes, a net
            fence), ``mixed`` (some of everything).
        density: multiplies the number of objects of every kind (1 = the documented defaults).
        lamp_probability: probability that the vehicle lamp is on.
        growth_max: largest marine-growth coverage of a surface (0 disables growth).
        texture_names: image textures the sampler may use (the names given to the renderer).
        texture_probability: probability that a concrete, rock or seabed material uses an image texture
            (when ``texture_names`` is not empty).
        water_background: probability that the open-water background (rays that hit nothing) is clear-water
            blue to cyan-green, as water looks in a photograph taken in clear water, instead of the near-grey
            gradient (0, the default, keeps every scene as before: the extra draws come last).
    """

    near_m: float = 0.3
    far_m: float = 15.0
    camera_height_m: tuple[float, float] = (0.4, 4.0)
    pitch_deg: tuple[float, float] = (-50.0, 5.0)
    roll_deg: tuple[float, float] = (-5.0, 5.0)
    hfov_deg: tuple[float, float] = (55.0, 95.0)
    slope_max: float = 0.12
    undulation_m: tuple[float, float] = (0.0, 0.25)
    layouts: tuple[Layout, ...] = LAYOUTS
    density: float = 1.0
    lamp_probability: float = 0.5
    growth_max: float = 0.6
    texture_names: tuple[str, ...] = ()
    texture_probability: float = 0.3
    water_background: float = 0.0

    def __post_init__(self) -> None:
        check_positive("near_m", self.near_m)
        check_range("far_m", self.far_m, self.near_m + 1.0, 1000.0)
        object.__setattr__(self, "camera_height_m", check_interval("camera_height_m", self.camera_height_m, 0.3, 50))
        object.__setattr__(self, "pitch_deg", check_interval("pitch_deg", self.pitch_deg, -89.0, 60.0))
        object.__setattr__(self, "roll_deg", check_interval("roll_deg", self.roll_deg, -45.0, 45.0))
        object.__setattr__(self, "hfov_deg", check_interval("hfov_deg", self.hfov_deg, 10.0, 150.0))
        object.__setattr__(self, "undulation_m", check_interval("undulation_m", self.undulation_m, 0.0, 2.0))
        check_range("slope_max", self.slope_max, 0.0, 0.5)
        if self.camera_height_m[0] < self.near_m + 0.1:
            raise ValueError(
                f"camera_height_m: expected a minimum >= near_m + 0.1 = {self.near_m + 0.1} so that the seabed "
                f"stays beyond near_m, got {self.camera_height_m[0]}"
            )
        layouts = tuple(self.layouts) if isinstance(self.layouts, (list, tuple)) else None
        if not layouts or any(x not in LAYOUTS for x in layouts):
            raise ValueError(f"layouts: expected a non-empty list from {list(LAYOUTS)}, got {self.layouts!r}")
        object.__setattr__(self, "layouts", layouts)
        check_range("density", self.density, 0.0, 10.0)
        check_range("lamp_probability", self.lamp_probability, 0.0, 1.0)
        check_range("growth_max", self.growth_max, 0.0, 1.0)
        check_range("texture_probability", self.texture_probability, 0.0, 1.0)
        check_range("water_background", self.water_background, 0.0, 1.0)
        names = self.texture_names
        if not isinstance(names, (list, tuple)) or not all(isinstance(n, str) and n for n in names):
            raise TypeError(f"texture_names: expected a list of non-empty strings, got {names!r}")
        object.__setattr__(self, "texture_names", tuple(names))

    def to_dict(self) -> dict[str, Any]:
        """All fields as JSON-friendly values (tuples become lists)."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: dict[str, Any], *, where: str = "scene config") -> SceneConfig:
        """Build from a dict (e.g. a YAML file's, :func:`murk._config.read_yaml`) with the one config loader:
        unknown keys, wrong types and bad values are errors naming ``where`` and the key."""
        return from_dict(cls, d, where=where)
