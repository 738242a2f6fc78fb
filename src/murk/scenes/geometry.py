"""Analytic ray-primitive intersections, written once for numpy and torch.

Every kernel takes the array namespace ``xp`` (the ``numpy`` or ``torch`` module), the three components of
unit ray directions (arrays of any shape; rays start at the camera centre, the origin of camera-relative
world coordinates) and a sequence of per-primitive constants ``k`` (Python floats in the numpy renderer,
``(B, 1)`` float32 tensors in the batched torch renderer). A kernel returns the ray parameter ``t`` of the
nearest hit, which is the line-of-sight distance in metres because the directions are unit vectors, and
``inf`` where the ray misses. The ``*_surface`` functions give the outward normal and texture coordinates at
a hit. Using the same code for both back ends is what keeps the numpy and torch renderers equal.

The constants are computed in float64 by the ``pack_*`` functions, relative to the camera position, so that
per-pixel work is small and cancellation-free in float32: spheres and thin cylinders use the
Lagrange-identity form ``r^2 - |c x d|^2`` of the discriminant, and frusta move the ray origin to the entry
of their bounding sphere before solving the quadratic.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from murk.scenes.params import Box, Frustum, Net, Seabed, Sphere

INF = float("inf")
EPS_T = 1e-4
"""Smallest accepted hit distance (m)."""
N_WAVES = 2
"""The seabed always has this many undulation terms (unused ones have amplitude 0), so batches align."""
SEABED_NEWTON_STEPS = 3
SEABED_MAX_STEP_M = 2.0

Array = Any

# Layout of the packed constants of each primitive type (one float64 row per primitive).
BOX_FIELDS = 15 + 4  # R^T (9, row-major), camera in box frame (3), half extents (3), bounding sphere (4)
FRUSTUM_FIELDS = 3 + 3 + 3 + 3 + 3 + 4  # a-C (3), axis w (3), L, r0, slope k (3), e1 (3), e2 (3), bounds (4)
SPHERE_FIELDS = 4 + 4  # centre-C (3), radius, bounding sphere (4)
NET_FIELDS = 3 + 3 + 3 + 3 + 4 + 4  # centre-C, normal, u axis, v axis, (hu, hv, spacing, thread), bounds (4)
SEABED_FIELDS = 3 + 4 * N_WAVES  # hc, sx, sy, then (amplitude, kx, ky, phase at the camera) per wave


def rotation_rows(yaw_deg: float, pitch_deg: float, roll_deg: float) -> tuple[tuple[float, float, float], ...]:
    """Rows of the local-to-world rotation ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (plain Python floats)."""
    cy, sy = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    cp, sp = math.cos(math.radians(pitch_deg)), math.sin(math.radians(pitch_deg))
    cr, sr = math.cos(math.radians(roll_deg)), math.sin(math.radians(roll_deg))
    return (
        (cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr),
        (sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr),
        (-sp, cp * sr, cp * cr),
    )


def rotation_matrix(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """Local-to-world rotation ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (float64, 3x3)."""
    return np.array(rotation_rows(yaw_deg, pitch_deg, roll_deg))


def net_axes(yaw_deg: float, tilt_deg: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u axis, v axis, normal) of a net panel: u horizontal at ``yaw``, v up, tilted by ``tilt`` about u."""
    r = rotation_matrix(yaw_deg, 0.0, tilt_deg)
    return r[:, 0], r[:, 2], r[:, 1]


