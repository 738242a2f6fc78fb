"""Exact distances of the analytic ray casts, in the line-of-sight convention (not z-depth).

Expected values are computed here in float64 from the pinhole model (tests/scenes/conftest.py:ray_dirs),
independently of the renderer's float32 code.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from murk.rng import derive_seed
from murk.scenes import (
    Box,
    Camera,
    Frustum,
    Net,
    SceneObject,
    Sphere,
    Wave,
    intrinsics,
    render_scene,
    render_scenes_torch,
    sample_scene,
)
from murk.scenes import geometry as geo
from murk.scenes.render import pack_scene, render_packed_numpy

from .conftest import make_scene, ray_dirs

SIZE = (64, 48)


def _render_both(params, torch_cpu=None):
    _, dist = render_scene(params, SIZE)
    out = [dist.astype(np.float64)]
    if torch_cpu is not None:
        _, td = render_scenes_torch([params], SIZE, "cpu")
        out.append(td[0, 0].numpy().astype(np.float64))
    return out


@pytest.mark.parametrize("height_m", [0.5, 2.0, 7.5])
def test_flat_seabed_straight_down_is_exact_line_of_sight_distance(height_m, torch_cpu) -> None:
    # A camera height H above a flat seabed, looking straight down: every ray reaches the plane after
    # H / cos(theta) metres, theta = the angle to the optical axis. That is the distance, not the z-depth H.
    cam = Camera((0.0, 0.0, height_m), 30.0, -90.0, 0.0, 70.0)
    params = make_scene(camera=cam, seabed_z_m=0.0)
    k = intrinsics(params, SIZE)
    u = (np.arange(SIZE[0]) - k["cx"]) / k["fx"]
    v = (np.arange(SIZE[1]) - k["cy"]) / k["fy"]
    expected = height_m * np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2)
    for dist in _render_both(params, torch_cpu):
        np.testing.assert_allclose(dist, expected, rtol=2e-6)
        # z-depth = distance * cos(theta) is the constant height: the map is NOT z-depth.
        np.testing.assert_allclose(dist / np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2), height_m, rtol=2e-6)
    assert expected.max() > height_m * 1.2  # the corner rays are much longer than the height


def test_flat_seabed_oblique_view_and_far_clamp(torch_cpu) -> None:
    # Pitch -20 deg, 2 m above a flat seabed: hits at 2 / (-d_z) while that is <= far_m; beyond, far_m.
    cam = Camera((0.0, 0.0, 2.0), -40.0, -20.0, 0.0, 80.0)
    params = make_scene(camera=cam, seabed_z_m=0.0)
    d = ray_dirs(params, SIZE)
    with np.errstate(divide="ignore"):
        hit = np.where(d[..., 2] < 0, 2.0 / -d[..., 2], np.inf)
    expected = np.clip(hit, params.near_m, params.far_m)
    for dist in _render_both(params, torch_cpu):
        near = hit < 0.84 * params.far_m
        assert near.sum() > 500 and (~near).sum() > 100
        np.testing.assert_allclose(dist[near], expected[near], rtol=1e-5)
        beyond = hit > 1.01 * params.far_m
        assert np.all(dist[beyond] == params.far_m)


def test_box_face_distance_and_occlusion_order(torch_cpu) -> None:
    # Front face of an axis-aligned box at x = 5: distance 5 / d_x. A smaller box in front at x = 2.75
    # hides part of it; elsewhere the far box is seen; outside both the far clamp.
    far_box = Box((6.0, 0.0, 0.0), (1.0, 1.5, 1.5), (0.0, 0.0, 0.0), 0)
    near_box = Box((3.0, 0.6, 0.2), (0.25, 0.5, 0.5), (0.0, 0.0, 0.0), 0)
    objects = (SceneObject("block", (far_box,)), SceneObject("block", (near_box,)))
    params = make_scene(objects)
    d = ray_dirs(params, SIZE)
    y5, z5 = 5 * d[..., 1] / d[..., 0], 5 * d[..., 2] / d[..., 0]
    y2, z2 = 2.75 * d[..., 1] / d[..., 0], 2.75 * d[..., 2] / d[..., 0]
    on_near = (np.abs(y2 - 0.6) < 0.48) & (np.abs(z2 - 0.2) < 0.48)
    on_far = (np.abs(y5) < 1.45) & (np.abs(z5) < 1.45) & ~((np.abs(y2 - 0.6) < 0.52) & (np.abs(z2 - 0.2) < 0.52))
    near_any = (np.abs(y2 - 0.6) < 0.8) & (np.abs(z2 - 0.2) < 0.8)  # front or a side face of the near box
    off = ((np.abs(y5) > 1.55) | (np.abs(z5) > 1.55)) & ~near_any
    assert on_near.sum() > 20 and on_far.sum() > 100 and off.sum() > 100
    swapped = make_scene(objects[::-1])
    for params_i in (params, swapped):
        for dist in _render_both(params_i, torch_cpu):
            np.testing.assert_allclose(dist[on_near], 2.75 / d[..., 0][on_near], rtol=1e-5)
            np.testing.assert_allclose(dist[on_far], 5.0 / d[..., 0][on_far], rtol=1e-5)
            assert np.all(dist[off] == params.far_m)


def test_rotated_box_edge_on(torch_cpu) -> None:
    # A unit box turned 45 deg about z shows two faces meeting at an edge at x = 6 - sqrt(2): the visible
    # face of each ray is at distance (6 - sqrt(2)) / (d_x - |d_y|).
    box = Box((6.0, 0.0, 0.0), (1.0, 1.0, 1.0), (45.0, 0.0, 0.0), 0)
    params = make_scene((SceneObject("block", (box,)),))
    d = ray_dirs(params, SIZE)
    t = (6 - math.sqrt(2)) / (d[..., 0] - np.abs(d[..., 1]))
    y, z = t * d[..., 1], t * d[..., 2]
    inside = (np.abs(y) < 0.65) & (np.abs(z) < 0.9)
    assert inside.sum() > 50
    for dist in _render_both(params, torch_cpu):
        np.testing.assert_allclose(dist[inside], t[inside], rtol=1e-5)


def test_sphere_cylinder_and_cone_distances(torch_cpu) -> None:
    sphere = Sphere((5.0, -1.0, 0.0), 0.8, 0)
    cyl = Frustum((6.0, 1.5, -2.0), (6.0, 1.5, 2.0), 0.5, 0.5, 0)
    params = make_scene((SceneObject("tetrapod", (sphere,)), SceneObject("pile", (cyl,))))
    d = ray_dirs(params, SIZE)
    c = np.array([5.0, -1.0, 0.0])
    b = d @ c
    disc = 0.8**2 - np.sum(np.cross(d, c) ** 2, axis=-1)
    t_sphere = b - np.sqrt(np.maximum(disc, 0))
    on_sphere = disc > 0.05
    # Vertical cylinder x^2 + y^2 about (6, 1.5): (dx^2 + dy^2) t^2 - 2 (6 dx + 1.5 dy) t + 6^2 + 1.5^2 - r^2 = 0
    a2 = d[..., 0] ** 2 + d[..., 1] ** 2
    bh = 6 * d[..., 0] + 1.5 * d[..., 1]
    cc = 36 + 2.25 - 0.25
    disc_c = bh**2 - a2 * cc
    t_cyl = (bh - np.sqrt(np.maximum(disc_c, 0))) / a2
    on_cyl = (disc_c > 0.02 * a2) & (np.abs(t_cyl * d[..., 2]) < 1.9)
    assert on_sphere.sum() > 20 and on_cyl.sum() > 20
    for dist in _render_both(params, torch_cpu):
        np.testing.assert_allclose(dist[on_sphere], t_sphere[on_sphere], rtol=1e-5)
        np.testing.assert_allclose(dist[on_cyl], t_cyl[on_cyl], rtol=1e-5)


def test_cone_frustum_slant_and_cap() -> None:
    # A cone frustum along +x from x=4 (r=1) to x=8 (r=0.25): the camera on its axis sees the base cap at
    # distance 4 / d_x for rays within radius 1 at x = 4.
    cone = Frustum((4.0, 0.0, 0.0), (8.0, 0.0, 0.0), 1.0, 0.25, 0)
    params = make_scene((SceneObject("tetrapod", (cone,)),))
    d = ray_dirs(params, SIZE)
    t_cap = 4.0 / d[..., 0]
    rad = t_cap * np.hypot(d[..., 1], d[..., 2])
    on_cap = rad < 0.95
    assert on_cap.sum() > 50
    (dist,) = _render_both(params)
    np.testing.assert_allclose(dist[on_cap], t_cap[on_cap], rtol=1e-5)
    # Seen from the side, the slanted surface: radius r(x) = 1 - (x - 4) * 0.1875 at the hit point.
    side = make_scene((SceneObject("tetrapod", (cone,)),), camera=Camera((6.0, -5.0, 0.0), 90.0, 0.0, 0.0, 60.0))
    d2 = ray_dirs(side, SIZE)
    (dist2,) = _render_both(side)
    p = np.array([6.0, -5.0, 0.0]) + dist2[..., None] * d2
    hit = dist2 < side.far_m
    assert hit.sum() > 50
    r_expected = 1 - (p[..., 0] - 4) * 0.1875
    on_side = hit & (p[..., 0] > 4.05) & (p[..., 0] < 7.95)
    np.testing.assert_allclose(np.hypot(p[..., 1], p[..., 2])[on_side], r_expected[on_side], atol=2e-5)


def test_net_threads_and_holes(torch_cpu) -> None:
    # A net across the view at x = 3 (u axis = +y... after the 90 deg yaw), threads every 0.2 m.
    net = Net((3.0, 0.0, 0.0), (1.0, 0.8), (90.0, 0.0), 0.2, 0.01, 0)
    params = make_scene((SceneObject("net", (net,)),))
    d = ray_dirs(params, SIZE)
    t = 3.0 / d[..., 0]
    u, v = t * d[..., 1], t * d[..., 2]
    px = 1.0 / geo_focal(params)
    width = np.maximum(0.01, 1.2 * t * px)

    def off_thread(c):
        return np.abs(c / 0.2 - np.round(c / 0.2)) * 0.2

    inside = (np.abs(u) < 1.0 - 3 * width) & (np.abs(v) < 0.8 - 3 * width)
    on = inside & ((off_thread(u) < 0.4 * width) | (off_thread(v) < 0.4 * width))
    hole = inside & (off_thread(u) > 0.6 * width) & (off_thread(v) > 0.6 * width)
    assert on.sum() > 30 and hole.sum() > 150
    for dist in _render_both(params, torch_cpu):
        np.testing.assert_allclose(dist[on], t[on], rtol=1e-5)
        assert np.all(dist[hole] == params.far_m)


def geo_focal(params) -> float:
    return intrinsics(params, SIZE)["fx"]


def test_undulating_seabed_hits_are_on_the_surface() -> None:
    # After the Newton steps the ray point lies on the height field (residual << 1 mm) for every hit.
    waves = (Wave(0.2, (0.9, 0.4), 0.3), Wave(0.08, (-0.5, 1.6), 1.0))
    cam = Camera((0.0, 0.0, 1.5), 20.0, -25.0, 0.0, 80.0)
    params = make_scene(camera=cam, seabed_z_m=0.0, waves=waves, slope=(0.05, -0.03))
    packed = pack_scene(params, SIZE)
    d = ray_dirs(params, SIZE).astype(np.float32)
    dd = (d[..., 0], d[..., 1], d[..., 2])
    k = packed.seabed.tolist()
    t = geo.seabed_t(np, dd, k, 60.0)
    hit = np.isfinite(t)
    assert hit.mean() > 0.5
    sel = hit & (t < 15)
    res = geo.seabed_residual(np, tuple(a[sel].astype(np.float64) for a in dd), t[sel].astype(np.float64), k)
    assert np.abs(res).max() < 2e-4


def test_culling_never_changes_the_result() -> None:
    # The screen rectangles are conservative: culled and brute-force renders are byte-identical.
    for i in range(6):
        params = sample_scene(derive_seed(11, i))
        packed = pack_scene(params, (96, 72))
        rgb_a, dist_a = render_packed_numpy(packed, cull=True)
        rgb_b, dist_b = render_packed_numpy(packed, cull=False)
        assert np.array_equal(dist_a, dist_b)
        assert np.array_equal(rgb_a, rgb_b)


def test_screen_rect_contains_every_hit() -> None:
    from murk.scenes.render import camera_frame, screen_rect

    params = make_scene(camera=Camera((0.0, 0.0, 0.0), 10.0, -5.0, 3.0, 70.0))
    frame = camera_frame(params, SIZE)
    rng = np.random.default_rng(0)
    for _ in range(200):
        c = rng.normal(size=3) * 4
        r = float(rng.uniform(0.05, 2.0))
        r0, r1, c0, c1 = screen_rect(frame, c, r)
        t = geo.sphere_t(
            np,
            _rays(frame),
            [*c.tolist(), r],
        )
        rows, cols = np.nonzero(np.isfinite(t))
        if rows.size:
            assert rows.min() >= r0 and rows.max() < r1 and cols.min() >= c0 and cols.max() < c1


def _rays(frame):
    from murk.scenes.render import _rays_numpy

    return _rays_numpy(frame)[0]


def test_vectorised_screen_rects_match_the_scalar_ones() -> None:
    from murk.scenes.render import camera_frame, screen_rect, screen_rects

    frame = camera_frame(make_scene(camera=Camera((0.0, 0.0, 0.0), -30.0, 10.0, 0.0, 80.0)), SIZE)
    rng = np.random.default_rng(1)
    centres = rng.normal(size=(300, 3)) * 5
    radii = rng.uniform(0.01, 3.0, 300)
    many = screen_rects(frame, centres, radii)
    for (r0, r1, c0, c1), c, r in zip(many.tolist(), centres, radii, strict=True):
        s0, s1, t0, t1 = screen_rect(frame, c, float(r))
        if s1 > s0 and t1 > t0:  # a visible sphere: the same rectangle
            assert (r0, r1, c0, c1) == (s0, s1, t0, t1)
        else:
            assert r1 <= r0 or c1 <= c0


def test_ray_parallel_to_frustum_caps_hits_the_side_without_overflow_warning() -> None:
    # A ray perpendicular to a cylinder's axis never reaches its cap planes (dw = 0, so the cap distance is ~1e30 and
    # its square overflows): the side hit at 2 - 0.5 m must come out, with no RuntimeWarning on the way.
    import warnings

    cyl = Frustum((2.0, 0.0, -0.5), (2.0, 0.0, 0.5), 0.5, 0.5, 0)
    cone = Frustum((2.0, 0.0, -0.5), (2.0, 0.0, 0.5), 0.6, 0.4, 0)  # radius 0.5 at the ray's height
    d = tuple(np.array([v], np.float32) for v in (1.0, 0.0, 0.0))
    for prim in (cyl, cone):
        k = geo.pack_frustum(prim, np.zeros(3)).astype(np.float32)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            t = geo.frustum_t(np, d, k)
        np.testing.assert_allclose(t, [1.5], rtol=1e-6)
