"""Surface shading, written once for numpy and torch: one procedural material formula and clear-air lighting.

Every material is the same formula with different coefficients (a row of :func:`material_table`), so a whole
image is shaded in one vectorised pass. Per pixel:

1. base colour: ``rgb_a`` blended towards ``rgb_b`` by mid- and large-scale noise (weight ``contrast``), or an
   image texture; speckle; sand ripples; horizontal construction joints; stains; marine growth patches;
2. light: hemispherical ambient + directional (Lambert) + an optional lamp cone at the camera with
   inverse-square falloff (``ref^2 / (d^2 + ref^2 / 2)``, at most twice ``lamp_rgb`` up close);
3. surfaces beyond 85 % of ``far_m`` blend into the open-water background, reached at ``far_m`` (the far
   clipping distance, where the depth map is clamped).

No water effect is applied here: the clean image shows the scene in clear air; ``murk synth`` adds the water
(Eq. (1) of the paper and the later stages).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from murk.scenes.geometry import clamp
from murk.scenes.params import Lighting, Material
from murk.scenes.textures import TILE_PX, wrap_coords

MATERIAL_FIELDS = 24
"""Columns of a material row: rgb_a (3), rgb_b (3), contrast, speckle, stain, stain_rgb (3), growth,
growth_rgb (3), ripple, ripple wavenumber (rad/m), 1/joint spacing (1/m), joint depth, 1/scale (1/m),
offset (2, texels), image-texture index (-1 = none)."""
LIGHT_FIELDS = 23
"""Scene lighting constants: sun direction (3), sun (3), ambient (3), lamp (3), lamp cos(inner), cos(outer),
lamp ref^2, background low (3), background high (3), far_m, pixel angle (rad)."""

FADE_START = 0.85
"""Fraction of ``far_m`` where surfaces start to blend into the background."""
JOINT_WIDTH_M = 0.02
COARSE_FACTOR = 8.0
"""The coarse noise lookup uses tiles this many times larger than the material's ``scale_m``."""

Array = Any


def material_row(m: Material, texture_index: int) -> list[float]:
    """The coefficient row of one material (see :data:`MATERIAL_FIELDS`)."""
    joint = m.joint_spacing_m > 0
    return [
        *m.rgb_a,
        *m.rgb_b,
        m.contrast,
        m.speckle,
        m.stain,
        *m.stain_rgb,
        m.growth,
        *m.growth_rgb,
        m.ripple,
        2.0 * math.pi / m.ripple_wavelength_m,
        1.0 / m.joint_spacing_m if joint else 0.0,
        0.45 if joint else 0.0,
        1.0 / m.scale_m,
        m.offset[0] * TILE_PX,
        m.offset[1] * TILE_PX,
        float(texture_index),
    ]


def material_table(materials: tuple[Material, ...], texture_names: list[str]) -> np.ndarray:
    """(M, MATERIAL_FIELDS) float64 rows; ``texture_names`` maps a material's texture name to its index."""
    rows = [material_row(m, texture_names.index(m.texture) if m.texture is not None else -1) for m in materials]
    return np.asarray(rows, dtype=np.float64).reshape(len(materials), MATERIAL_FIELDS)


def light_row(light: Lighting, far_m: float, px_angle: float) -> list[float]:
    """The lighting constants of a scene (see :data:`LIGHT_FIELDS`)."""
    inner = math.radians(light.lamp_cone_deg)
    outer = inner + math.radians(max(light.lamp_soft_deg, 1e-3))
    return [
        *light.sun_direction,
        *light.sun_rgb,
        *light.ambient_rgb,
        *light.lamp_rgb,
        math.cos(inner),
        math.cos(min(outer, math.pi / 2)),
        light.lamp_ref_m**2,
        *light.background_low_rgb,
        *light.background_high_rgb,
        far_m,
        px_angle,
    ]


def _zero(c: Any) -> bool:
    """True for a scalar coefficient equal to 0 (its term can be skipped exactly)."""
    return isinstance(c, float) and c == 0.0


