"""Scene sampling: determinism, JSON round trip, placement rules, variety, config validation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from murk.rng import derive_seed
from murk.scenes import (
    LAYOUTS,
    Box,
    Frustum,
    Net,
    SceneConfig,
    Sphere,
    render_scene,
    sample_scene,
    scene_from_dict,
    seabed_height,
)
from murk.scenes.sample import CLEARANCE_M, _distance


@pytest.fixture(scope="module")
def many():
    return [sample_scene(derive_seed(99, i)) for i in range(60)]


def test_deterministic_and_seed_recorded() -> None:
    assert sample_scene(123) == sample_scene(123)
    assert sample_scene(123).seed == 123
    assert sample_scene(np.random.default_rng(1)).seed is None
    assert sample_scene(np.random.default_rng(1)) == sample_scene(np.random.default_rng(1))
    assert sample_scene(123) != sample_scene(124)


def test_json_round_trip_re_renders_identically(many) -> None:
    for p in many[:10]:
        text = json.dumps(p.to_dict(), allow_nan=False)
        back = scene_from_dict(json.loads(text))
        assert back == p
    rgb, dist = render_scene(many[0], (48, 36))
    rgb2, dist2 = render_scene(scene_from_dict(json.loads(json.dumps(many[0].to_dict()))), (48, 36))
    assert rgb.tobytes() == rgb2.tobytes() and dist.tobytes() == dist2.tobytes()


def test_scene_dict_describes_objects_poses_materials_camera(many) -> None:
    d = many[0].to_dict()
    assert set(d) >= {"camera", "lighting", "seabed", "materials", "objects", "near_m", "far_m", "seed", "version"}
    assert set(d["camera"]) == {"position_m", "yaw_deg", "pitch_deg", "roll_deg", "hfov_deg"}
    prim = d["objects"][0]["primitives"][0]
    assert prim["shape"] in {"box", "frustum", "sphere", "net"} and "material" in prim


def test_every_object_keeps_clear_of_the_camera(many) -> None:
    for p in many:
        cam = np.asarray(p.camera.position_m)
        for prim in p.primitives():
            assert _distance(prim, cam) >= p.near_m + CLEARANCE_M - 1e-6
        # The camera is above the seabed by at least the configured minimum height.
        assert cam[2] - seabed_height(p.seabed, cam[0], cam[1]) >= 0.4 - 1e-4


def test_distance_lower_bound_is_a_bound() -> None:
    # _distance never exceeds the true distance from the camera to points on the primitive's surface.
    from murk.scenes.geometry import net_axes, rotation_matrix

    rng = np.random.default_rng(0)
    cam = np.zeros(3)
    n = 4000
    box = Box((3.0, 1.0, 0.5), (0.5, 0.8, 0.3), (30.0, 10.0, -5.0), 0)
    local = rng.uniform(-1, 1, (n, 3))
    axis = rng.integers(0, 3, n)
    local[np.arange(n), axis] = np.sign(local[np.arange(n), axis])  # on a face
    box_pts = np.asarray(box.center_m) + (local * np.asarray(box.half_size_m)) @ rotation_matrix(*box.rotation_deg).T
    fr = Frustum((2.0, -1.0, 0.0), (4.0, 1.0, 1.0), 0.3, 0.2, 0)
    a, b = np.asarray(fr.start_m), np.asarray(fr.end_m)
    w = (b - a) / np.linalg.norm(b - a)
    e1 = np.cross(w, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(w, e1)
    s_ax = rng.random((n, 1))
    th = rng.uniform(0, 2 * np.pi, (n, 1))
    r = 0.3 + (0.2 - 0.3) * s_ax
    fr_pts = a + s_ax * (b - a) + r * (np.cos(th) * e1 + np.sin(th) * e2)
    sp = Sphere((3.0, 0.0, -1.0), 0.7, 0)
    v = rng.normal(size=(n, 3))
    sp_pts = np.asarray(sp.center_m) + 0.7 * v / np.linalg.norm(v, axis=1, keepdims=True)
    net = Net((4.0, 0.5, 0.0), (1.0, 0.5), (80.0, 5.0), 0.1, 0.005, 0)
    u_ax, v_ax, _ = net_axes(*net.rotation_deg)
    uv = rng.uniform(-1, 1, (n, 2)) * np.asarray(net.half_size_m)
    net_pts = np.asarray(net.center_m) + uv[:, :1] * u_ax + uv[:, 1:] * v_ax
    for prim, pts in ((box, box_pts), (fr, fr_pts), (sp, sp_pts), (net, net_pts)):
        bound = _distance(prim, cam)
        true_min = float(np.linalg.norm(pts, axis=1).min())
        assert 0 < bound <= true_min + 1e-9, type(prim).__name__
        assert bound > true_min - 0.5  # and not uselessly small


def test_variety_of_layouts_and_objects(many) -> None:
    kinds = {o.kind for p in many for o in p.objects}
    assert kinds >= {"caisson", "block", "tetrapod", "pile", "pipe", "rubble", "net", "rebar"}
    counts = [len(p.primitives()) for p in many]
    assert min(counts) >= 1 and max(counts) > 40
    hfov = [p.camera.hfov_deg for p in many]
    pitch = [p.camera.pitch_deg for p in many]
    assert max(hfov) - min(hfov) > 25 and max(pitch) - min(pitch) > 35
    assert len({m.kind for p in many for m in p.materials}) >= 5
    assert any(p.lighting.lamp_rgb[0] > 0 for p in many) and any(p.lighting.lamp_rgb[0] == 0 for p in many)


def test_layout_restriction_and_density() -> None:
    cfg = SceneConfig(layouts=("piles",))
    kinds = {o.kind for i in range(10) for o in sample_scene(i, cfg).objects}
    assert "pile" in kinds and "caisson" not in kinds and "tetrapod" not in kinds
    empty = sample_scene(1, SceneConfig(density=0.0))
    assert empty.objects == ()
    _, dist = render_scene(empty, (40, 30))
    assert dist.max() <= empty.far_m and dist.min() >= empty.near_m


def test_config_validation() -> None:
    with pytest.raises(ValueError, match=r"camera_height_m: expected a minimum >= near_m \+ 0.1"):
        SceneConfig(camera_height_m=(0.3, 2.0))
    with pytest.raises(ValueError, match=r"layouts: expected a non-empty list from"):
        SceneConfig(layouts=("harbour",))  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"hfov_deg\[1\]: expected a number in \[10.0, 150.0\]"):
        SceneConfig(hfov_deg=(50.0, 170.0))
    with pytest.raises(ValueError, match=r"far_m: expected a number in"):
        SceneConfig(far_m=0.5)
    with pytest.raises(TypeError, match="texture_names: expected a list of non-empty strings"):
        SceneConfig(texture_names=("",))
    with pytest.raises(ValueError, match=r"scene config: unknown key\(s\) fov; allowed: camera_height_m, "):
        SceneConfig.from_dict({"fov": 3})
    with pytest.raises(TypeError, match="config: expected SceneConfig"):
        sample_scene(0, {"far_m": 10})  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"rng: expected numpy\.random\.Generator, int or None"):
        sample_scene("seed")  # type: ignore[arg-type]
    cfg = SceneConfig.from_dict({"hfov_deg": [60, 70], "layouts": ["quay"]})
    assert cfg.hfov_deg == (60.0, 70.0) and cfg.layouts == ("quay",)
    assert SceneConfig.from_dict(cfg.to_dict()) == cfg
    assert set(LAYOUTS) == {"quay", "breakwater", "piles", "mixed"}


def test_scene_from_dict_errors(many) -> None:
    d = many[0].to_dict()
    with pytest.raises(ValueError, match="scene: expected format version 1, got 99"):
        scene_from_dict({**d, "version": 99})
    bad = {**d}
    del bad["camera"]
    with pytest.raises(ValueError, match="scene: missing field 'camera'"):
        scene_from_dict(bad)
    broken = json.loads(json.dumps(d))
    broken["objects"][0]["primitives"][0]["shape"] = "torus"
    with pytest.raises(ValueError, match="scene: expected a primitive shape in"):
        scene_from_dict(broken)
    with pytest.raises(TypeError, match="scene: expected a dict"):
        scene_from_dict([1])  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "cfg",
    [
        SceneConfig(),
        SceneConfig(pitch_deg=(0.0, 60.0), camera_height_m=(10.0, 50.0), hfov_deg=(10.0, 20.0)),
        SceneConfig(pitch_deg=(-89.0, -80.0), camera_height_m=(0.4, 0.5), hfov_deg=(140.0, 150.0), density=3.0),
        SceneConfig(far_m=5.0, near_m=0.5, camera_height_m=(0.6, 1.0), undulation_m=(1.0, 2.0), slope_max=0.5),
    ],
)
def test_sampling_never_fails(cfg: SceneConfig) -> None:
    # Many seeds, including extreme (but valid) configurations: sampling always yields a renderable scene.
    for i in range(150):
        p = sample_scene(derive_seed(4242, i), cfg)
        cam = np.asarray(p.camera.position_m)
        assert all(_distance(prim, cam) >= cfg.near_m + CLEARANCE_M - 1e-6 for prim in p.primitives())
    _, dist = render_scene(p, (24, 18))
    assert dist.min() >= cfg.near_m and dist.max() <= cfg.far_m
