"""What the torch twins of murk's OpenCV image operations share (:mod:`murk.enhance.equalize`,
:mod:`murk.enhance.log_filter`): the check of a torch batch and OpenCV's reflect-101 border (``BORDER_REFLECT_101``,
``BORDER_DEFAULT``) for any pad size. torch is imported inside the functions."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from murk.errors import ShapeError

if TYPE_CHECKING:
    import torch


def reflect101_index(n: int, pad_after: int, device: torch.device, pad_before: int = 0) -> torch.Tensor:
    """Source indices of a reflect-101 extension of an axis of length n (any pad size, like OpenCV)."""
    import torch

    i = torch.arange(-pad_before, n + pad_after, device=device)
    if n == 1:
        return torch.zeros_like(i)
    period = 2 * (n - 1)
    i = torch.remainder(i, period)
    return torch.where(i < n, i, period - i)


def pad_reflect101(x: torch.Tensor, r: int) -> torch.Tensor:
    """``x`` (..., H, W) extended by ``r`` pixels on every side, reflect-101 (also when ``r`` >= H or W)."""
    import torch.nn.functional as F

    h, w = x.shape[-2:]
    if h > r and w > r:
        return F.pad(x, (r, r, r, r), mode="reflect")
    return x.index_select(-2, reflect101_index(h, r, x.device, r)).index_select(-1, reflect101_index(w, r, x.device, r))


def check_image_batch(images: Any, channels: int | None) -> None:
    """Raise TypeError unless ``images`` is a float torch tensor, ShapeError unless it is (B, C, H, W) (with
    ``channels`` channels when given)."""
    import torch

    if not isinstance(images, torch.Tensor):
        raise TypeError(f"images: expected a torch tensor (B, C, H, W), got {type(images).__name__}")
    if images.ndim != 4 or (channels is not None and images.shape[1] != channels):
        want = f"(B, {channels}, H, W)" if channels else "(B, C, H, W)"
        raise ShapeError(f"images: expected shape {want}, got {tuple(images.shape)}")
    if not images.is_floating_point():
        raise TypeError(f"images: expected a float tensor in [0, 1], got dtype {images.dtype}")
