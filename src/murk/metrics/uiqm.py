"""UIQM, the no-reference underwater image quality measure of Eq. (10) of the paper, with its three terms.

``UIQM = 0.0282 UICM + 0.2953 UISM + 3.5753 UIConM`` (Eq. (10) of the paper, weights of Panetta et al.).

Three presets (``docs/metrics.md`` explains which published numbers each one reproduces):

- ``panetta2016`` (default): the definitions of Panetta et al. read literally. UICM with the asymmetric
  alpha-trimmed mean (T_L = ceil(0.1 K) lowest and T_R = floor(0.1 K) highest values dropped) and the
  variance over all pixels (Eq. (4) read literally); UISM as the EME of the Sobel edge maps over 8x8 blocks
  (Sec. IV); UIConM as the PLIP logAMEE of the intensity over 8x8 blocks (Eq. (9)). Eq. (9) taken literally
  is <= 0 (each block term c log c with c in [0, 1] is <= 0), so murk returns its negation: UIConM >= 0,
  larger = more contrast. Computed in float64 on the image scaled to [0, 255].
- ``funie``: reproduces the widely copied Python code of FUnIE-GAN (``uqim_utils.py``, python-3 fork): 10x10
  blocks, blue weight 0.144, its off-by-one trimmed mean accumulated sequentially in float32, Sobel magnitude
  rescaled by 255/max, UIConM as the Michelson term on block max/min over all three channels. float32 like
  the original.
- ``jointid``: ``funie`` with the block weights computed from float W/10 and H/10 (the Joint-ID lab's copy);
  identical to ``funie`` when W and H are multiples of 10.

Never NaN: where a term is undefined (a constant channel makes the ``funie`` Sobel rescale 0/0; an image
smaller than one block has no EME; a 1-pixel image has no trimmed mean) a documented finite value is returned
and a :class:`~murk.metrics.MetricWarning` is emitted (see each function).

References:
    K. Panetta, C. Gao, S. Agaian, "Human-Visual-System-Inspired Underwater Image Quality Measures", IEEE
    J. Oceanic Eng. 41(3):541-551, 2016, doi:10.1109/JOE.2015.2469915.
    M. J. Islam, Y. Xia, J. Sattar, "Fast Underwater Image Enhancement for Improved Visual Perception", IEEE
    RA-L 5(2):3227-3234, 2020, doi:10.1109/LRA.2020.2974710 (the ``funie`` code family).
    G. Yang, G. Kang, J. Lee, Y. Cho, "Joint-ID: Transformer-Based Joint Image Enhancement and Depth
    Estimation for Underwater Environments", IEEE Sensors J., 2023, doi:10.1109/JSEN.2023.3338730.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Literal, NamedTuple

import cv2
import numpy as np

from murk.metrics._common import (
    block_max_min,
    block_max_min_torch,
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

UIQMPreset = Literal["panetta2016", "funie", "jointid"]
UIQM_PRESETS: tuple[str, ...] = ("panetta2016", "funie", "jointid")
UIQM_WEIGHTS = (0.0282, 0.2953, 3.5753)
"""(c1, c2, c3) of Eq. (10): the weights of Panetta et al. for UICM, UISM and UIConM."""

_UICM_WEIGHTS = (-0.0268, 0.1586)
_UISM_WEIGHTS = {"panetta2016": (0.299, 0.587, 0.114), "funie": (0.299, 0.587, 0.144), "jointid": (0.299, 0.587, 0.144)}
_BLOCK = {"panetta2016": 8, "funie": 10, "jointid": 10}
_PLIP_GAMMA = 1026.0  # PLIP gamma = k = 1026 (beta = 1) for 8-bit gray tones, Panetta et al. Sec. IV

_MSG_TINY = "image {h}x{w} has no whole {b}x{b} block: EME (UISM) and logAMEE (UIConM) are undefined, set to 0"
_MSG_ONE_PIXEL = "a 1-pixel image has no alpha-trimmed mean (all values trimmed): the plain mean is used in UICM"
_MSG_FLAT = (
    "channel(s) {ch} are constant: the {preset} Sobel rescale 255/max is 0/0 (the original code returns NaN); "
    "their edge maps are set to 0, so they contribute 0 to UISM"
)


@dataclass(frozen=True)
class UIQMResult:
    """UIQM of one image with its terms (Eq. (10)): ``uiqm = 0.0282 uicm + 0.2953 uism + 3.5753 uiconm``."""

    uiqm: float
    uicm: float
    uism: float
    uiconm: float
    preset: str

    def as_dict(self) -> dict[str, float | str]:
        """The fields as a plain dict (for tables and JSON)."""
        return asdict(self)


class UIQMBatch(NamedTuple):
    """Per-image UIQM and terms of a batch: float64 tensors of shape (B,) on the input's device."""

    uiqm: torch.Tensor
    uicm: torch.Tensor
    uism: torch.Tensor
    uiconm: torch.Tensor


