"""UCIQE, the underwater colour image quality evaluation of Yang and Sowmya, with its three terms.

``UCIQE = 0.4680 sigma_c + 0.2745 con_l + 0.2576 mu_s`` (the linear model of Yang & Sowmya).

Two presets (``docs/metrics.md`` explains which published numbers each one reproduces):

- ``uciqe_m`` (default): the semantics of the ``UCIQE.m`` behind the published 0.4-0.65 values. The image is
  quantised to 8 bits and converted to the 8-bit CIELAB encoding (OpenCV ``COLOR_RGB2LAB``: L*255/100,
  a*+128, b*+128; D65), which is divided by 255. Chroma C is computed from the *encoded* a, b (so even a gray
  pixel has C ~ 0.71); saturation = C / sqrt(C^2 + L^2); ``sigma_c = sqrt(mean |1 - (mean(C)/C)^2|)`` (what
  ``UCIQE.m`` computes, not a standard deviation); ``con_l`` = difference of the 1 % and 99 % order
  statistics of L as ``stretchlim`` returns them (``sorted(L)[floor(0.01 N)]`` and
  ``sorted(L)[ceil(0.99 N) - 1]``, 0-based; [0, 1] when they coincide, so a flat image has con_l = 1);
  ``mu_s`` = mean saturation. Matches ``UCIQE.m`` (run in Octave with OpenCV's Lab) to 1e-5.
- ``cielab_raw``: the other common family, in raw CIELAB units (L* in [0, 100]): ``sigma_c`` = standard
  deviation of C* = sqrt(a*^2 + b*^2), ``con_l`` = P99 - P1 of L* (linear-interpolated percentiles),
  ``mu_s`` = mean of C*/L*. Values are of order 10-30. Pixels with L* = 0 have no saturation: they are left
  out of ``mu_s`` (with a warning); an image with no such pixel left gets ``mu_s = 0``.

References:
    M. Yang, A. Sowmya, "An Underwater Color Image Quality Evaluation Metric", IEEE Trans. Image Process.
    24(12):6062-6071, 2015, doi:10.1109/TIP.2015.2491020.
    CIE 15:2004 Colorimetry (CIELAB); IEC 61966-2-1 (sRGB).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Literal, NamedTuple

import cv2
import numpy as np

from murk.metrics._common import (
    check_choice,
    check_data_range,
    check_rgb_numpy,
    check_rgb_torch,
    to_255_numpy,
    to_255_torch,
    warn_metric,
)

if TYPE_CHECKING:
    import torch

UCIQEPreset = Literal["uciqe_m", "cielab_raw"]
UCIQE_PRESETS: tuple[str, ...] = ("uciqe_m", "cielab_raw")
UCIQE_WEIGHTS = (0.4680, 0.2745, 0.2576)
"""(c1, c2, c3) of Yang & Sowmya for sigma_c, con_l and mu_s."""

# sRGB (D65) -> XYZ and the D65 reference white (2 degree observer), IEC 61966-2-1 / CIE 15.
_RGB_TO_XYZ = np.array([[0.412453, 0.357580, 0.180423], [0.212671, 0.715160, 0.072169], [0.019334, 0.119193, 0.950227]])
_WHITE_D65 = np.array([0.95047, 1.0, 1.08883])
_LAB_EPS = (6.0 / 29.0) ** 3  # CIE: f(t) = t^(1/3) above, t / (3 (6/29)^2) + 4/29 below
_LAB_SLOPE = 1.0 / (3.0 * (6.0 / 29.0) ** 2)

# Chroma of every encoded (a, b) pair of the 8-bit Lab encoding, index a * 256 + b (UCIQE.m divides by 255).
_CHROMA_TAB = np.hypot((np.arange(65536) // 256) / 255.0, (np.arange(65536) % 256) / 255.0)

_MSG_BLACK = "saturation C*/L* is undefined at {n} pixel(s) with L* = 0: they are left out of mu_s"
_MSG_ALL_BLACK = "saturation C*/L* is undefined everywhere (L* = 0 at every pixel): mu_s set to 0"


@dataclass(frozen=True)
class UCIQEResult:
    """UCIQE of one image with its terms: ``uciqe = 0.4680 sigma_c + 0.2745 con_l + 0.2576 mu_s``."""

    uciqe: float
    sigma_c: float
    con_l: float
    mu_s: float
    preset: str

    def as_dict(self) -> dict[str, float | str]:
        """The fields as a plain dict (for tables and JSON)."""
        return asdict(self)


class UCIQEBatch(NamedTuple):
    """Per-image UCIQE and terms of a batch: float64 tensors of shape (B,) on the input's device."""

    uciqe: torch.Tensor
    sigma_c: torch.Tensor
    con_l: torch.Tensor
    mu_s: torch.Tensor


