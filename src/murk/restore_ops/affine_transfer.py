"""Locally affine transfer of a restoration onto its input: the restoration's colours with the input's structure.

Under the image formation model (Eq. 1 of the paper), ``I_c = J_c t_c + B_c (1 - t_c)``. The clean image is then
``J_c = a_c I_c + b_c`` per channel, with ``a_c = 1 / t_c`` and ``b_c = -B_c (1 - t_c) / t_c``. Both vary only with
distance, smoothly except at depth edges. This module fits exactly that form to a restoration ``R`` of ``I``.

In every window of ``(2 r + 1)^2`` pixels each channel of ``R`` is fitted by least squares as ``a_c I_c + b_c``:
``a = cov(I, R) / (var(I) + eps)``, ``b = mean(R) - a mean(I)``. The coefficients are box-averaged and applied to
the input: ``out_c = mean(a_c) I_c + mean(b_c)``. This is He, Sun and Tang's guided filter, with the input as the
guide of each channel and the restoration as the filtered image.

The output keeps the input's edges and texture and takes the restoration's colour, level and haze removal. It
drops whatever the restoration does that is not locally affine in the input:
- network artefacts;
- deblurring (forward scattering stays);
- particles taken out (marine snow stays), unless :func:`guard_particle_removal` puts them back.

A large radius approaches one global affine map per channel. A small one approaches the restoration itself.

With ``step`` > 1 the coefficients are fitted on a subsample of the frame and upsampled: He and Sun's fast guided
filter. The subsample is every ``step``-th row and column, starting at the centre of the first ``step`` x ``step``
block (``step`` odd), the window radius is ``radius / step`` there, and the box-averaged coefficients are resized
bilinearly to the frame (half-pixel centres, as OpenCV's and torch's bilinear resizing). Samples and resized grid
coincide when the frame's sides are multiples of ``step``; otherwise they drift apart by less than ``step / 2``
pixels at the far border, which the coefficients, smooth over the window, do not notice. The output is then
``mean(a) I + mean(b)`` at full resolution as before. :func:`transfer_step` picks ``step`` from the radius (at most
an eighth of it), so that each window still holds at least about 17 x 17 samples.

The particle guard (:func:`guard_particle_removal`) keeps the restoration's own output where it took out a
particle. A pixel is guarded where two soft tests (ramps :data:`GUARD_RAMP` wide) both hold:
- the input has a small bright blob there: the luma's white top-hat with a ``size_px`` square (the luma minus its
  morphological opening) exceeds ``threshold``;
- the restoration is darker there than the transfer: ``Y(transfer) - Y(restored)`` > 0, full at the ramp's width.
Each test is grown by one pixel (3x3 maximum), so that a particle's rim goes with it. The output is
``transfer + w (restored - transfer)``, with ``w`` in [0, 1] the product of the two tests.

numpy/OpenCV functions and their torch twins (``*_torch``, batches (B, C, H, W) on any device) sit side by side and
are pinned equal by tests/twins.py. The torch box means come from cumulative sums in float64 over the reflected
frame, as OpenCV's running sums accumulate in double.

References: K. He, J. Sun, X. Tang, "Guided Image Filtering", IEEE TPAMI 35(6), 2013, doi:10.1109/TPAMI.2012.213;
K. He, J. Sun, "Fast Guided Filter", arXiv:1505.00996, 2015.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from torch import Tensor


def _coefficients(guide: np.ndarray, src: np.ndarray, radius: int, eps: float) -> tuple[np.ndarray, np.ndarray]:
    """The box-averaged coefficients ``mean(a)``, ``mean(b)`` of the guided filter (He et al. 2013, Alg. 1): box
    means of side ``2 radius + 1`` (OpenCV's running-sum box filter, reflected borders)."""
    k = (2 * radius + 1, 2 * radius + 1)

    def mean(a: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(a, cv2.CV_32F, k, borderType=cv2.BORDER_REFLECT)

    mi, mp = mean(guide), mean(src)
    var = mean(guide * guide) - mi * mi
    a = (mean(guide * src) - mi * mp) / (var + np.float32(eps))
    b = mp - a * mi
    return mean(a), mean(b)


def guided_filter(guide: np.ndarray, src: np.ndarray, radius: int, eps: float) -> np.ndarray:
    """Guided filter (He et al. 2013, Alg. 1) with box means of side ``2 radius + 1`` (OpenCV's running-sum box
    filter: the cost does not grow with the radius; reflected borders). Element-wise: a grey ``guide`` with a
    grey ``src`` (UDCP's transmission refinement), or (H, W, 3) with (H, W, 3), each channel its own guide."""
    mean_a, mean_b = _coefficients(guide, src, radius, eps)
    return (mean_a * guide + mean_b).astype(np.float32)


GUARD_RAMP = 0.02
"""Luma width (of 1) over which each test of the particle guard goes from 0 to 1."""
GUARD_SIZE = 0.04
"""Side of the guard's top-hat square, as a fraction of the image's long side (:func:`guard_size_px`)."""
_LUMA = np.array([0.2126, 0.7152, 0.0722], np.float32)  # Rec. 709


def transfer_radius_px(height: int, width: int, radius: float) -> int:
    """The window radius in pixels for ``radius`` given as a fraction of the image's long side, at least 1 and
    smaller than the short side."""
    r = round(float(radius) * max(height, width))
    return int(max(1, min(r, min(height, width) - 1)))


def transfer_step(radius_px: int) -> int:
    """The subsampling step of :func:`affine_transfer` for a window radius: the largest odd number at most an
    eighth of the radius, at least 1 (80 px -> 9, 32 -> 3, 15 -> 1)."""
    step = max(1, int(radius_px) // 8)
    return step if step % 2 else step - 1


def _check_transfer(
    shape: tuple[int, ...],
    other: tuple[int, ...],
    radius_px: int,
    eps: float,
    step: int,
    layout: str = "(H, W, 3) arrays",
) -> None:
    """The arguments of :func:`affine_transfer` and its twin; ``shape`` and ``other`` as (H, W, C)."""
    if len(shape) != 3 or shape[-1] != 3 or shape != other:
        raise ValueError(f"image/restored: expected two {layout} of one shape, got {shape}, {other} (as H, W, C)")
    if isinstance(radius_px, bool) or int(radius_px) != radius_px or not 1 <= radius_px <= min(shape[:2]):
        raise ValueError(
            f"radius_px: expected an integer from 1 to the short side ({min(shape[:2])}), got {radius_px!r}"
        )
    if not eps > 0:
        raise ValueError(f"eps: expected > 0, got {eps!r}")
    if isinstance(step, bool) or int(step) != step or step < 1 or step % 2 == 0 or step // 2 >= min(shape[:2]):
        raise ValueError(
            f"step: expected an odd integer >= 1 whose centre sample lies in the frame (step // 2 < "
            f"{min(shape[:2])}), got {step!r}"
        )


def _low_radius(radius_px: int, step: int, low_hw: tuple[int, int]) -> int:
    """The window radius on the subsample: ``radius / step``, at least 1 and below its short side."""
    return int(max(1, min(round(radius_px / step), min(low_hw) - 1)))


def affine_transfer(
    image: np.ndarray, restored: np.ndarray, radius_px: int, eps: float = 1e-4, step: int = 1
) -> np.ndarray:
    """The locally affine transfer (module doc) of ``restored`` onto ``image``, both float (H, W, 3) in [0, 1]:
    :func:`guided_filter` with ``image`` as the guide of each channel; float32 (H, W, 3), not clipped. ``step`` > 1
    fits the coefficients on a subsample (the fast guided filter, module doc; see :func:`transfer_step`).

    Raises:
        ValueError: shapes differ or are not (H, W, 3), ``radius_px`` < 1, ``eps`` <= 0, or ``step`` not odd.
    """
    img = np.asarray(image, np.float32)
    res = np.asarray(restored, np.float32)
    _check_transfer(img.shape, res.shape, radius_px, eps, step)
    if step == 1:
        return guided_filter(img, res, int(radius_px), float(eps))
    c = step // 2
    low_i = np.ascontiguousarray(img[c::step, c::step])
    low_r = np.ascontiguousarray(res[c::step, c::step])
    mean_a, mean_b = _coefficients(low_i, low_r, _low_radius(int(radius_px), step, low_i.shape[:2]), float(eps))
    h, w = img.shape[:2]
    up_a = cv2.resize(mean_a, (w, h), interpolation=cv2.INTER_LINEAR)
    up_b = cv2.resize(mean_b, (w, h), interpolation=cv2.INTER_LINEAR)
    return (up_a * img + up_b).astype(np.float32)


def guard_size_px(height: int, width: int) -> int:
    """The side of the particle guard's top-hat square: :data:`GUARD_SIZE` x the long side, odd, at least 3."""
    return max(3, round(GUARD_SIZE * max(height, width)) | 1)


def _check_guard(
    shapes_ok: bool, layout: str, shapes: tuple[tuple[int, ...], ...], threshold: float, size_px: int
) -> None:
    if not shapes_ok:
        raise ValueError(
            f"image/transfer/restored: expected three {layout} of one shape, got {', '.join(map(str, shapes))}"
        )
    if isinstance(threshold, bool) or not threshold > 0:
        raise ValueError(f"threshold: expected a top-hat luma > 0, got {threshold!r}")
    if isinstance(size_px, bool) or int(size_px) != size_px or size_px < 3 or size_px % 2 == 0:
        raise ValueError(f"size_px: expected an odd integer >= 3, got {size_px!r}")


def guard_particle_removal(
    image: np.ndarray, transfer: np.ndarray, restored: np.ndarray, threshold: float, size_px: int
) -> np.ndarray:
    """The transfer with the restoration's particle removal kept (module doc): float32 (H, W, 3), not clipped.

    ``image`` is the input, ``transfer`` its :func:`affine_transfer`, ``restored`` the restoration, all float
    (H, W, 3). ``threshold``: top-hat luma (of 1) from which the input counts as a particle; ``size_px``: side of
    the top-hat square, odd (particles smaller than it are found).

    Raises:
        ValueError: shapes differ or are not (H, W, 3), ``threshold`` <= 0, or ``size_px`` not odd and >= 3.
    """
    img, tr, res = (np.asarray(a, np.float32) for a in (image, transfer, restored))
    ok = img.ndim == 3 and img.shape[-1] == 3 and img.shape == tr.shape == res.shape
    _check_guard(ok, "(H, W, 3) arrays", (img.shape, tr.shape, res.shape), threshold, size_px)
    grow = np.ones((3, 3), np.uint8)
    luma = _LUMA[None]  # (1, 3): cv2.transform's one-row matrix, one pass over the frame

    def ramp(a: np.ndarray, start: float) -> np.ndarray:  # clip((a - start) / GUARD_RAMP, 0, 1), in place
        a -= np.float32(start)
        a *= np.float32(1.0 / GUARD_RAMP)
        return np.clip(a, 0.0, 1.0, out=a)

    y = cv2.transform(np.ascontiguousarray(img), luma)
    top_hat = cv2.morphologyEx(y, cv2.MORPH_TOPHAT, np.ones((int(size_px), int(size_px)), np.uint8))
    blob = cv2.dilate(ramp(top_hat, float(threshold)), grow)
    change = res - tr
    removed = cv2.dilate(ramp(-cv2.transform(change, luma), 0.0), grow)
    w = blob * removed
    change *= cv2.merge([w, w, w])  # a (H, W, 3) weight: numpy's broadcast of (H, W, 1) is 15x slower here
    change += tr
    return change


# --- torch twins -------------------------------------------------------------------------------------------------


def _box_mean_torch(x: Tensor, radius: int) -> Tensor:
    """Mean over windows of side ``2 radius + 1`` of a batch (B, C, H, W), borders reflected with the edge pixel
    repeated (OpenCV's ``BORDER_REFLECT``; ``radius`` < H and W); float32."""
    import torch

    out = x.double()
    k = 2 * radius + 1
    for dim in (2, 3):
        n = int(out.shape[dim])
        i = torch.arange(-radius, n + radius, device=x.device)
        i = torch.where(i < 0, -i - 1, torch.where(i >= n, 2 * n - i - 1, i))
        c = torch.cumsum(out.index_select(dim, i), dim)
        c = torch.cat([torch.zeros_like(c.narrow(dim, 0, 1)), c], dim)
        out = (c.narrow(dim, k, n) - c.narrow(dim, 0, n)) / k
    return out.float()


def _coefficients_torch(guide: Tensor, src: Tensor, radius: int, eps: float) -> tuple[Tensor, Tensor]:
    """The twin of :func:`_coefficients` for batches (B, C, H, W)."""

    def mean(a: Tensor) -> Tensor:
        return _box_mean_torch(a, radius)

    mi, mp = mean(guide), mean(src)
    var = mean(guide * guide) - mi * mi
    a = (mean(guide * src) - mi * mp) / (var + eps)
    b = mp - a * mi
    return mean(a), mean(b)


def guided_filter_torch(guide: Tensor, src: Tensor, radius: int, eps: float) -> Tensor:
    """The twin of :func:`guided_filter` for batches (B, C, H, W), element-wise per channel."""
    g = guide.float()
    mean_a, mean_b = _coefficients_torch(g, src.float(), radius, eps)
    return mean_a * g + mean_b


def affine_transfer_torch(image: Tensor, restored: Tensor, radius_px: int, eps: float = 1e-4, step: int = 1) -> Tensor:
    """The twin of :func:`affine_transfer` for batches (B, 3, H, W); float32, not clipped.

    Raises:
        ValueError: as :func:`affine_transfer`.
    """
    import torch.nn.functional as F

    if image.ndim != 4 or image.shape != restored.shape:
        raise ValueError(
            f"image/restored: expected two (B, 3, H, W) batches of one shape, got {tuple(image.shape)}, "
            f"{tuple(restored.shape)}"
        )
    _check_transfer(
        (*image.shape[2:], image.shape[1]),
        (*restored.shape[2:], restored.shape[1]),
        radius_px,
        eps,
        step,
        "(B, 3, H, W) batches",
    )
    if step == 1:
        return guided_filter_torch(image, restored, int(radius_px), float(eps))
    img, res = image.float(), restored.float()
    c = step // 2
    low_i, low_r = img[:, :, c::step, c::step], res[:, :, c::step, c::step]
    r = _low_radius(int(radius_px), step, (int(low_i.shape[2]), int(low_i.shape[3])))
    mean_a, mean_b = _coefficients_torch(low_i, low_r, r, float(eps))
    size = (int(img.shape[2]), int(img.shape[3]))
    up_a = F.interpolate(mean_a, size=size, mode="bilinear", align_corners=False)
    up_b = F.interpolate(mean_b, size=size, mode="bilinear", align_corners=False)
    return up_a * img + up_b


def guard_particle_removal_torch(
    image: Tensor, transfer: Tensor, restored: Tensor, threshold: float, size_px: int
) -> Tensor:
    """The twin of :func:`guard_particle_removal` for batches (B, 3, H, W); float32. The morphology ignores what
    lies outside the frame, as OpenCV's default border does.

    Raises:
        ValueError: as :func:`guard_particle_removal`.
    """
    import torch
    import torch.nn.functional as F

    ok = image.ndim == 4 and image.shape[1] == 3 and image.shape == transfer.shape == restored.shape
    shapes = tuple(tuple(a.shape) for a in (image, transfer, restored))
    _check_guard(ok, "(B, 3, H, W) batches", shapes, threshold, size_px)
    luma = torch.from_numpy(_LUMA).to(image.device).view(1, 3, 1, 1)
    img, tr, res = image.float(), transfer.float(), restored.float()

    def grow(a: Tensor, k: int) -> Tensor:  # grey dilation with a k x k square (k odd)
        return F.max_pool2d(a, k, stride=1, padding=k // 2)

    k = int(size_px)
    y = (img * luma).sum(1, keepdim=True)
    opened = grow(-grow(-y, k), k)  # erosion, then dilation
    blob = grow(((y - opened - threshold) / GUARD_RAMP).clamp(0.0, 1.0), 3)
    removed = grow((((tr - res) * luma).sum(1, keepdim=True) / GUARD_RAMP).clamp(0.0, 1.0), 3)
    return tr + blob * removed * (res - tr)
