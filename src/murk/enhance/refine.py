"""The ``refine`` step of the network restorers (``jointid``, ``lite``): the restoration re-expressed as a locally
affine map of its input, with the particle guard (:mod:`murk.restore_ops.affine_transfer`).

:class:`RefineSettings` holds the three options; :func:`refine_restoration` applies them to a batch, with the
coefficients fitted on a subsample (the fast guided filter, :func:`murk.restore_ops.affine_transfer.transfer_step`). On
the CPU it runs the OpenCV functions frame by frame; on another device the torch twins, on the device (equal,
tests/twins.py). Figures and the trade-off: docs/enhance.md, "`jointid?refine`".
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from murk.enhance.choices import DEFAULT_REFINE_GUARD


@dataclass(frozen=True)
class RefineSettings:
    """``radius``: the transfer's window radius as a fraction of the long side, in [0, 1] (0: off); ``eps``: its
    regulariser (> 0); ``guard``: the top-hat luma from which the restoration's particle removal is kept, in
    [0, 1) (0: no guard). Errors name the options as the restorers spell them."""

    radius: float = 0.0
    eps: float = 1e-4
    guard: float = DEFAULT_REFINE_GUARD

    def __post_init__(self) -> None:
        if isinstance(self.radius, bool) or not 0.0 <= float(self.radius) <= 1.0:
            raise ValueError(f"refine: expected a fraction of the long side in [0, 1] (0 = off), got {self.radius!r}")
        if isinstance(self.eps, bool) or not float(self.eps) > 0:
            raise ValueError(f"refine_eps: expected > 0, got {self.eps!r}")
        if isinstance(self.guard, bool) or not 0.0 <= float(self.guard) < 1.0:
            raise ValueError(f"refine_guard: expected a top-hat luma in [0, 1) (0 = off), got {self.guard!r}")

    @property
    def on(self) -> bool:
        return self.radius > 0


def refine_restoration(images: Tensor, enhanced: Tensor, settings: RefineSettings) -> Tensor:
    """The transfer of each restoration in ``enhanced`` (B, 3, H, W) onto its input in ``images`` (same shape, any
    device), with the guard; float32 in [0, 1] on ``enhanced``'s device, in channels-last memory on the CPU (what a
    numpy frame converts to without a copy). ``enhanced`` itself when off; neither input is modified."""
    from murk.restore_ops import affine_transfer as at

    if not settings.on:
        return enhanced
    h, w = int(images.shape[-2]), int(images.shape[-1])
    radius, size = at.transfer_radius_px(h, w, settings.radius), at.guard_size_px(h, w)
    step = at.transfer_step(radius)  # the fast guided filter: coefficients fitted on a subsample
    if enhanced.device.type != "cpu":
        src = images.to(enhanced.device, torch.float32)
        out = at.affine_transfer_torch(src, enhanced, radius, settings.eps, step)
        if settings.guard > 0:
            out = at.guard_particle_removal_torch(src, out, enhanced, settings.guard, size)
        return out.clamp_(0.0, 1.0).contiguous()
    outs = []
    for src, res in zip(images.float().cpu(), enhanced.float(), strict=True):
        # (H, W, 3) arrays in C order once: OpenCV would copy a strided view at every call
        i_hwc = np.ascontiguousarray(src.permute(1, 2, 0).numpy())
        r_hwc = np.ascontiguousarray(res.permute(1, 2, 0).numpy())
        hwc = at.affine_transfer(i_hwc, r_hwc, radius, settings.eps, step)
        if settings.guard > 0:
            hwc = at.guard_particle_removal(i_hwc, hwc, r_hwc, settings.guard, size)
        outs.append(torch.from_numpy(np.clip(hwc, 0.0, 1.0, out=hwc)).permute(2, 0, 1))
    if len(outs) == 1:  # channels-last memory, as a numpy frame is: no copy
        return outs[0][None]
    return torch.stack(outs).contiguous(memory_format=torch.channels_last)
