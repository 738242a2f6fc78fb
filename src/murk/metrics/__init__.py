"""Image-quality and depth metrics: UIQM (Eq. (10)), UCIQE, PSNR/SSIM, depth errors, restoration measures.

Every function takes the data range explicitly and returns finite values (a :class:`MetricWarning` says
when a term was undefined and which documented value was used). numpy functions score one image; the
``*_torch`` twins score a (B, 3, H, W) batch on its device and return per-image float64 tensors.

>>> from murk.metrics import uiqm, uciqe
>>> r = uiqm(image_uint8, data_range=255)               # panetta2016 (default)
>>> r.uiqm, r.uicm, r.uism, r.uiconm
>>> uiqm(image_uint8, data_range=255, preset="funie")   # the FUnIE-GAN code's numbers
>>> uciqe(image_float01, data_range=1.0).uciqe          # UCIQE.m semantics (default)
>>> m = restoration_measures(raw01, restored01)          # input-vs-output measures noise cannot fool
>>> flags(m)                                             # e.g. ['artefacts', 'structure loss']

Presets and why the default differs from the common codes: ``docs/metrics.md``.
"""

from murk.metrics._common import MetricWarning
from murk.metrics.affine_psnr import affine_fit, affine_fit_psnr, affine_fit_psnr_torch
from murk.metrics.depth import (
    DEPTH_ERROR_NAMES,
    DepthErrors,
    DepthErrorsBatch,
    depth_errors,
    depth_errors_torch,
    mean_depth_errors,
)
from murk.metrics.fidelity import (
    FLAG_NAMES,
    MEASURE_KEYS,
    ArtefactEnergy,
    ColourExposure,
    ParticleCount,
    StructureFidelity,
    artefact_energy,
    artefact_ratio,
    colour_exposure,
    count_flags,
    flags,
    join_flags,
    particle_count,
    restoration_measures,
    structure_fidelity,
)
from murk.metrics.reference import SSIMWindow, ciede2000, psnr, psnr_torch, ssim, ssim_torch
from murk.metrics.resize import pil_bicubic_resize
from murk.metrics.uciqe import UCIQE_PRESETS, UCIQEBatch, UCIQEPreset, UCIQEResult, uciqe, uciqe_torch
from murk.metrics.uiqm import UIQM_PRESETS, UIQMBatch, UIQMPreset, UIQMResult, uiqm, uiqm_torch

__all__ = [
    "DEPTH_ERROR_NAMES",
    "FLAG_NAMES",
    "MEASURE_KEYS",
    "UCIQE_PRESETS",
    "UIQM_PRESETS",
    "ArtefactEnergy",
    "ColourExposure",
    "DepthErrors",
    "DepthErrorsBatch",
    "MetricWarning",
    "ParticleCount",
    "SSIMWindow",
    "StructureFidelity",
    "UCIQEBatch",
    "UCIQEPreset",
    "UCIQEResult",
    "UIQMBatch",
    "UIQMPreset",
    "UIQMResult",
    "affine_fit",
    "affine_fit_psnr",
    "affine_fit_psnr_torch",
    "artefact_energy",
    "artefact_ratio",
    "ciede2000",
    "colour_exposure",
    "count_flags",
    "depth_errors",
    "depth_errors_torch",
    "flags",
    "join_flags",
    "mean_depth_errors",
    "particle_count",
    "pil_bicubic_resize",
    "psnr",
    "psnr_torch",
    "restoration_measures",
    "ssim",
    "ssim_torch",
    "structure_fidelity",
    "uciqe",
    "uciqe_torch",
    "uiqm",
    "uiqm_torch",
]