def uiqm(image: np.ndarray, *, data_range: float, preset: UIQMPreset = "panetta2016") -> UIQMResult:
    """UIQM of one RGB image and its three terms. Implements Eq. (10) of the paper.

    Args:
        image: RGB array (H, W, 3), integer or float, values in [0, data_range].
        data_range: the value of full white: 255 for uint8-scaled input, 1.0 for floats in [0, 1], 65535
            for uint16. Required, never inferred. The image is scaled to [0, 255] internally (the PLIP
            constants and the ``funie`` code assume 8-bit gray levels).
        preset: ``"panetta2016"`` (default, the paper's definitions), ``"funie"`` or ``"jointid"`` (reproduce
            those codebases to 1e-4). See the module docstring.

    Returns:
        A frozen :class:`UIQMResult` with ``uiqm``, ``uicm``, ``uism``, ``uiconm`` and ``preset``.

    Raises:
        TypeError: ``image`` is not a numpy array of a real dtype, or ``data_range``/``preset`` has the wrong
            type.
        ShapeError: ``image`` is not (H, W, 3).
        ValueError: bad ``data_range`` or ``preset``; NaN/inf values; values outside [0, data_range].

    Warns:
        MetricWarning: a term is undefined for this image and its documented finite value is used.
    """
    preset = check_choice("preset", preset, UIQM_PRESETS)  # type: ignore[assignment]
    data_range = check_data_range(data_range)
    check_rgb_numpy("image", image, data_range)
    if preset == "panetta2016":
        x = _snap_numpy(to_255_numpy(image, data_range, np.float64))
        uicm_v = _uicm_panetta(x)
        uism_v, uiconm_v = _uism_uiconm_panetta(x)
    else:
        x = _snap_numpy(to_255_numpy(image, data_range, np.float64)).astype(np.float32)
        uicm_v = _uicm_funie(x)
        uism_v = _uism_funie(x, preset)
        uiconm_v = _uiconm_funie(x, preset)
    c1, c2, c3 = UIQM_WEIGHTS
    value = c1 * uicm_v + c2 * uism_v + c3 * uiconm_v  # Eq. (10)
    return UIQMResult(float(value), float(uicm_v), float(uism_v), float(uiconm_v), preset)


# ----------------------------------------------------------------------------------------------------------
# the input grid


SNAP_DECIMALS = 3
"""Images are rounded to 1/1000 of a grey level on the [0, 255] scale before UIQM. An 8-bit image stored as
float32 in [0, 1] (k/255 is not exactly representable) then scores exactly as the uint8 image: without it,
float rounding leaves ~1e-4 gradients in flat 8x8 blocks, and UISM's log(Imax/Imin) (Imin = 0 blocks are
skipped, tiny Imin are not) rose by up to 0.28 (UIQM +0.08) for the same picture. Real image content finer
than 1/1000 grey level does not exist at 8-16 bits."""


def _snap_numpy(x: np.ndarray) -> np.ndarray:
    return np.round(x, SNAP_DECIMALS)


