"""Depth-dependent forward-scattering blur, Eqs. (2)-(6) of the paper.

The point spread function is a 2-D Gaussian (Eq. 2) whose width grows linearly with distance (Eq. 3):
``sigma(d) = sigma0 + k d`` (paper: sigma0 = 0.5 px, k = 0.15 px/m, the same for all channels). The ideal
result is the spatially varying blur of Eq. (4), where every output pixel uses the PSF of its own distance.

Two modes:

- ``approx`` (the paper's, Eqs. 5-6): blur the whole image once with the largest PSF of the image,
  ``sigma_max = sigma(max d)``, and blend ``I_fs = (1 - a(d)) I + a(d) I_blur`` with
  ``a(d) = 1 - exp(-gamma d)`` (gamma = 0.2 / m: a = 63 % at 5 m).
- ``exact`` (Eq. 4): a stack of blurred copies at the fixed sigma grid ``sigma0 + j * step`` spanning the
  image's sigma range; each pixel interpolates (linearly in variance) between the two grid levels that
  bracket its own sigma. :func:`forward_scatter_reference` is the brute-force per-pixel convolution it is
  tested against.

Discrete kernels: sampled ``exp(-x^2 / (2 sigma^2))`` on integer offsets ``|x| <= ceil(4 sigma)``, normalised
to sum 1 (separable, so the 2-D PSF of Eq. 2 is the outer product and also sums to 1); borders are mirrored
without repeating the edge pixel (OpenCV's BORDER_REFLECT_101, torch's "reflect").

References: the source paper, Sec. IV.4.1 and V.5.1; McGlamery, "A computer model for underwater camera
systems", Proc. SPIE 208, 1980, doi:10.1117/12.958279; Jaffe, "Computer modeling and the design of optimal
underwater imaging systems", IEEE J. Oceanic Eng. 15(2), 1990, doi:10.1109/48.50695.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Literal

import cv2
import numpy as np

if TYPE_CHECKING:
    import torch

FsMode = Literal["approx", "exact"]
TRUNCATE = 4.0
"""Kernel radius in standard deviations: ``radius = ceil(TRUNCATE * sigma)``."""


def sigma_px(dist_m: np.ndarray | float, sigma0_px: float = 0.5, k_px_per_m: float = 0.15) -> np.ndarray | float:
    """PSF standard deviation in pixels at distance ``dist_m``: Eq. (3), ``sigma = sigma0 + k d``."""
    return sigma0_px + k_px_per_m * dist_m  # Eq. (3)


def blend_weight(dist_m: np.ndarray, gamma_per_m: float = 0.2) -> np.ndarray:
    """Blend weight of the blurred image, Eq. (6): ``a(d) = 1 - exp(-gamma d)``, float32."""
    a = np.multiply(dist_m, np.float32(-gamma_per_m), dtype=np.float32)
    cv2.exp(a, a)
    np.subtract(np.float32(1.0), a, out=a)  # Eq. (6)
    return a


def kernel_radius(sigma: float) -> int:
    """Radius of the discrete kernel for ``sigma`` pixels."""
    return max(1, math.ceil(TRUNCATE * float(sigma)))


def gaussian_kernel_1d(sigma: float, radius: int | None = None) -> np.ndarray:
    """Sampled, normalised 1-D Gaussian (float64) on offsets ``-radius..radius``."""
    if not sigma > 0:
        raise ValueError(f"sigma: expected > 0 px, got {sigma}")
    r = kernel_radius(sigma) if radius is None else int(radius)
    x = np.arange(-r, r + 1, dtype=np.float64)
    g = np.exp(-0.5 * (x / sigma) ** 2)
    return g / g.sum()


def psf(sigma: float) -> np.ndarray:
    """The 2-D PSF of Eq. (2) sampled on the pixel grid, (2r+1, 2r+1) float64, summing to 1."""
    g = gaussian_kernel_1d(sigma)
    return np.outer(g, g)  # Eq. (2): separable Gaussian


def gaussian_blur(image: np.ndarray, sigma: float) -> np.ndarray:
    """Blur a float32 (H, W, C) image with the discrete PSF of ``sigma`` pixels (reflect-101 borders)."""
    k = 2 * kernel_radius(sigma) + 1
    return cv2.GaussianBlur(image, (k, k), sigmaX=float(sigma), sigmaY=float(sigma), borderType=cv2.BORDER_REFLECT_101)


def forward_scatter_approx(
    basic: np.ndarray, dist_m: np.ndarray, *, sigma0_px: float = 0.5, k_px_per_m: float = 0.15, gamma_per_m: float = 0.2
) -> tuple[np.ndarray, float]:
    """The paper's approximation of forward scattering, Eqs. (5)-(6). Returns ``(I_fs, sigma_max_px)``.

    ``I_bar`` is ``basic`` blurred with ``sigma_max = sigma(max dist)`` (Eq. 3); then
    ``I_fs = (1 - a) I_basic + a I_bar`` with ``a = 1 - exp(-gamma d)``.
    """
    sigma_max = float(sigma_px(float(dist_m.max()), sigma0_px, k_px_per_m))
    blurred = gaussian_blur(basic, sigma_max)
    a3 = cv2.cvtColor(blend_weight(dist_m, gamma_per_m), cv2.COLOR_GRAY2BGR)  # a(d) on all 3 channels
    cv2.subtract(blurred, basic, blurred)
    cv2.multiply(blurred, a3, blurred)
    cv2.add(blurred, basic, blurred)  # Eq. (5): I + a (I_bar - I)
    return blurred, sigma_max


def sigma_levels(sigma_min: float, sigma_max: float, *, sigma0_px: float, step_px: float) -> np.ndarray:
    """The fixed grid ``sigma0 + j * step`` restricted to the levels that bracket [sigma_min, sigma_max]."""
    if not step_px > 0:
        raise ValueError(f"exact_step_px: expected > 0, got {step_px}")
    j0 = max(0, math.floor((sigma_min - sigma0_px) / step_px + 1e-9))
    j1 = max(j0, math.ceil((sigma_max - sigma0_px) / step_px - 1e-9))
    return sigma0_px + step_px * np.arange(j0, j1 + 1, dtype=np.float64)


def _level_weights(sig: np.ndarray, levels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the lower bracketing level and the weight of the upper one (linear in variance)."""
    n = len(levels)
    if n == 1:
        return np.zeros(sig.shape, np.int64), np.zeros(sig.shape, np.float32)
    lo = np.clip(np.searchsorted(levels, sig, side="right") - 1, 0, n - 2)
    v_lo, v_hi = levels[lo] ** 2, levels[lo + 1] ** 2
    w = np.clip((sig.astype(np.float64) ** 2 - v_lo) / (v_hi - v_lo), 0.0, 1.0)
    return lo, w.astype(np.float32)