def _perp_basis(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors perpendicular to the unit vector ``w`` and to each other (plain Python: 3-vectors)."""
    wx, wy, wz = (float(c) for c in w)
    hx, hy, hz = (0.0, 0.0, 1.0) if abs(wz) < 0.9 else (1.0, 0.0, 0.0)
    ex, ey, ez = wy * hz - wz * hy, wz * hx - wx * hz, wx * hy - wy * hx
    n = math.sqrt(ex * ex + ey * ey + ez * ez)
    ex, ey, ez = ex / n, ey / n, ez / n
    return np.array([ex, ey, ez]), np.array([wy * ez - wz * ey, wz * ex - wx * ez, wx * ey - wy * ex])


def pack_box(p: Box, cam: np.ndarray) -> np.ndarray:
    """Constants of a box relative to the camera position ``cam`` (see :data:`BOX_FIELDS`)."""
    r = rotation_matrix(*p.rotation_deg)
    c = np.asarray(p.center_m) - cam
    rt = r.T
    ol = -(rt @ c)
    h = np.asarray(p.half_size_m)
    return np.concatenate([rt.ravel(), ol, h, c, [math.sqrt(float(h @ h))]])


def pack_frustum(p: Frustum, cam: np.ndarray) -> np.ndarray:
    """Constants of a capped cone frustum relative to ``cam`` (see :data:`FRUSTUM_FIELDS`)."""
    a = np.asarray(p.start_m) - cam
    b = np.asarray(p.end_m) - cam
    axis = b - a
    length = math.sqrt(float(axis @ axis))
    w = axis / length
    slope = (p.radius_end_m - p.radius_start_m) / length
    e1, e2 = _perp_basis(w)
    centre = 0.5 * (a + b)
    radius = math.hypot(0.5 * length, max(p.radius_start_m, p.radius_end_m))
    return np.concatenate([a, w, [length, p.radius_start_m, slope], e1, e2, centre, [radius]])


def pack_sphere(p: Sphere, cam: np.ndarray) -> np.ndarray:
    """Constants of a sphere relative to ``cam`` (see :data:`SPHERE_FIELDS`)."""
    c = np.asarray(p.center_m) - cam
    return np.concatenate([c, [p.radius_m], c, [p.radius_m]])


def pack_net(p: Net, cam: np.ndarray) -> np.ndarray:
    """Constants of a net panel relative to ``cam`` (see :data:`NET_FIELDS`)."""
    u, v, n = net_axes(*p.rotation_deg)
    c = np.asarray(p.center_m) - cam
    hu, hv = p.half_size_m
    return np.concatenate([c, n, u, v, [hu, hv, p.spacing_m, p.thread_m], c, [math.hypot(hu, hv) + p.thread_m]])


def pack_seabed(s: Seabed, cam: np.ndarray) -> np.ndarray:
    """Constants of the seabed height field relative to ``cam`` (see :data:`SEABED_FIELDS`)."""
    if len(s.waves) > N_WAVES:
        raise ValueError(f"seabed.waves: expected at most {N_WAVES} waves, got {len(s.waves)}")
    sx, sy = s.slope
    hc = s.z0_m + sx * cam[0] + sy * cam[1] - cam[2]
    row = [hc, sx, sy]
    for i in range(N_WAVES):
        if i < len(s.waves):
            w = s.waves[i]
            kx, ky = w.wavevector_per_m
            row += [w.amplitude_m, kx, ky, kx * cam[0] + ky * cam[1] + w.phase_rad]
        else:
            row += [0.0, 0.0, 0.0, 0.0]
    return np.asarray(row, dtype=np.float64)


def clamp(xp: Any, x: Array, lo: Any = None, hi: Any = None) -> Array:
    """``x`` limited to [lo, hi] (either bound may be None, a float or an array/tensor); the numpy branch uses
    the ``maximum``/``minimum`` ufuncs, which cost far less per call than ``np.clip``."""
    if isinstance(x, float):
        return min(max(x, -INF if lo is None else lo), INF if hi is None else hi)
    if xp is np:
        if lo is not None:
            x = np.maximum(x, lo)
        if hi is not None:
            x = np.minimum(x, hi)
        return x
    if lo is not None:
        x = xp.clamp(x, min=lo)
    if hi is not None:
        x = xp.clamp(x, max=hi)
    return x


def _safe(xp: Any, x: Array, eps: float) -> Array:
    """``x`` nudged away from 0 so that ``1 / x`` is finite: adds 1e-30, which changes no float32 value of
    magnitude above ~1e-23 and turns an exact 0 into a huge but finite reciprocal (the sign does not matter
    where it is used). ``eps`` documents the scale below which values are effectively zero."""
    del eps
    return x + 1e-30


def _sign(xp: Any, x: Array) -> Array:
    """+1 where ``x >= 0``, else -1, in the dtype of ``x``."""
    return xp.sign(x) + (x == 0)


def box_t(xp: Any, d: tuple[Array, Array, Array], k: Any) -> Array:
    """Nearest hit of an oriented box (slab method in the box frame)."""
    dx, dy, dz = d

    def slab(j: int) -> tuple[Array, Array]:  # entry and exit distances of the slab of local axis j
        dl = _safe(xp, k[3 * j] * dx + k[3 * j + 1] * dy + k[3 * j + 2] * dz, 1e-12)
        inv = 1.0 / dl
        ol, h = k[9 + j], k[12 + j]
        ta = (-h - ol) * inv
        tb = (h - ol) * inv
        return xp.minimum(ta, tb), xp.maximum(ta, tb)

    tn, tf = slab(0)
    for j in (1, 2):
        lo, hi = slab(j)
        tn = xp.maximum(tn, lo)
        tf = xp.minimum(tf, hi)
    return xp.where((tn <= tf) & (tn > EPS_T), tn, INF)


def box_surface(xp: Any, d: tuple[Array, Array, Array], t: Array, k: Any) -> tuple[Array, ...]:
    """(nx, ny, nz, u, v) at box hits: the face is the local axis where the hit is closest to the surface."""
    dx, dy, dz = d
    p = [k[9 + j] + t * (k[3 * j] * dx + k[3 * j + 1] * dy + k[3 * j + 2] * dz) for j in range(3)]
    q = [xp.abs(p[j]) * (1.0 / k[12 + j]) for j in range(3)]
    jx = (q[0] >= q[1]) & (q[0] >= q[2])
    jy = ~jx & (q[1] >= q[2])
    sx, sy, sz = (_sign(xp, p[j]) for j in range(3))
    # World normal = R @ (one-hot local normal); R's columns are the rows of R^T.
    n = [xp.where(jx, sx * k[i], xp.where(jy, sy * k[3 + i], sz * k[6 + i])) for i in range(3)]
    jz = ~jx & ~jy
    u = xp.where(jx, p[1] + k[13], p[0] + k[12])
    v = xp.where(jz, p[1] + k[13], p[2] + k[14])
    return n[0], n[1], n[2], u, v


def frustum_t(xp: Any, d: tuple[Array, Array, Array], k: Any) -> Array:
    """Nearest hit of a capped cone frustum (side quadratic + two cap discs)."""
    dx, dy, dz = d
    ax, ay, az, wx, wy, wz, length, r0, slope = (k[i] for i in range(9))
    # Move the origin to the entry of the bounding sphere so that the quadratic is well conditioned.
    s0 = clamp(xp, k[15] * dx + k[16] * dy + k[17] * dz - k[18], 0.0)
    ox = s0 * dx - ax
    oy = s0 * dy - ay
    oz_ = s0 * dz - az
    dw = wx * dx + wy * dy + wz * dz
    ow = ox * wx + oy * wy + oz_ * wz
    od = ox * dx + oy * dy + oz_ * dz
    q = ox * ox + oy * oy + oz_ * oz_
    cylinder = isinstance(slope, float) and slope == 0.0
    if cylinder:
        a2 = 1.0 - dw * dw
        bh = od - dw * ow
        cc = q - ow * ow - r0 * r0
    else:
        rr = r0 + slope * ow
        a2 = 1.0 - dw * dw * (1.0 + slope * slope)
        bh = od - dw * (ow + slope * rr)
        cc = q - ow * ow - rr * rr
    disc = bh * bh - a2 * cc
    real = disc >= 0
    sq = xp.sqrt(clamp(xp, disc, 0.0))
    inv_a = 1.0 / _safe(xp, a2, 1e-9)
    t_min = EPS_T - s0
    best = None
    # For a cylinder (a2 >= 0) the smaller root is the entry; the larger one is an exit, never the first hit of
    # a ray from outside (the caps below catch rays that enter through an end). A cone may need both roots.
    for sign in (-1.0,) if cylinder else (-1.0, 1.0):
        tt = (sign * sq - bh) * inv_a
        zz = ow + tt * dw
        ok = real & (tt > t_min) & (zz >= 0) & (zz <= length)
        cand = xp.where(ok, tt, INF)
        best = cand if best is None else xp.minimum(best, cand)
    inv_w = 1.0 / _safe(xp, dw, 1e-12)
    r1 = r0 + slope * length
    for z_cap, r_cap in ((0.0, r0), (length, r1)):
        # A ray parallel to the caps (dw = 0) has tc ~ 1e30 and tc * tc overflows to inf: "no hit", as it should be,
        # so numpy's overflow warning is silenced (every finite value stays as computed; torch never warns).
        with np.errstate(over="ignore"):
            tc = (z_cap - ow) * inv_w
            rad2 = q + tc * (2.0 * od + tc) - z_cap * z_cap
        best = xp.minimum(best, xp.where((tc > t_min) & (rad2 <= r_cap * r_cap), tc, INF))
    return s0 + best


def frustum_surface(xp: Any, d: tuple[Array, Array, Array], t: Array, k: Any) -> tuple[Array, ...]:
    """(nx, ny, nz, u, v) at frustum hits (u runs around the axis, v along it; caps use a planar map)."""
    dx, dy, dz = d
    ax, ay, az, wx, wy, wz, length, r0, slope = (k[i] for i in range(9))
    px = t * dx - ax
    py = t * dy - ay
    pz = t * dz - az
    z = px * wx + py * wy + pz * wz
    rx = px - z * wx
    ry = py - z * wy
    rz = pz - z * wz
    a1 = rx * k[9] + ry * k[10] + rz * k[11]
    a2 = rx * k[12] + ry * k[13] + rz * k[14]
    inv_r = 1.0 / xp.sqrt(rx * rx + ry * ry + rz * rz + 1e-20)
    s = (1.0 + slope * slope) ** -0.5
    cap0 = z <= 1e-4
    cap1 = z >= length - 1e-4
    n = []
    for rc, wc in ((rx, wx), (ry, wy), (rz, wz)):
        side = (rc * inv_r - slope * wc) * s
        n.append(xp.where(cap0, -wc, xp.where(cap1, wc, side)))
    cap = cap0 | cap1
    r_mean = r0 + 0.5 * slope * length
    u = xp.where(cap, a1, xp.arctan2(a2, a1) * r_mean)
    v = xp.where(cap, a2, z)
    return n[0], n[1], n[2], u, v


def sphere_t(xp: Any, d: tuple[Array, Array, Array], k: Any) -> Array:
    """Nearest hit of a sphere, discriminant as ``r^2 - |c x d|^2`` (no cancellation)."""
    dx, dy, dz = d
    cx, cy, cz, r = k[0], k[1], k[2], k[3]
    b = cx * dx + cy * dy + cz * dz
    mx = cy * dz - cz * dy
    my = cz * dx - cx * dz
    mz = cx * dy - cy * dx
    disc = r * r - (mx * mx + my * my + mz * mz)
    t = b - xp.sqrt(clamp(xp, disc, 0.0))
    return xp.where((disc >= 0) & (t > EPS_T), t, INF)


def sphere_surface(xp: Any, d: tuple[Array, Array, Array], t: Array, k: Any) -> tuple[Array, ...]:
    """(nx, ny, nz, u, v) at sphere hits; u, v are horizontal offsets from the centre (a planar map that suits
    the low caps of rubble mounds and the small hubs of tetrapods)."""
    dx, dy, dz = d
    inv = 1.0 / k[3]
    px = t * dx - k[0]
    py = t * dy - k[1]
    pz = t * dz - k[2]
    return px * inv, py * inv, pz * inv, px + 0.5 * pz, py - 0.5 * pz


def net_t(xp: Any, d: tuple[Array, Array, Array], k: Any, px_angle: Any) -> Array:
    """Nearest hit of a net panel: the plane, inside the rectangle, on a thread or the border rope.

    ``px_angle`` is the angular size of a pixel (rad); threads are drawn at least 1.2 pixels wide.
    """
    dx, dy, dz = d
    cx, cy, cz, nx, ny, nz = (k[i] for i in range(6))
    hu, hv, spacing, thread = k[12], k[13], k[14], k[15]
    den = nx * dx + ny * dy + nz * dz
    t = (nx * cx + ny * cy + nz * cz) / _safe(xp, den, 1e-12)
    qx = t * dx - cx
    qy = t * dy - cy
    qz = t * dz - cz
    u = qx * k[6] + qy * k[7] + qz * k[8]
    v = qx * k[9] + qy * k[10] + qz * k[11]
    au = xp.abs(u)
    av = xp.abs(v)
    inside = (t > EPS_T) & (au <= hu) & (av <= hv)
    width = clamp(xp, t * (1.2 * px_angle), thread)
    inv_s = 1.0 / spacing
    gu = u * inv_s
    gv = v * inv_s
    on_u = xp.abs(gu - xp.floor(gu + 0.5)) * (2.0 * spacing) <= width
    on_v = xp.abs(gv - xp.floor(gv + 0.5)) * (2.0 * spacing) <= width
    rope = 2.0 * width
    border = (au >= hu - rope) | (av >= hv - rope)
    return xp.where(inside & (on_u | on_v | border), t, INF)


def net_surface(xp: Any, d: tuple[Array, Array, Array], t: Array, k: Any) -> tuple[Array, ...]:
    """(nx, ny, nz, u, v) at net hits; the normal faces the camera."""
    dx, dy, dz = d
    den = k[3] * dx + k[4] * dy + k[5] * dz
    s = -_sign(xp, den)
    qx = t * dx - k[0]
    qy = t * dy - k[1]
    qz = t * dz - k[2]
    u = qx * k[6] + qy * k[7] + qz * k[8]
    v = qx * k[9] + qy * k[10] + qz * k[11]
    return s * k[3], s * k[4], s * k[5], u, v


def seabed_start(xp: Any, d: tuple[Array, Array, Array], k: Any, t_cap: float) -> dict[str, Any]:
    """Initial state of the seabed root search along each ray.

    ``g(t)`` is the height of the ray point above the seabed: ``g = t*den - hc - sum(a sin(A + t B))`` with
    ``den = d_z - sx d_x - sy d_y`` (< 0 for rays descending towards the sloped plane). With ``U = sum |a|``,
    ``g > 0`` before ``lo = (hc + U) / den`` and ``g <= 0`` at ``hi = (hc - U) / den``, which brackets a root;
    the search starts at the plane's exact hit ``hc / den``.
    """
    dx, dy, dz = d
    hc, sx, sy = k[0], k[1], k[2]
    den = dz - sx * dx - sy * dy
    descending = den < -1e-6
    den_s = xp.where(descending, den, -1.0)
    inv = 1.0 / den_s
    amp = sum(abs(k[3 + 4 * i]) for i in range(N_WAVES))
    lo = clamp(xp, (hc + amp) * inv, 0.0, t_cap)
    hi = clamp(xp, (hc - amp) * inv, 0.0, t_cap)
    valid = descending & (lo < t_cap)  # the first possible hit lies within t_cap
    t = clamp(xp, hc * inv, lo, hi)
    bw = [k[3 + 4 * i + 1] * dx + k[3 + 4 * i + 2] * dy for i in range(N_WAVES)]
    return {"den": den_s, "valid": valid, "bw": bw, "lo": lo, "hi": hi, "t": t, "cap": t_cap}


def _seabed_g(xp: Any, state: dict[str, Any], k: Any, t: Array) -> tuple[Array, Array]:
    g = t * state["den"] - k[0]
    gp = state["den"]
    for i in range(N_WAVES):
        amp, phase0 = k[3 + 4 * i], k[3 + 4 * i + 3]
        if isinstance(amp, float) and amp == 0.0:
            continue
        ph = phase0 + t * state["bw"][i]
        g = g - amp * xp.sin(ph)
        gp = gp - (amp * state["bw"][i]) * xp.cos(ph)
    return g, gp


def seabed_newton(xp: Any, state: dict[str, Any], k: Any, steps: int) -> tuple[Array, Array]:
    """``steps`` plain Newton steps from the plane's hit; returns (t, converged).

    A ray has converged when its last step was below :data:`SEABED_NEWTON_TOL_M` (Newton converges
    quadratically, so the remaining error is orders of magnitude smaller) and it never left the bracket.
    """
    if steps < 1:
        raise ValueError(f"seabed_newton: expected at least one step, got {steps}")
    t = t_prev = state["t"]
    inside = state["valid"]
    for _ in range(steps):
        g, gp = _seabed_g(xp, state, k, t)
        t_prev, t = t, t - g / _safe(xp, gp, 1e-12)
        inside = inside & (t >= state["lo"]) & (t <= state["hi"])
    step = xp.abs(t - t_prev)  # the last step
    # Rays that ran past the bracket's far end at t_cap hit beyond t_cap (the background): done too.
    return t, (inside & (step < SEABED_NEWTON_TOL_M)) | (t > state["hi"]) & (state["hi"] >= state["cap"])


def seabed_safeguarded(xp: Any, state: dict[str, Any], k: Any, steps: int) -> Array:
    """The robust search: a Newton step when it stays inside the current bracket, else bisection; returns t
    after ``steps`` steps (or earlier, once every ray's last update is below :data:`SEABED_TOL_M`)."""
    lo, hi, t = state["lo"], state["hi"], state["t"]
    for _ in range(steps):
        g, gp = _seabed_g(xp, state, k, t)
        above = g > 0
        lo = xp.where(above, t, lo)
        hi = xp.where(above, hi, t)
        tn = t - g / _safe(xp, gp, 1e-12)
        ok = (tn >= lo) & (tn <= hi)
        t_new = xp.where(ok, tn, 0.5 * (lo + hi))
        moving = xp.abs(t_new - t) > SEABED_TOL_M
        t = t_new
        if not bool(moving.any()):
            break
    return t


SEABED_TOL_M = 1e-5
"""The robust search stops when every ray's last update is smaller than this."""
SEABED_NEWTON_TOL_M = 1e-3
"""The Newton phase has converged for a ray when its last step was smaller than this."""
SEABED_ROBUST_STEPS = 40


def _pick(xp: Any, x: Any, idx: Any, shape: Any) -> Any:
    """Elements ``idx`` of ``x`` broadcast to ``shape`` and flattened (floats pass through)."""
    if isinstance(x, float):
        return x
    if xp is np:
        return np.take(np.broadcast_to(x, shape), idx) if np.shape(x) != tuple(shape) else np.take(x, idx)
    return x.expand(shape).reshape(-1)[idx]


def seabed_t(xp: Any, d: tuple[Array, Array, Array], k: Any, t_cap: float) -> Array:
    """Hit distance of the seabed height field along each ray (``inf`` where it misses).

    :data:`SEABED_NEWTON_STEPS` Newton steps from the plane's exact hit; the rays that have not converged then
    (or that left the bracket of :func:`seabed_start`) get the safeguarded Newton/bisection search from the
    start, which always converges to a root; it runs on those rays only. For a flat seabed the first step is
    exact.
    """
    state = seabed_start(xp, d, k, t_cap)
    t, done = seabed_newton(xp, state, k, SEABED_NEWTON_STEPS)
    todo = state["valid"] & ~done
    if xp is np:
        idx = np.flatnonzero(todo)
    else:
        idx = xp.nonzero(todo.reshape(-1)).squeeze(1)
    if idx.shape[0]:
        shape = t.shape
        sub = {
            key: (
                [_pick(xp, b, idx, shape) for b in val]
                if key == "bw"
                else val
                if key == "cap"
                else _pick(xp, val, idx, shape)
            )
            for key, val in state.items()
        }
        k_sub = [_pick(xp, c, idx, shape) for c in k]
        t = t.reshape(-1).copy() if xp is np else t.reshape(-1).clone()
        t[idx] = seabed_safeguarded(xp, sub, k_sub, SEABED_ROBUST_STEPS)
        t = t.reshape(shape)
    return xp.where(state["valid"] & (t < t_cap) & (t > EPS_T), t, INF)


def seabed_residual(xp: Any, d: tuple[Array, Array, Array], t: Array, k: Any) -> Array:
    """Signed height of the ray point at ``t`` above the seabed (m); 0 at an exact hit."""
    dx, dy, dz = d
    g = t * (dz - k[1] * dx - k[2] * dy) - k[0]
    for i in range(N_WAVES):
        g = g - k[3 + 4 * i] * xp.sin(k[3 + 4 * i + 3] + t * (k[3 + 4 * i + 1] * dx + k[3 + 4 * i + 2] * dy))
    return g


def seabed_surface(
    xp: Any, d: tuple[Array, Array, Array], t: Array, k: Any, cam_xy: tuple[Any, Any]
) -> tuple[Array, ...]:
    """(nx, ny, nz, u, v) at seabed hits; u, v are world x, y."""
    dx, dy, _ = d
    hx = k[1] + 0.0 * t
    hy = k[2] + 0.0 * t
    for i in range(N_WAVES):
        amp, kx, ky, phase0 = (k[3 + 4 * i + j] for j in range(4))
        c = amp * xp.cos(phase0 + t * (kx * dx + ky * dy))
        hx = hx + kx * c
        hy = hy + ky * c
    inv = 1.0 / xp.sqrt(hx * hx + hy * hy + 1.0)
    return -hx * inv, -hy * inv, inv, cam_xy[0] + t * dx, cam_xy[1] + t * dy
