"""Whether the particles a restorer leaves keep their colour: CIELAB a* at marine-snow sites against a ring around them.

A colour balance stretches each channel by its own gain. On green or blue water the red gain is large, and the red
of a bright, near-white particle is stretched with the water's: the particles that stay turn pink or red while the
water around them turns neutral. Real particles sit close to the camera, so the water column barely tints them;
their colour relative to their surroundings should not move towards red.

Definitions (no reference needed; float RGB in [0, 1], CIELAB by OpenCV's float ``RGB2Lab``, sRGB, D65):

- **sites**: the bright particles of the INPUT, found as :func:`murk.metrics.particle_count` finds them (luma
  stretched to its 0.5th-99.5th percentiles, white top-hat with a 15-px ellipse, components of 2-400 px, elongation
  at most 3); the same pixels are read in the output;
- **ring**: the pixels within :data:`RING_PX` of a site and more than one pixel from every site;
- **tint** of an image: mean a* over the sites minus mean a* over the ring (positive: the particles are redder,
  or less green, than what surrounds them);
- **rise**: the output's tint minus the input's.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from murk.errors import ShapeError

RING_PX = 4
"""Outer radius of the ring around the particle sites, in pixels."""


@dataclass(frozen=True)
class ParticleTint:
    """:func:`particle_tint`: a* at the sites minus a* in the ring, for the input and the output, their difference
    (``rise``) and the number of sites; NaN tints when the input has no bright particle."""

    tint_in: float
    tint_out: float
    rise: float
    sites: int


def particle_sites(image: np.ndarray) -> tuple[np.ndarray, int]:
    """The bright particle sites of ``image`` (float RGB (H, W, 3) in [0, 1]): a boolean mask and the count."""
    from murk.metrics.fidelity import PARTICLE_CONFIG, PARTICLE_PERCENTILES, PARTICLE_SPAN_FLOOR
    from murk.snow.extract import kept_components, particle_mask

    x = _check_rgb("image", image)
    y = x[..., 0] * np.float32(0.2126) + x[..., 1] * np.float32(0.7152) + x[..., 2] * np.float32(0.0722)
    lo, hi = np.percentile(y, PARTICLE_PERCENTILES)
    span = max(float(hi) - float(lo), PARTICLE_SPAN_FLOOR)
    gray = np.rint(np.clip((y - np.float32(lo)) * np.float32(255.0 / span), 0.0, 255.0)).astype(np.uint8)
    mask = np.zeros(y.shape, bool)
    comps = kept_components(particle_mask(gray, PARTICLE_CONFIG), PARTICLE_CONFIG)
    for x0, y0, w, h, m in comps:
        mask[y0 : y0 + h, x0 : x0 + w] |= m.astype(bool)
    return mask, len(comps)


def particle_tint(input: np.ndarray, output: np.ndarray) -> ParticleTint:
    """The particles' a* against their surroundings in ``input`` and in the restorer's ``output`` (module doc).

    Raises:
        ShapeError: not RGB (H, W, 3), or the shapes differ.
    """
    x = _check_rgb("input", input)
    o = _check_rgb("output", output)
    if x.shape != o.shape:
        raise ShapeError(f"output: expected the shape of input {x.shape}, got {o.shape}")
    sites, count = particle_sites(x)
    if not count:
        return ParticleTint(float("nan"), float("nan"), float("nan"), 0)
    near = cv2.dilate(sites.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (3, 3))) > 0
    outer = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * RING_PX + 1, 2 * RING_PX + 1))
    ring = (cv2.dilate(sites.astype(np.uint8), outer) > 0) & ~near
    t_in, t_out = (_tint(im, sites, ring) for im in (x, o))
    return ParticleTint(t_in, t_out, t_out - t_in, count)


def _tint(image: np.ndarray, sites: np.ndarray, ring: np.ndarray) -> float:
    a = cv2.cvtColor(np.ascontiguousarray(np.clip(image, 0.0, 1.0)), cv2.COLOR_RGB2Lab)[..., 1]
    return float(a[sites].mean(dtype=np.float64) - a[ring].mean(dtype=np.float64))


def _check_rgb(name: str, image: object) -> np.ndarray:
    if not isinstance(image, np.ndarray) or image.ndim != 3 or image.shape[2] != 3:
        raise ShapeError(f"{name}: expected an RGB image (H, W, 3), got {getattr(image, 'shape', type(image))}")
    return np.asarray(image, np.float32)