def forward_scatter_exact(
    basic: np.ndarray, dist_m: np.ndarray, *, sigma0_px: float = 0.5, k_px_per_m: float = 0.15, step_px: float = 0.25
) -> tuple[np.ndarray, float]:
    """Spatially varying blur of Eq. (4) via a blur stack. Returns ``(I_fs, sigma_max_px)``.

    Every pixel takes the blurred value at its own ``sigma(d)``, interpolated linearly in variance between
    the two levels of the grid ``sigma0 + j * step_px`` that bracket it. The test suite bounds the error
    against :func:`forward_scatter_reference` (see ``docs/synthesis.md``).
    """
    sig = np.asarray(sigma_px(dist_m.astype(np.float64), sigma0_px, k_px_per_m))  # an array for an array
    s_min, s_max = float(sig.min()), float(sig.max())
    levels = sigma_levels(s_min, s_max, sigma0_px=sigma0_px, step_px=step_px)
    lo, w = _level_weights(sig, levels)
    out = np.zeros_like(basic, dtype=np.float32)
    for j, s in enumerate(levels):
        weight = np.where(lo == j, 1.0 - w, 0.0) + np.where(lo == j - 1, w, 0.0)
        if not weight.any():
            continue
        out += gaussian_blur(basic, float(s)) * weight.astype(np.float32)[:, :, None]
    return out, s_max


def forward_scatter_reference(
    basic: np.ndarray, dist_m: np.ndarray, *, sigma0_px: float = 0.5, k_px_per_m: float = 0.15
) -> np.ndarray:
    """Brute-force Eq. (4): every output pixel convolved with the PSF of its own distance (float64).

    O(H W r^2); meant for validation on small images, not for production.
    """
    h, w, _ = basic.shape
    src = basic.astype(np.float64)
    out = np.empty_like(src)
    sig = np.asarray(sigma_px(dist_m.astype(np.float64), sigma0_px, k_px_per_m))  # an array for an array
    for y in range(h):
        for x in range(w):
            g = gaussian_kernel_1d(float(sig[y, x]))
            r = (len(g) - 1) // 2
            ys = _reflect101(np.arange(y - r, y + r + 1), h)
            xs = _reflect101(np.arange(x - r, x + r + 1), w)
            patch = src[np.ix_(ys, xs)]  # (2r+1, 2r+1, 3)
            out[y, x] = np.einsum("i,j,ijc->c", g, g, patch)  # Eq. (4) at pixel (y, x)
    return out


def _reflect101(idx: np.ndarray, n: int) -> np.ndarray:
    """Mirror indices into [0, n) without repeating the edge (period 2(n-1))."""
    if n == 1:
        return np.zeros_like(idx)
    period = 2 * (n - 1)
    q = np.mod(idx, period)
    return np.where(q >= n, period - q, q)


