"""The exposure a restoration keeps: one gain per frame that gives the restoration the mean luma of a reference
(the network's input, after the simplest colour balance it takes), torch only (the network restorers' step).

A restorer that learnt from synthetic water estimates the clean scene's colour and its local contrast, and also its
overall brightness. The last is not a property of the water: it is the camera's exposure, and murk's synthetic
truth sets it by the procedural scene's own levels. On the Underwater ImageNet pairs of the development set, whose
references keep their input's exposure, ``lite``'s per-image brightness was further from the references' than the
colour balance's (mean absolute luma error 0.065 against 0.041); on the UIEB pairs the two were alike (0.038 against
0.041; docs/enhance.md, "exposure"). So by default the ``lite`` and ``jointid`` restorers keep the exposure of their
balanced input: the restoration is scaled
by ``k = mean luma(reference) / mean luma(restoration)`` (Rec. 601 luma, the restoration clamped to [0, 1] first),
``k`` bounded to ``[1 / MAX_EXPOSURE_GAIN, MAX_EXPOSURE_GAIN]``. A gain, not an offset: black stays black and the
colour's chromaticity is kept. The affine-fit score of the synthetic evaluation forgives it (one gain per image).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from torch import Tensor

MAX_EXPOSURE_GAIN = 2.0
"""The gain is bounded to [1 / this, this] (a nearly black restoration is not blown up)."""
LUMA_FLOOR = 1e-3
"""The restoration's mean luma is floored at this before the ratio is taken."""
LUMA_601 = (0.299, 0.587, 0.114)
"""Rec. 601 luma weights (those of ``lite``'s guide)."""


def mean_luma_torch(images: Tensor) -> Tensor:
    """The mean Rec. 601 luma of each frame of a batch (B, 3, H, W) -> (B,)."""
    w = images.new_tensor(LUMA_601).view(1, 3, 1, 1)
    return (images * w).sum(dim=1).mean(dim=(1, 2))


def exposure_gain_torch(reference: Tensor, restored: Tensor) -> Tensor:
    """The gain (B,) that gives each frame of ``restored`` (B, 3, H, W; clamped to [0, 1] here) the mean luma of
    the same frame of ``reference`` (B, 3, h, w; any size), bounded to [1 / :data:`MAX_EXPOSURE_GAIN`,
    :data:`MAX_EXPOSURE_GAIN`]."""
    target = mean_luma_torch(reference)
    have = mean_luma_torch(restored.clamp(0.0, 1.0)).clamp(min=LUMA_FLOOR)
    return (target / have).clamp(1.0 / MAX_EXPOSURE_GAIN, MAX_EXPOSURE_GAIN)


def keep_exposure_torch(restored: Tensor, reference: Tensor) -> Tensor:
    """``restored`` (B, 3, H, W) scaled per frame by :func:`exposure_gain_torch` and clamped to [0, 1] (a new
    tensor; neither input is modified)."""
    k = exposure_gain_torch(reference, restored)
    return (restored * k.to(restored.dtype)[:, None, None, None]).clamp(0.0, 1.0)