def _snap_torch(x: torch.Tensor) -> torch.Tensor:
    import torch

    return torch.round(x, decimals=SNAP_DECIMALS)


# panetta2016 (numpy, float64)


def _trim_counts(k: int) -> tuple[int, int]:
    """(T_L, T_R) = (ceil(0.1 K), floor(0.1 K)) in exact integer arithmetic."""
    return -(-k // 10), k // 10


def _trimmed_mean_panetta(v: np.ndarray) -> float:
    """Asymmetric alpha-trimmed mean: mean of the sorted values after dropping T_L lowest and T_R highest."""
    k = v.size
    t_l, t_r = _trim_counts(k)
    kept = k - t_l - t_r
    if kept <= 0:  # only K = 1; the caller has warned
        return float(v.mean())
    s = np.sort(v)
    return float(s[t_l : k - t_r].sum() / kept)


def _uicm_panetta(x: np.ndarray) -> float:
    """UICM: colourfulness from the trimmed means and variances of the RG and YB opponent channels."""
    r, g, b = x[..., 0], x[..., 1], x[..., 2]
    rg = (r - g).ravel()
    yb = (0.5 * (r + g) - b).ravel()
    if rg.size == 1:
        warn_metric(_MSG_ONE_PIXEL)
    mu_rg, mu_yb = _trimmed_mean_panetta(rg), _trimmed_mean_panetta(yb)
    s2_rg = float(np.mean((rg - mu_rg) ** 2))  # Eq. (4) read literally: over all pixels
    s2_yb = float(np.mean((yb - mu_yb) ** 2))
    a, b_ = _UICM_WEIGHTS
    return a * math.sqrt(mu_rg * mu_rg + mu_yb * mu_yb) + b_ * math.sqrt(s2_rg + s2_yb)


def _sobel_magnitude(x: np.ndarray, ddepth: int) -> np.ndarray:
    """Sobel gradient magnitude sqrt(Gx^2 + Gy^2) per channel, reflect border (edge pixel repeated)."""
    gx = cv2.Sobel(x, ddepth, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT)
    gy = cv2.Sobel(x, ddepth, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT)
    return np.sqrt(gx * gx + gy * gy)


def _eme_panetta(mx: np.ndarray, mn: np.ndarray) -> np.ndarray:
    """EME per channel from block max/min (k2, k1, C): 2/(k1 k2) sum ln(Imax/Imin); Imin = 0 blocks give 0."""
    k2, k1 = mx.shape[:2]
    ok = mn > 0
    ratio = np.where(ok, mx, 1.0) / np.where(ok, mn, 1.0)
    return 2.0 / (k1 * k2) * np.log(ratio).sum(axis=(0, 1))


def _plip_log_amee(mx: np.ndarray, mn: np.ndarray) -> float:
    """PLIP logAMEE (Eq. (9) of Panetta et al.) of block max/min (k2, k1); <= 0.

    Per block c = (Imax (-) Imin) / (Imax (+) Imin) with a (-) b = k (a - b)/(k - b) and
    a (+) b = a + b - a b / gamma, term t = c ln c (0 when c = 0). The PLIP sum and the PLIP scalar product
    with 1/(k1 k2) are evaluated through their closed form
    ``(1/(k1 k2)) (x) ((+)_i t_i) = gamma (1 - prod_i (1 - t_i/gamma)^(1/(k1 k2)))``,
    computed as ``-gamma expm1(sum_i log1p(-t_i/gamma) / (k1 k2))`` for accuracy.
    """
    gamma = k = _PLIP_GAMMA
    n = mx.size
    num = k * (mx - mn) / (k - mn)  # PLIP subtraction Imax (-) Imin
    den = mx + mn - mx * mn / gamma  # PLIP addition Imax (+) Imin
    ok = den > 0
    c = np.where(ok, num, 0.0) / np.where(ok, den, 1.0)
    pos = c > 0
    t = np.where(pos, c * np.log(np.where(pos, c, 1.0)), 0.0)
    return float(-gamma * math.expm1(float(np.log1p(-t / gamma).sum()) / n))  # Eq. (9)


def _uism_uiconm_panetta(x: np.ndarray) -> tuple[float, float]:
    """UISM (EME of Sobel edge maps, 8x8 blocks) and UIConM (-logAMEE of the intensity, 8x8 blocks)."""
    block = _BLOCK["panetta2016"]
    h, w = x.shape[:2]
    if h < block or w < block:
        warn_metric(_MSG_TINY.format(h=h, w=w, b=block))
        return 0.0, 0.0
    edge = _sobel_magnitude(x, cv2.CV_64F) * x  # grayscale edge map of each channel
    mx, mn = block_max_min(edge, block)
    eme = _eme_panetta(mx, mn)
    uism_v = float(np.dot(_UISM_WEIGHTS["panetta2016"], eme))
    intensity = (x[..., 0] + x[..., 1] + x[..., 2]) / 3.0
    imx, imn = block_max_min(intensity, block)
    uiconm_v = -_plip_log_amee(imx, imn)  # negated: Eq. (9) literally is <= 0
    return uism_v, uiconm_v


# ----------------------------------------------------------------------------------------------------------
# funie / jointid (numpy, float32 like the original code)


def _trimmed_mean_funie(v: np.ndarray) -> np.float32:
    """The FUnIE trimmed mean, reproduced exactly.

    T_L = ceil(0.1 K) and T_R = floor(0.1 K) in double precision; the code sums the sorted values with
    0-based indices T_L + 1 .. K - T_R - 1 (one value fewer than it divides by) with Python's ``sum`` over
    float32 scalars, i.e. a sequential float32 accumulation, reproduced here by ``np.cumsum`` (strictly
    sequential). The result is float32 (NumPy 2 promotion).
    """
    k = v.size
    t_l, t_r = math.ceil(0.1 * k), math.floor(0.1 * k)
    if k - t_l - t_r <= 0:  # only K = 1; the original divides by zero; the caller has warned
        return np.float32(v.astype(np.float64).mean())
    weight = 1.0 / (k - t_l - t_r)
    seg = np.sort(v)[t_l + 1 : k - t_r]
    total = np.cumsum(seg, dtype=np.float32)[-1] if seg.size else np.float32(0.0)
    return np.float32(total * np.float32(weight))


def _uicm_funie(x: np.ndarray) -> float:
    """FUnIE UICM on a float32 [0, 255] image: its trimmed means, float32 differences, double variances."""
    r, g, b = x[..., 0].ravel(), x[..., 1].ravel(), x[..., 2].ravel()
    rg = r - g
    yb = (r + g) / np.float32(2.0) - b
    if rg.size == 1:
        warn_metric(_MSG_ONE_PIXEL)
    mu_rg, mu_yb = _trimmed_mean_funie(rg), _trimmed_mean_funie(yb)
    # Variance: float32 differences, squared and summed in double (math.pow in the original).
    s2_rg = float(np.sum(np.square((rg - mu_rg).astype(np.float64)))) / rg.size
    s2_yb = float(np.sum(np.square((yb - mu_yb).astype(np.float64)))) / yb.size
    mr, my = float(mu_rg), float(mu_yb)
    a, b_ = _UICM_WEIGHTS
    return a * math.sqrt(mr * mr + my * my) + b_ * math.sqrt(s2_rg + s2_yb)


def _block_weight(shape_hw: tuple[int, int], preset: str, scale: float) -> float:
    """``scale / (k1 k2)``: integer block counts for funie, float W/10 and H/10 for jointid."""
    h, w = shape_hw
    b = _BLOCK[preset]
    if preset == "jointid":
        return scale / ((w / b) * (h / b))
    return scale / ((w // b) * (h // b))


def _channel_names(flags: list[bool]) -> str:
    return "".join(c for c, f in zip("RGB", flags, strict=True) if f)


def _uism_funie(x: np.ndarray, preset: str) -> float:
    """FUnIE UISM: EME over 10x10 blocks of (Sobel magnitude x 255/max) x channel, blue weight 0.144."""
    block = _BLOCK[preset]
    h, w = x.shape[:2]
    if h < block or w < block:
        warn_metric(_MSG_TINY.format(h=h, w=w, b=block))
        return 0.0
    mag = np.hypot(
        cv2.Sobel(x, cv2.CV_32F, 1, 0, ksize=3, borderType=cv2.BORDER_REFLECT),
        cv2.Sobel(x, cv2.CV_32F, 0, 1, ksize=3, borderType=cv2.BORDER_REFLECT),
    )
    peak = mag.reshape(-1, 3).max(axis=0)
    flat = peak == 0
    if flat.any():
        warn_metric(_MSG_FLAT.format(ch=_channel_names(flat.tolist()), preset=preset))
    scale = np.float32(255.0) / np.where(flat, np.float32(1.0), peak)  # float32 like the original
    scale = np.where(flat, np.float32(0.0), scale).astype(np.float32)
    edge = (mag * scale) * x
    mx, mn = block_max_min(edge, block)
    ok = (mn != 0) & (mx != 0)
    ratio = np.where(ok, mx, np.float32(1.0)) / np.where(ok, mn, np.float32(1.0))  # float32 division
    eme = _block_weight((h, w), preset, 2.0) * np.log(ratio.astype(np.float64)).sum(axis=(0, 1))
    return float(np.dot(_UISM_WEIGHTS[preset], eme))


def _uiconm_funie(x: np.ndarray, preset: str) -> float:
    """FUnIE UIConM: -1/(k1 k2) sum c ln c, c = (max - min)/(max + min) over each 10x10 block's three channels."""
    block = _BLOCK[preset]
    h, w = x.shape[:2]
    if h < block or w < block:  # the caller (UISM) has warned
        return 0.0
    mx, mn = block_max_min(x, block)
    mx, mn = mx.max(axis=2), mn.min(axis=2)  # over the block's three channels
    top, bot = mx - mn, mx + mn
    ok = (top != 0) & (bot != 0)
    c = (np.where(ok, top, np.float32(1.0)) / np.where(ok, bot, np.float32(1.0))).astype(np.float64)
    val = float(np.sum(c * np.log(c)))  # c = 1 where not ok: contributes 0
    return _block_weight((h, w), preset, -1.0) * val


# ----------------------------------------------------------------------------------------------------------
# torch twins


def uiqm_torch(images: torch.Tensor, *, data_range: float, preset: UIQMPreset = "panetta2016") -> UIQMBatch:
    """Batched UIQM (Eq. (10)) on a torch batch; the twin of :func:`uiqm`, on the input's device.

    Args:
        images: (B, 3, H, W) RGB tensor, integer or float, values in [0, data_range].
        data_range: full white (255 for uint8-scaled input, 1.0 for [0, 1]); required.
        preset: as in :func:`uiqm`.

    Returns:
        :class:`UIQMBatch` of float64 tensors (B,): ``uiqm``, ``uicm``, ``uism``, ``uiconm``.

    ``panetta2016`` equals :func:`uiqm` to rounding (float64) and stays on the device. ``funie``/``jointid``
    equal :func:`uiqm` (and the original code) too: their trimmed mean needs the original's sequential float32
    accumulation, which no parallel reduction reproduces, so the kept values are summed on the CPU (one copy
    of ~1 MB per 640x480 image); prefer ``panetta2016`` where speed matters. No gradients are tracked.

    Raises:
        TypeError, ShapeError, ValueError: as :func:`uiqm`, for a (B, 3, H, W) tensor.
    """
    import torch

    preset = check_choice("preset", preset, UIQM_PRESETS)  # type: ignore[assignment]
    data_range = check_data_range(data_range)
    check_rgb_torch("images", images, data_range)
    if preset == "panetta2016":
        x = _snap_torch(to_255_torch(images, data_range, torch.float64))
        uicm_v = _uicm_torch(x, preset)
        uism_v, uiconm_v = _uism_uiconm_panetta_torch(x)
    else:
        x = _snap_torch(to_255_torch(images, data_range, torch.float64)).float()
        uicm_v = _uicm_torch(x, preset)
        uism_v = _uism_funie_torch(x, preset)
        uiconm_v = _uiconm_funie_torch(x, preset)
    c1, c2, c3 = UIQM_WEIGHTS
    value = c1 * uicm_v + c2 * uism_v + c3 * uiconm_v  # Eq. (10)
    return UIQMBatch(value, uicm_v, uism_v, uiconm_v)


def _uicm_torch(x: torch.Tensor, preset: str) -> torch.Tensor:
    import torch

    r, g, b = x[:, 0], x[:, 1], x[:, 2]
    rg = (r - g).flatten(1)
    if preset == "panetta2016":
        yb = (0.5 * (r + g) - b).flatten(1)
    else:
        yb = ((r + g) / 2.0 - b).flatten(1)
    k = rg.shape[1]
    if k == 1:
        warn_metric(_MSG_ONE_PIXEL)
    mus, s2s = [], []
    for v in (rg, yb):
        if preset == "panetta2016":
            t_l, t_r = _trim_counts(k)
            lo, hi = t_l, k - t_r
        else:
            t_l, t_r = math.ceil(0.1 * k), math.floor(0.1 * k)
            lo, hi = t_l + 1, k - t_r
        kept = k - t_l - t_r
        if kept <= 0:
            mu = v.double().mean(dim=1)
            if preset != "panetta2016":
                mu = mu.float()
        elif preset == "panetta2016":
            mu = torch.sort(v, dim=1).values[:, lo:hi].sum(dim=1) * (1.0 / kept)
        else:
            mu = _sequential_float32_sum(torch.sort(v, dim=1).values[:, lo:hi]) * np.float32(1.0 / kept)
        if preset == "panetta2016":
            s2 = ((v - mu[:, None]) ** 2).mean(dim=1)
        else:  # float32 differences from the float32 trimmed mean, squared and summed in double
            s2 = ((v - mu[:, None]).double() ** 2).sum(dim=1) / k
        mus.append(mu.double())
        s2s.append(s2.double())
    a, b_ = _UICM_WEIGHTS
    return a * torch.sqrt(mus[0] ** 2 + mus[1] ** 2) + b_ * torch.sqrt(s2s[0] + s2s[1])


def _sequential_float32_sum(rows: torch.Tensor) -> torch.Tensor:
    """Row sums of a float32 (B, n) tensor accumulated strictly left to right in float32, as the FUnIE code's
    Python ``sum`` does. No parallel reduction reproduces that rounding, so the rows go through numpy's
    (sequential) ``cumsum`` on the CPU: one device-to-host copy of the kept values (~1 MB per 640x480 image).
    """
    import torch

    if rows.shape[1] == 0:
        return rows.new_zeros(rows.shape[0])
    host = rows.detach().cpu().numpy()
    sums = np.cumsum(host, axis=1, dtype=np.float32)[:, -1]
    return torch.from_numpy(np.ascontiguousarray(sums)).to(rows.device)


def _sobel_magnitude_torch(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Sobel Gx, Gy of (B, C, H, W) with the reflect border (edge pixel repeated), by shifted sums.

    Elementwise arithmetic only (no convolution), so no TF32 or algorithm choice can change the result.
    """
    import torch.nn.functional as F

    p = F.pad(x, (1, 1, 1, 1), mode="replicate")  # equals BORDER_REFLECT for a radius-1 kernel
    d = p[..., :, 2:] - p[..., :, :-2]
    gx = d[..., :-2, :] + 2.0 * d[..., 1:-1, :] + d[..., 2:, :]
    s = p[..., :, :-2] + 2.0 * p[..., :, 1:-1] + p[..., :, 2:]
    gy = s[..., 2:, :] - s[..., :-2, :]
    return gx, gy


def _uism_uiconm_panetta_torch(x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    import torch

    block = _BLOCK["panetta2016"]
    bsz, _, h, w = x.shape
    if h < block or w < block:
        warn_metric(_MSG_TINY.format(h=h, w=w, b=block))
        zero = x.new_zeros(bsz)
        return zero, zero
    gx, gy = _sobel_magnitude_torch(x)
    edge = torch.sqrt(gx * gx + gy * gy) * x
    mx, mn = block_max_min_torch(edge, block)  # (B, 3, k2, k1)
    k2, k1 = mx.shape[-2:]
    ok = mn > 0
    ratio = torch.where(ok, mx, 1.0) / torch.where(ok, mn, 1.0)
    eme = 2.0 / (k1 * k2) * torch.log(ratio).sum(dim=(-2, -1))
    uism_v = eme @ torch.tensor(_UISM_WEIGHTS["panetta2016"], dtype=eme.dtype, device=eme.device)
    intensity = (x[:, 0] + x[:, 1] + x[:, 2]) / 3.0
    imx, imn = block_max_min_torch(intensity, block)  # (B, k2, k1)
    gamma = k = _PLIP_GAMMA
    num = k * (imx - imn) / (k - imn)
    den = imx + imn - imx * imn / gamma
    okd = den > 0
    c = torch.where(okd, num, 0.0) / torch.where(okd, den, 1.0)
    pos = c > 0
    t = torch.where(pos, c * torch.log(torch.where(pos, c, 1.0)), 0.0)
    log_amee = -gamma * torch.expm1(torch.log1p(-t / gamma).sum(dim=(-2, -1)) / (k1 * k2))  # Eq. (9)
    return uism_v, -log_amee


def _uism_funie_torch(x: torch.Tensor, preset: str) -> torch.Tensor:
    import torch

    block = _BLOCK[preset]
    bsz, _, h, w = x.shape
    if h < block or w < block:
        warn_metric(_MSG_TINY.format(h=h, w=w, b=block))
        return x.new_zeros(bsz, dtype=torch.float64)
    gx, gy = _sobel_magnitude_torch(x)
    mag = torch.hypot(gx, gy)
    peak = mag.amax(dim=(-2, -1), keepdim=True)  # (B, 3, 1, 1)
    flat = peak == 0
    flat_channels = flat.flatten(1).any(dim=0).cpu().tolist()
    if any(flat_channels):
        warn_metric(_MSG_FLAT.format(ch=_channel_names(flat_channels), preset=preset))
    scale = torch.where(flat, 0.0, 255.0 / torch.where(flat, 1.0, peak))
    edge = (mag * scale) * x
    mx, mn = block_max_min_torch(edge, block)
    ok = (mn != 0) & (mx != 0)
    ratio = torch.where(ok, mx, 1.0) / torch.where(ok, mn, 1.0)
    eme = _block_weight((h, w), preset, 2.0) * torch.log(ratio.double()).sum(dim=(-2, -1))
    return eme @ torch.tensor(_UISM_WEIGHTS[preset], dtype=torch.float64, device=eme.device)


def _uiconm_funie_torch(x: torch.Tensor, preset: str) -> torch.Tensor:
    import torch

    block = _BLOCK[preset]
    bsz, _, h, w = x.shape
    if h < block or w < block:
        return x.new_zeros(bsz, dtype=torch.float64)
    mx, mn = block_max_min_torch(x, block)
    mx, mn = mx.amax(dim=1), mn.amin(dim=1)
    top, bot = mx - mn, mx + mn
    ok = (top != 0) & (bot != 0)
    c = (torch.where(ok, top, 1.0) / torch.where(ok, bot, 1.0)).double()
    return _block_weight((h, w), preset, -1.0) * (c * torch.log(c)).sum(dim=(-2, -1))