def forward_scatter(
    basic: np.ndarray,
    dist_m: np.ndarray,
    *,
    mode: FsMode = "approx",
    sigma0_px: float = 0.5,
    k_px_per_m: float = 0.15,
    gamma_per_m: float = 0.2,
    step_px: float = 0.25,
) -> tuple[np.ndarray, float]:
    """Forward scattering in the chosen ``mode`` (``approx``: Eqs. 5-6; ``exact``: Eq. 4)."""
    if mode == "approx":
        return forward_scatter_approx(
            basic, dist_m, sigma0_px=sigma0_px, k_px_per_m=k_px_per_m, gamma_per_m=gamma_per_m
        )
    if mode == "exact":
        return forward_scatter_exact(basic, dist_m, sigma0_px=sigma0_px, k_px_per_m=k_px_per_m, step_px=step_px)
    raise ValueError(f"fs_mode: expected 'approx' or 'exact', got {mode!r}")


# ----------------------------------------------------------------------------------------------- torch twin


def _reflect101_torch(n: int, r: int, device: torch.device) -> torch.Tensor:
    import torch

    return torch.from_numpy(_reflect101(np.arange(-r, n + r), n)).to(device)


def gaussian_blur_torch(x: torch.Tensor, sigma: torch.Tensor) -> torch.Tensor:
    """Torch twin of :func:`gaussian_blur` for a batch with one sigma per sample.

    ``x`` (B, C, H, W); ``sigma`` (B,) pixels. Kernels are the same sampled, normalised Gaussians (radius
    ``ceil(4 sigma)``, zero-padded to the batch's largest radius) applied as one grouped separable convolution.
    """
    import torch
    import torch.nn.functional as F

    b, c, h, w = x.shape
    sig = sigma.detach().to("cpu", torch.float64).reshape(-1)
    if sig.numel() != b:
        raise ValueError(f"sigma: expected {b} values (one per sample), got {sig.numel()}")
    radii = [kernel_radius(float(s)) for s in sig]
    r = max(radii)
    taps = torch.zeros(b, 2 * r + 1, dtype=torch.float64)
    for i, (s, ri) in enumerate(zip(sig.tolist(), radii, strict=True)):
        taps[i, r - ri : r + ri + 1] = torch.from_numpy(gaussian_kernel_1d(s, ri))
    k = taps.to(x.device, x.dtype).repeat_interleave(c, dim=0)  # (B*C, K)
    y = x.reshape(1, b * c, h, w)
    y = y.index_select(2, _reflect101_torch(h, r, x.device))
    y = F.conv2d(y, k.view(b * c, 1, -1, 1), groups=b * c)
    y = y.index_select(3, _reflect101_torch(w, r, x.device))
    y = F.conv2d(y, k.view(b * c, 1, 1, -1), groups=b * c)
    return y.view(b, c, h, w)


def forward_scatter_torch(
    basic: torch.Tensor,
    dist_m: torch.Tensor,
    *,
    mode: FsMode = "approx",
    sigma0_px: torch.Tensor | float = 0.5,
    k_px_per_m: torch.Tensor | float = 0.15,
    gamma_per_m: torch.Tensor | float = 0.2,
    step_px: float = 0.25,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Torch twin of :func:`forward_scatter`: basic (B, 3, H, W), dist (B, 1, H, W); per-sample parameters
    as (B,) tensors or scalars. Returns ``(I_fs, sigma_max_px (B,))``."""
    import torch

    b = basic.shape[0]

    def per_sample(v: torch.Tensor | float) -> torch.Tensor:
        return torch.as_tensor(v, dtype=torch.float64).reshape(-1).expand(b).clone()

    s0, k, g = per_sample(sigma0_px), per_sample(k_px_per_m), per_sample(gamma_per_m)
    d_max = dist_m.detach().amax(dim=(1, 2, 3)).to("cpu", torch.float64)
    s_max = s0 + k * d_max  # Eq. (3) at the farthest pixel
    if mode == "approx":
        blurred = gaussian_blur_torch(basic, s_max)
        a = 1.0 - torch.exp(-g.to(dist_m).view(-1, 1, 1, 1) * dist_m)  # Eq. (6)
        return basic + a * (blurred - basic), s_max  # Eq. (5)
    if mode != "exact":
        raise ValueError(f"fs_mode: expected 'approx' or 'exact', got {mode!r}")
    out = torch.empty_like(basic)
    for i in range(b):  # levels differ per sample; each sample is one stack
        sig = (s0[i] + k[i] * dist_m[i : i + 1].double()).to(basic.device)
        levels = sigma_levels(float(sig.min()), float(sig.max()), sigma0_px=float(s0[i]), step_px=step_px)
        lo, w = _level_weights(sig.cpu().numpy(), levels)
        lo_t, w_t = torch.from_numpy(lo).to(basic.device), torch.from_numpy(w).to(basic)
        acc = torch.zeros_like(basic[i : i + 1])
        for j, s in enumerate(levels):
            weight = torch.where(lo_t == j, 1.0 - w_t, 0.0) + torch.where(lo_t == j - 1, w_t, 0.0)
            if bool(weight.any()):
                acc += gaussian_blur_torch(basic[i : i + 1], torch.tensor([s])) * weight
        out[i : i + 1] = acc
    return out, s_max