def uciqe(image: np.ndarray, *, data_range: float, preset: UCIQEPreset = "uciqe_m") -> UCIQEResult:
    """UCIQE of one RGB image and its three terms (Yang & Sowmya 2015).

    Args:
        image: RGB array (H, W, 3), integer or float, values in [0, data_range].
        data_range: the value of full white: 255 for uint8-scaled input, 1.0 for floats in [0, 1]. Required,
            never inferred. ``uciqe_m`` quantises the image to 8 bits (round half to even) because
            ``UCIQE.m`` works on the 8-bit Lab encoding; ``cielab_raw`` works in float64.
        preset: ``"uciqe_m"`` (default) or ``"cielab_raw"``; see the module docstring.

    Returns:
        A frozen :class:`UCIQEResult` with ``uciqe``, ``sigma_c``, ``con_l``, ``mu_s`` and ``preset``.

    Raises:
        TypeError: ``image`` is not a numpy array of a real dtype, or ``data_range``/``preset`` has the wrong
            type.
        ShapeError: ``image`` is not (H, W, 3).
        ValueError: bad ``data_range`` or ``preset``; NaN/inf values; values outside [0, data_range].

    Warns:
        MetricWarning: (``cielab_raw``) saturation undefined at black pixels.
    """
    preset = check_choice("preset", preset, UCIQE_PRESETS)  # type: ignore[assignment]
    data_range = check_data_range(data_range)
    check_rgb_numpy("image", image, data_range)
    if preset == "uciqe_m":
        sigma_c, con_l, mu_s = _uciqe_m(_quantise_u8(image, data_range))
    else:
        sigma_c, con_l, mu_s = _cielab_raw(image, data_range)
    c1, c2, c3 = UCIQE_WEIGHTS
    value = c1 * sigma_c + c2 * con_l + c3 * mu_s
    return UCIQEResult(float(value), float(sigma_c), float(con_l), float(mu_s), preset)


# ----------------------------------------------------------------------------------------------------------
# uciqe_m (numpy)


def _quantise_u8(image: np.ndarray, data_range: float) -> np.ndarray:
    """The image as uint8 (H, W, 3): as is when it is uint8 with data_range 255, else rint(x * 255/range)."""
    if image.dtype == np.uint8 and data_range == 255.0:
        return np.ascontiguousarray(image)
    return np.rint(to_255_numpy(image, data_range, np.float32)).astype(np.uint8)


def _stretchlim_indices(n: int) -> tuple[int, int]:
    """0-based ranks of the low and high limits of ``stretchlim`` (1 % and 99 %) among n sorted values."""
    return math.floor(0.01 * n), math.ceil(0.99 * n) - 1


def _uciqe_m(rgb_u8: np.ndarray) -> tuple[float, float, float]:
    lab = cv2.cvtColor(rgb_u8, cv2.COLOR_RGB2LAB)
    n = lab.shape[0] * lab.shape[1]
    flat = lab.reshape(n, 3)
    # Chroma depends on (a, b) only: a 65536-bin histogram gives mean(C) and sigma_c exactly and fast.
    ab = flat[:, 1].astype(np.int64) * 256 + flat[:, 2]
    chroma_tab = _CHROMA_TAB
    hist_ab = np.bincount(ab, minlength=65536)
    used = hist_ab > 0
    mean_c = float(np.dot(hist_ab[used], chroma_tab[used])) / n
    # a, b >= 1 in the 8-bit encoding of any sRGB colour, so C > 0 (no division by zero).
    sigma_c = math.sqrt(float(np.dot(hist_ab[used], np.abs(1.0 - (mean_c / chroma_tab[used]) ** 2))) / n)
    lum = flat[:, 0].astype(np.float64) / 255.0
    c = chroma_tab[ab]
    mu_s = float(np.mean(c / np.sqrt(c * c + lum * lum)))
    hist_l = np.cumsum(np.bincount(flat[:, 0], minlength=256))
    i_lo, i_hi = _stretchlim_indices(n)
    lo = int(np.searchsorted(hist_l, i_lo, side="right"))  # value of rank i_lo
    hi = int(np.searchsorted(hist_l, i_hi, side="right"))
    con_l = 1.0 if lo == hi else (hi - lo) / 255.0  # stretchlim returns [0, 1] when the limits coincide
    return sigma_c, con_l, mu_s


# ----------------------------------------------------------------------------------------------------------
# cielab_raw (numpy)


