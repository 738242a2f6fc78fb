"""Image-quality and depth metrics: UIQM (Eq. (10)), UCIQE, PSNR/SSIM and depth errors.

Every function takes the data range explicitly and returns finite values (a :class:`MetricWarning` says
when a term was undefined and which documented value was used). numpy functions score one image; the
``*_torch`` twins score a (B, 3, H, W) batch on its device and return per-image float64 tensors.

>>> from murk.metrics import uiqm, uciqe
>>> r = uiqm(image_uint8, data_range=255)               # panetta2016 (default)
>>> r.uiqm, r.uicm, r.uism, r.uiconm
>>> uiqm(image_uint8, data_range=255, preset="funie")   # the FUnIE-GAN code's numbers
>>> uciqe(image_float01, data_range=1.0).uciqe          # UCIQE.m semantics (default)

Presets and why the default differs from the common codes: ``docs/metrics.md``.
"""

from murk.metrics._common import MetricWarning
from murk.metrics.depth import (
    DEPTH_ERROR_NAMES,
    DepthErrors,
    DepthErrorsBatch,
    depth_errors,
    depth_errors_torch,
    mean_depth_errors,
)
from murk.metrics.reference import SSIMWindow, psnr, psnr_torch, ssim, ssim_torch
from murk.metrics.resize import pil_bicubic_resize
from murk.metrics.uciqe import UCIQE_PRESETS, UCIQEBatch, UCIQEPreset, UCIQEResult, uciqe, uciqe_torch
from murk.metrics.uiqm import UIQM_PRESETS, UIQMBatch, UIQMPreset, UIQMResult, uiqm, uiqm_torch

__all__ = [
    "DEPTH_ERROR_NAMES",
    "UCIQE_PRESETS",
    "UIQM_PRESETS",
    "DepthErrors",
    "DepthErrorsBatch",
    "MetricWarning",
    "SSIMWindow",
    "UCIQEBatch",
    "UCIQEPreset",
    "UCIQEResult",
    "UIQMBatch",
    "UIQMPreset",
    "UIQMResult",
    "depth_errors",
    "depth_errors_torch",
    "mean_depth_errors",
    "pil_bicubic_resize",
    "psnr",
    "psnr_torch",
    "ssim",
    "ssim_torch",
    "uciqe",
    "uciqe_torch",
    "uiqm",
    "uiqm_torch",
]