def shade(
    xp: Any,
    t: Array,
    d: tuple[Array, Array, Array],
    n: tuple[Array, Array, Array],
    uv: tuple[Array, Array],
    cos_axis: Array,
    mat: Any,
    light: Any,
    lookup: Any,
    image_rgb: tuple[Array, Array, Array] | None = None,
) -> tuple[Array, Array, Array]:
    """Shade pixels; returns (r, g, b) in [0, 1].

    Args:
        xp: ``numpy`` or ``torch``.
        t: hit distance (m), ``inf`` where the ray hit nothing.
        d: unit ray directions (world frame).
        n: unit surface normals (any finite value where ``t`` is inf).
        uv: surface coordinates (m).
        cos_axis: cosine between the ray and the camera axis (for the lamp cone).
        mat: the :data:`MATERIAL_FIELDS` coefficients, per-pixel arrays or Python floats (one material);
            terms whose scalar coefficient is 0 are skipped, which leaves the result unchanged.
        light: the :data:`LIGHT_FIELDS` scene constants.
        lookup: ``lookup(x, y) -> (..., 4)`` noise-tile fetch at texel coordinates in [0, TILE_PX).
        image_rgb: image-texture colour per pixel, used where ``mat[23] >= 0``.
    """
    dx, dy, dz = d
    nx, ny, nz = n
    u, v = uv
    far = light[21]
    # numpy callers pass t already limited to [0, far_m]; the torch renderer passes inf for misses.
    tc = t if xp is np else clamp(xp, t, 0.0, far)
    ndd = nx * dx + ny * dy + nz * dz
    # Texels per pixel on the surface: fades the fine noise where it would alias.
    fp = tc * (light[22] * mat[20] * float(TILE_PX)) / clamp(xp, xp.abs(ndd), 0.25)
    fp2 = fp * fp
    to_texel = mat[20] * float(TILE_PX)
    su = u * to_texel
    sv = v * to_texel
    fine = lookup(wrap_coords(xp, su + mat[21], TILE_PX), wrap_coords(xp, sv + mat[22], TILE_PX))
    coarse = lookup(
        wrap_coords(xp, su * (1.0 / COARSE_FACTOR) + (mat[22] + 97.0), TILE_PX),
        wrap_coords(xp, sv * (1.0 / COARSE_FACTOR) + (mat[21] + 31.0), TILE_PX),
    )
    f_fbm, f_speck = fine[..., 0], fine[..., 2]
    c_var, c_stain, c_growth = coarse[..., 0], coarse[..., 1], coarse[..., 3]

    fade_mid = 1.0 / (1.0 + fp2 * (1.0 / 64.0))
    mix = clamp(xp, ((f_fbm - 0.5) * fade_mid + 0.6 * (c_var - 0.5)) * mat[6] + 0.5, 0.0, 1.0)
    base = [mat[i] + (mat[3 + i] - mat[i]) * mix for i in range(3)]
    if image_rgb is not None and not (isinstance(mat[23], float) and mat[23] < 0):
        has_img = mat[23] >= 0
        shade_img = 0.85 + 0.3 * c_var
        base = [xp.where(has_img, image_rgb[i] * shade_img, base[i]) for i in range(3)]
    # Speckle, ripples and joints modulate brightness.
    bright = None
    if not _zero(mat[7]):
        fade_fine = 1.0 / (1.0 + fp2 * 0.25)
        bright = 1.0 + (2.0 * f_speck - 1.0) * fade_fine * mat[7]
    if not _zero(mat[16]):
        ripple = 1.0 + xp.sin(mat[17] * (u + 0.37 * v) + 5.0 * c_var) * fade_mid * mat[16]
        bright = ripple if bright is None else bright * ripple
    if not _zero(mat[19]):
        jv = v * mat[18]
        joint_dist = xp.abs(jv - xp.floor(jv + 0.5)) / clamp(xp, mat[18], 1e-6)
        joint = 1.0 - xp.where(joint_dist < JOINT_WIDTH_M, mat[19], 0.0 * jv)
        bright = joint if bright is None else bright * joint
    if bright is not None:
        base = [b * bright for b in base]
    # Stains (coverage mat[8]) and marine growth (coverage mat[12], more on upward-facing surfaces).
    if not _zero(mat[8]):
        stain = clamp(xp, (c_stain - (1.0 - mat[8])) * 5.0, 0.0, 1.0) * 0.7
        base = [b + stain * (mat[9 + i] - b) for i, b in enumerate(base)]
    if not _zero(mat[12]):
        cover = (0.75 + 0.25 * nz) * mat[12]
        growth = clamp(xp, (c_growth - (1.0 - cover)) * 6.0, 0.0, 1.0)
        tone = 0.7 + 0.6 * f_fbm
        base = [b + growth * (mat[13 + i] * tone - b) for i, b in enumerate(base)]

    # Lighting: hemispherical ambient + sun (Lambert) + lamp cone at the camera.
    ndl = clamp(xp, nx * light[0] + ny * light[1] + nz * light[2], 0.0)
    hemi = 0.7 + 0.3 * nz
    lamp_on = not all(_zero(light[9 + i]) for i in range(3))
    if lamp_on:
        cone = clamp(xp, (cos_axis - light[13]) * (1.0 / (light[12] - light[13])), 0.0, 1.0)
        lamp = cone * clamp(xp, -ndd, 0.0) * light[14] / (tc * tc + 0.5 * light[14])
    # Far fade into the open-water background (a vertical gradient); skipped (exactly: the fade is 0) when a
    # numpy chunk has no surface beyond FADE_START * far_m.
    fading = xp is not np or float(tc.max(initial=0.0)) > FADE_START * far
    if fading:
        fade = clamp(xp, (tc - FADE_START * far) * (1.0 / ((1.0 - FADE_START) * far)), 0.0, 1.0)
        up = clamp(xp, 0.5 + 1.2 * dz, 0.0, 1.0)
    out = []
    for i in range(3):
        lit = light[6 + i] * hemi + light[3 + i] * ndl
        if lamp_on:
            lit = lit + light[9 + i] * lamp
        c = base[i] * lit
        if fading:
            bg = light[15 + i] + (light[18 + i] - light[15 + i]) * up
            c = c + fade * (bg - c)
        out.append(clamp(xp, c, 0.0, 1.0))
    return out[0], out[1], out[2]