def _srgb_linear(c: np.ndarray) -> np.ndarray:
    """sRGB decoding (IEC 61966-2-1) of values in [0, 1]; the power is evaluated only where it applies."""
    out = c / 12.92
    hi = c > 0.04045
    out[hi] = ((c[hi] + 0.055) / 1.055) ** 2.4
    return out


_SRGB_LINEAR_U8 = _srgb_linear(np.arange(256) / 255.0)


def _lab_f(image: np.ndarray, data_range: float) -> np.ndarray:
    """CIELAB's f(X/Xn), f(Y/Yn), f(Z/Zn) per pixel, (N, 3) float64, of an sRGB image (D65).

    uint8 input with data_range 255 is decoded through a 256-entry table (the same values as the formula).
    """
    if image.dtype == np.uint8 and data_range == 255.0:
        lin = _SRGB_LINEAR_U8[image]
    else:
        lin = _srgb_linear(to_255_numpy(image, data_range, np.float64) / 255.0)
    xyz = (lin @ (_RGB_TO_XYZ.T / _WHITE_D65)).reshape(-1, 3)
    return np.where(xyz > _LAB_EPS, np.cbrt(xyz), xyz * _LAB_SLOPE + 4.0 / 29.0)


def _cielab_raw(image: np.ndarray, data_range: float) -> tuple[float, float, float]:
    f = _lab_f(image, data_range)
    fx, fy, fz = f[:, 0], f[:, 1], f[:, 2]
    lum = np.maximum(116.0 * fy - 16.0, 0.0)  # L*
    chroma = np.hypot(500.0 * (fx - fy), 200.0 * (fy - fz))  # C* = sqrt(a*^2 + b*^2)
    sigma_c = float(np.std(chroma))
    p1, p99 = np.percentile(lum, [1.0, 99.0])
    con_l = float(p99 - p1)
    pos = lum > 0
    n_pos = int(np.count_nonzero(pos))
    if n_pos == 0:
        warn_metric(_MSG_ALL_BLACK)
        return sigma_c, con_l, 0.0
    if n_pos < lum.size:
        warn_metric(_MSG_BLACK.format(n=lum.size - n_pos))
    mu_s = float(np.divide(chroma, lum, out=np.zeros_like(lum), where=pos).sum()) / n_pos
    return sigma_c, con_l, mu_s


# ----------------------------------------------------------------------------------------------------------
# torch twins

_LAB_LUT: dict[str, torch.Tensor] = {}


def _lab_u8_lut(device: torch.device) -> torch.Tensor:
    """OpenCV's 8-bit RGB -> Lab for all 2^24 colours as a (2^24, 3) uint8 tensor, built once per device.

    Built by converting every colour with ``cv2.cvtColor`` (a per-pixel function), so the torch path uses
    bit-identical Lab values (48 MiB per device).
    """
    import torch

    key = str(device)
    if key not in _LAB_LUT:
        codes = np.arange(1 << 24, dtype=np.uint32)
        rgb = np.stack([(codes >> 16) & 255, (codes >> 8) & 255, codes & 255], axis=-1).astype(np.uint8)
        lab = cv2.cvtColor(rgb.reshape(4096, 4096, 3), cv2.COLOR_RGB2LAB).reshape(-1, 3)
        _LAB_LUT[key] = torch.from_numpy(lab).to(device)
    return _LAB_LUT[key]


def uciqe_torch(images: torch.Tensor, *, data_range: float, preset: UCIQEPreset = "uciqe_m") -> UCIQEBatch:
    """Batched UCIQE on a torch batch; the twin of :func:`uciqe`, on the input's device.

    Args:
        images: (B, 3, H, W) RGB tensor, integer or float, values in [0, data_range].
        data_range: full white (255 for uint8-scaled input, 1.0 for [0, 1]); required.
        preset: as in :func:`uciqe`.

    Returns:
        :class:`UCIQEBatch` of float64 tensors (B,): ``uciqe``, ``sigma_c``, ``con_l``, ``mu_s``.

    ``uciqe_m`` uses OpenCV's 8-bit Lab through a lookup table of all 2^24 colours (built once per device,
    48 MiB), so it equals :func:`uciqe` to float64 rounding.

    Raises:
        TypeError, ShapeError, ValueError: as :func:`uciqe`, for a (B, 3, H, W) tensor.
    """
    import torch

    preset = check_choice("preset", preset, UCIQE_PRESETS)  # type: ignore[assignment]
    data_range = check_data_range(data_range)
    check_rgb_torch("images", images, data_range)
    if preset == "uciqe_m":
        if images.dtype == torch.uint8 and data_range == 255.0:
            q = images.long()
        else:
            q = torch.round(to_255_torch(images, data_range, torch.float32)).long()
        sigma_c, con_l, mu_s = _uciqe_m_torch(q)
    else:
        sigma_c, con_l, mu_s = _cielab_raw_torch(to_255_torch(images, data_range, torch.float64) / 255.0)
    c1, c2, c3 = UCIQE_WEIGHTS
    return UCIQEBatch(c1 * sigma_c + c2 * con_l + c3 * mu_s, sigma_c, con_l, mu_s)


