"""Helpers for the scene tests: hand-made scenes with known geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from murk.scenes import Camera, Lighting, Material, SceneObject, SceneParams, Seabed, Wave

PLAIN = Material(
    kind="concrete",
    rgb_a=(0.6, 0.6, 0.6),
    rgb_b=(0.4, 0.4, 0.4),
    contrast=0.5,
    speckle=0.2,
    stain=0.2,
    stain_rgb=(0.3, 0.25, 0.2),
    growth=0.3,
    growth_rgb=(0.3, 0.35, 0.2),
    ripple=0.05,
    ripple_wavelength_m=0.2,
    joint_spacing_m=1.0,
    scale_m=1.0,
    offset=(0.1, 0.2),
)
LIGHT = Lighting(
    sun_direction=(0.0, 0.6, 0.8),
    sun_rgb=(0.5, 0.5, 0.5),
    ambient_rgb=(0.6, 0.6, 0.6),
    lamp_rgb=(0.3, 0.3, 0.3),
    lamp_cone_deg=30.0,
    lamp_soft_deg=10.0,
    lamp_ref_m=2.0,
    background_low_rgb=(0.2, 0.25, 0.3),
    background_high_rgb=(0.4, 0.5, 0.6),
)


def make_scene(
    objects: tuple[SceneObject, ...] = (),
    *,
    camera: Camera | None = None,
    seabed_z_m: float = -50.0,
    waves: tuple[Wave, ...] = (),
    slope: tuple[float, float] = (0.0, 0.0),
) -> SceneParams:
    """A scene looking along +x from the origin (unless ``camera`` is given) with a flat seabed far below."""
    cam = camera or Camera((0.0, 0.0, 0.0), 0.0, 0.0, 0.0, 60.0)
    return SceneParams(
        seed=None,
        camera=cam,
        lighting=LIGHT,
        seabed=Seabed(seabed_z_m, slope, waves, 0),
        materials=(PLAIN,),
        objects=objects,
    )


def ray_dirs(params: SceneParams, size: tuple[int, int]) -> np.ndarray:
    """Unit ray directions (H, W, 3) in float64, computed independently of the renderer from the camera
    angles and the pinhole model (pixel centres, square pixels)."""
    c = params.camera
    w, h = size
    f = (w / 2) / math.tan(math.radians(c.hfov_deg) / 2)
    yaw, pitch, roll = (math.radians(a) for a in (c.yaw_deg, c.pitch_deg, c.roll_deg))
    assert roll == 0.0
    fwd = np.array([math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), math.sin(pitch)])
    right = np.array([math.sin(yaw), -math.cos(yaw), 0.0])
    up = np.cross(right, fwd)
    xn = (np.arange(w) + 0.5 - w / 2) / f
    yn = (np.arange(h) + 0.5 - h / 2) / f
    d = fwd[None, None, :] + xn[None, :, None] * right[None, None, :] - yn[:, None, None] * up[None, None, :]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


@pytest.fixture(scope="session")
def torch_cpu():
    torch = pytest.importorskip("torch")
    return torch
