"""Full-reference metrics: PSNR and SSIM, numpy (scikit-image) and torch twins.

The numpy functions delegate to scikit-image (``skimage.metrics``); the torch twins implement the same
definitions for batches on any device and are pinned to scikit-image by tests. The data range is always
explicit.

SSIM windows (``window``):

- ``"gaussian"`` (default): Wang et al. 2004, an 11x11 Gaussian window with sigma 1.5 and population
  covariances, as MATLAB's ``ssim`` (scikit-image with ``gaussian_weights=True, sigma=1.5,
  use_sample_covariance=False``).
- ``"uniform"``: scikit-image's default, a 7x7 uniform window with sample covariances.

For colour images SSIM is the mean of the per-channel SSIM. Images smaller than the window (e.g. 1x1) have
no full window: SSIM then uses a uniform window of the largest odd size that fits, with population
covariances (for 1x1 that is the luminance term alone), and warns.

References:
    Z. Wang, A. C. Bovik, H. R. Sheikh, E. P. Simoncelli, "Image Quality Assessment: From Error Visibility to
    Structural Similarity", IEEE Trans. Image Process. 13(4):600-612, 2004, doi:10.1109/TIP.2003.819861.
    S. van der Walt et al., "scikit-image: image processing in Python", PeerJ 2:e453, 2014,
    doi:10.7717/peerj.453.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from murk.errors import ShapeError
from murk.metrics._common import check_choice, check_data_range, check_real_array, warn_metric

if TYPE_CHECKING:
    import torch

SSIMWindow = Literal["gaussian", "uniform"]
SSIM_WINDOWS: tuple[str, ...] = ("gaussian", "uniform")
_GAUSS_SIGMA = 1.5
_GAUSS_RADIUS = 5  # int(3.5 * 1.5 + 0.5): scipy's truncate = 3.5 -> 11x11 window
_UNIFORM_SIZE = 7
_K1, _K2 = 0.01, 0.03

_MSG_SMALL = "image {h}x{w} is smaller than the {size}x{size} SSIM window: a {fit}x{fit} uniform window is used"


def _check_pair_numpy(pred: Any, ref: Any) -> tuple[np.ndarray, np.ndarray]:
    for name, a in (("pred", pred), ("ref", ref)):
        check_real_array(name, a, "(H, W, C) or (H, W)")
        if a.ndim not in (2, 3) or a.size == 0:
            raise ShapeError(f"{name}: expected shape (H, W, C) or (H, W), got {a.shape}")
    if pred.shape != ref.shape:
        raise ShapeError(f"pred: expected the shape of ref {ref.shape}, got {pred.shape}")
    return pred, ref


def psnr(pred: np.ndarray, ref: np.ndarray, *, data_range: float) -> float:
    """Peak signal-to-noise ratio in dB, ``10 log10(data_range^2 / MSE)`` (scikit-image).

    Args:
        pred: image (H, W, C) or (H, W), integer or float.
        ref: reference image of the same shape.
        data_range: the value of full white (255 for uint8-scaled input, 1.0 for [0, 1]); required.

    Returns:
        PSNR in dB; ``inf`` when ``pred`` equals ``ref`` (MSE = 0).

    Raises:
        TypeError: not numpy arrays of a real dtype, or a bad ``data_range`` type.
        ShapeError: shapes differ or are not 2-D/3-D.
        ValueError: ``data_range`` not a finite number > 0.
    """
    from skimage.metrics import peak_signal_noise_ratio

    data_range = check_data_range(data_range)
    pred, ref = _check_pair_numpy(pred, ref)
    if np.array_equal(pred, ref):
        return math.inf
    return float(peak_signal_noise_ratio(ref.astype(np.float64), pred.astype(np.float64), data_range=data_range))


def ssim(pred: np.ndarray, ref: np.ndarray, *, data_range: float, window: SSIMWindow = "gaussian") -> float:
    """Structural similarity (Wang et al. 2004) by scikit-image; mean over channels for colour images.

    Args:
        pred: image (H, W, C) or (H, W), integer or float.
        ref: reference image of the same shape.
        data_range: the value of full white (255 for uint8-scaled input, 1.0 for [0, 1]); required.
        window: ``"gaussian"`` (11x11, sigma 1.5, population covariances; default) or ``"uniform"`` (7x7,
            sample covariances; scikit-image's default). See the module docstring.

    Returns:
        SSIM in [-1, 1]; 1.0 when ``pred`` equals ``ref`` (the formula gives exactly 1 there).

    Raises:
        TypeError, ShapeError, ValueError: as :func:`psnr`; ``window`` not one of the options.

    Warns:
        MetricWarning: the image is smaller than the window (a smaller uniform window is used).
    """
    from skimage.metrics import structural_similarity

    window = check_choice("window", window, SSIM_WINDOWS)  # type: ignore[assignment]
    data_range = check_data_range(data_range)
    pred, ref = _check_pair_numpy(pred, ref)
    h, w = ref.shape[:2]
    size = 2 * _GAUSS_RADIUS + 1 if window == "gaussian" else _UNIFORM_SIZE
    kwargs: dict[str, Any]
    if min(h, w) < size:
        fit = _largest_odd(min(h, w))
        warn_metric(_MSG_SMALL.format(h=h, w=w, size=size, fit=fit))
        kwargs = {"win_size": fit, "gaussian_weights": False, "use_sample_covariance": False}
    elif window == "gaussian":
        kwargs = {"gaussian_weights": True, "sigma": _GAUSS_SIGMA, "use_sample_covariance": False}
    else:
        kwargs = {"win_size": _UNIFORM_SIZE, "gaussian_weights": False, "use_sample_covariance": True}
    channel_axis = -1 if ref.ndim == 3 else None
    value = structural_similarity(
        ref.astype(np.float64), pred.astype(np.float64), data_range=data_range, channel_axis=channel_axis, **kwargs
    )
    return float(value)


def ciede2000(pred: np.ndarray, ref: np.ndarray, *, data_range: float) -> float:
    """Mean CIEDE2000 colour difference (Sharma, Wu, Dalal, Color Res. Appl. 30(1), 2005,
    doi:10.1002/col.20070) between two sRGB images (H, W, 3), both converted to CIE L*a*b* (D65) by
    scikit-image (``rgb2lab``, ``deltaE_ciede2000``); lower is better, 0 for identical colours.

    Raises:
        ShapeError: the images are not (H, W, 3) of one shape.
    """
    from skimage.color import deltaE_ciede2000, rgb2lab

    pred, ref = _check_pair_numpy(pred, ref)
    if ref.ndim != 3 or ref.shape[2] != 3:
        raise ShapeError(f"ref: expected an RGB image (H, W, 3) for CIEDE2000, got {ref.shape}")
    data_range = check_data_range(data_range)
    a = np.clip(pred.astype(np.float64) / data_range, 0.0, 1.0)
    b = np.clip(ref.astype(np.float64) / data_range, 0.0, 1.0)
    return float(np.mean(deltaE_ciede2000(rgb2lab(b), rgb2lab(a))))


def _largest_odd(n: int) -> int:
    return n if n % 2 == 1 else n - 1


# ----------------------------------------------------------------------------------------------------------
# torch twins


def _check_pair_torch(pred: Any, ref: Any) -> tuple[torch.Tensor, torch.Tensor]:
    import torch

    for name, a in (("pred", pred), ("ref", ref)):
        if not isinstance(a, torch.Tensor):
            raise TypeError(f"{name}: expected a torch.Tensor of shape (B, C, H, W), got {type(a).__name__}")
        if a.dtype == torch.bool or a.is_complex():
            raise TypeError(f"{name}: expected an integer or float tensor, got dtype {a.dtype}")
        if a.ndim != 4 or a.numel() == 0:
            raise ShapeError(f"{name}: expected shape (B, C, H, W), got {tuple(a.shape)}")
    if pred.shape != ref.shape:
        raise ShapeError(f"pred: expected the shape of ref {tuple(ref.shape)}, got {tuple(pred.shape)}")
    return pred.detach().double(), ref.detach().double()


def psnr_torch(pred: torch.Tensor, ref: torch.Tensor, *, data_range: float) -> torch.Tensor:
    """Per-image PSNR in dB of (B, C, H, W) batches: float64 tensor (B,), ``inf`` where an image is exact.

    Twin of :func:`psnr` (same definition; pinned to scikit-image by tests).
    """
    import torch

    data_range = check_data_range(data_range)
    x, y = _check_pair_torch(pred, ref)
    mse = ((x - y) ** 2).flatten(1).mean(dim=1)
    safe = torch.where(mse > 0, mse, 1.0)
    return torch.where(mse > 0, 10.0 * torch.log10(data_range**2 / safe), math.inf)


def _filter_valid(x: torch.Tensor, kernel: torch.Tensor) -> torch.Tensor:
    """Separable 'valid' filtering of (N, H, W) with a 1-D kernel along both axes, by shifted sums."""
    r = kernel.numel()
    h, w = x.shape[-2:]
    acc = kernel[0] * x[..., :, : w - r + 1]
    for i in range(1, r):
        acc = acc + kernel[i] * x[..., :, i : w - r + 1 + i]
    out = kernel[0] * acc[..., : h - r + 1, :]
    for i in range(1, r):
        out = out + kernel[i] * acc[..., i : h - r + 1 + i, :]
    return out


def ssim_torch(
    pred: torch.Tensor, ref: torch.Tensor, *, data_range: float, window: SSIMWindow = "gaussian"
) -> torch.Tensor:
    """Per-image SSIM of (B, C, H, W) batches: float64 tensor (B,), mean over channels.

    Twin of :func:`ssim` (same windows and small-image rule); computed in float64 with elementwise shifted
    sums (no convolution, so no TF32), equal to scikit-image to ~1e-12.

    Raises:
        TypeError, ShapeError, ValueError: as :func:`ssim`, for (B, C, H, W) tensors.
    """
    import torch

    window = check_choice("window", window, SSIM_WINDOWS)  # type: ignore[assignment]
    data_range = check_data_range(data_range)
    x, y = _check_pair_torch(pred, ref)
    bsz, ch, h, w = x.shape
    size = 2 * _GAUSS_RADIUS + 1 if window == "gaussian" else _UNIFORM_SIZE
    if min(h, w) < size:
        fit = _largest_odd(min(h, w))
        warn_metric(_MSG_SMALL.format(h=h, w=w, size=size, fit=fit))
        kernel = torch.full((fit,), 1.0 / fit, dtype=torch.float64, device=x.device)
        cov_norm = 1.0
    elif window == "gaussian":
        t = torch.arange(-_GAUSS_RADIUS, _GAUSS_RADIUS + 1, dtype=torch.float64, device=x.device)
        kernel = torch.exp(-0.5 * (t / _GAUSS_SIGMA) ** 2)
        kernel = kernel / kernel.sum()
        cov_norm = 1.0
    else:
        kernel = torch.full((size,), 1.0 / size, dtype=torch.float64, device=x.device)
        n = size * size
        cov_norm = n / (n - 1.0)
    x = x.reshape(bsz * ch, h, w)
    y = y.reshape(bsz * ch, h, w)
    ux, uy = _filter_valid(x, kernel), _filter_valid(y, kernel)
    uxx, uyy, uxy = _filter_valid(x * x, kernel), _filter_valid(y * y, kernel), _filter_valid(x * y, kernel)
    vx = cov_norm * (uxx - ux * ux)
    vy = cov_norm * (uyy - uy * uy)
    vxy = cov_norm * (uxy - ux * uy)
    c1, c2 = (_K1 * data_range) ** 2, (_K2 * data_range) ** 2
    s = ((2 * ux * uy + c1) * (2 * vxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))
    return s.flatten(1).mean(dim=1).reshape(bsz, ch).mean(dim=1)