def _uciqe_m_torch(q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    import torch

    bsz = q.shape[0]
    codes = (q[:, 0] * 65536 + q[:, 1] * 256 + q[:, 2]).flatten(1)  # (B, N)
    n = codes.shape[1]
    lab = _lab_u8_lut(q.device)[codes]  # (B, N, 3) uint8
    lum = lab[..., 0].double() / 255.0
    a = lab[..., 1].double() / 255.0
    b = lab[..., 2].double() / 255.0
    c = torch.sqrt(a * a + b * b)
    mean_c = c.mean(dim=1, keepdim=True)
    sigma_c = torch.sqrt(torch.abs(1.0 - (mean_c / c) ** 2).mean(dim=1))
    mu_s = (c / torch.sqrt(c * c + lum * lum)).mean(dim=1)
    offsets = torch.arange(bsz, device=q.device)[:, None] * 256
    hist = torch.bincount((lab[..., 0].long() + offsets).flatten(), minlength=bsz * 256).reshape(bsz, 256)
    cum = torch.cumsum(hist, dim=1)
    i_lo, i_hi = _stretchlim_indices(n)
    ranks = torch.tensor([[i_lo, i_hi]], device=q.device).expand(bsz, 2).contiguous()
    lims = torch.searchsorted(cum, ranks, right=True)  # (B, 2) values of the two ranks
    con_l = torch.where(lims[:, 0] == lims[:, 1], 1.0, (lims[:, 1] - lims[:, 0]).double() / 255.0)
    return sigma_c, con_l.double(), mu_s


def _srgb_to_lab_torch(rgb: torch.Tensor) -> torch.Tensor:
    """CIELAB (L*, a*, b*) of sRGB values in [0, 1], (..., 3) float64; the formulas of :func:`_lab_f`."""
    import torch

    m = torch.as_tensor(_RGB_TO_XYZ.T / _WHITE_D65, dtype=rgb.dtype, device=rgb.device)
    lin = torch.where(rgb <= 0.04045, rgb / 12.92, ((rgb.clamp_min(0.04045) + 0.055) / 1.055) ** 2.4)
    xyz = lin @ m
    f = torch.where(xyz > _LAB_EPS, torch.pow(xyz.clamp_min(0.0), 1.0 / 3.0), xyz * _LAB_SLOPE + 4.0 / 29.0)
    return torch.stack(
        [116.0 * f[..., 1] - 16.0, 500.0 * (f[..., 0] - f[..., 1]), 200.0 * (f[..., 1] - f[..., 2])], dim=-1
    )


def _percentile_torch(v: torch.Tensor, pct: float) -> torch.Tensor:
    """Per-row percentile of (B, N) with numpy's default linear interpolation (no torch.quantile size limit)."""
    import torch

    n = v.shape[1]
    s = torch.sort(v, dim=1).values
    pos = pct / 100.0 * (n - 1)
    lo = math.floor(pos)
    hi = min(lo + 1, n - 1)
    t = pos - lo
    return s[:, lo] + (s[:, hi] - s[:, lo]) * t


def _cielab_raw_torch(rgb01: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    import torch

    lab = _srgb_to_lab_torch(rgb01.permute(0, 2, 3, 1)).flatten(1, 2)  # (B, N, 3)
    lum = lab[..., 0].clamp_min(0.0)
    chroma = torch.hypot(lab[..., 1], lab[..., 2])
    sigma_c = chroma.std(dim=1, correction=0)
    con_l = _percentile_torch(lum, 99.0) - _percentile_torch(lum, 1.0)
    pos = lum > 0
    n_pos = pos.sum(dim=1)
    n_black = int((lum.shape[1] - n_pos).sum())
    if n_black:
        if bool((n_pos == 0).any()):
            warn_metric(_MSG_ALL_BLACK)
        else:
            warn_metric(_MSG_BLACK.format(n=n_black))
    sat = torch.where(pos, chroma / torch.where(pos, lum, 1.0), 0.0)
    mu_s = torch.where(n_pos > 0, sat.sum(dim=1) / n_pos.clamp_min(1), 0.0)
    return sigma_c, con_l, mu_s
