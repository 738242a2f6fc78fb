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

Presets and why the default differs from the common codes: ``docs/metrics.md``. The names are imported on first
use, so that :mod:`murk.metrics.table` (the metric table, read by the command line's help) imports no metric.
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
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

_LAZY = {
    "MetricWarning": "_common",
    "affine_fit": "affine_psnr",
    "affine_fit_psnr": "affine_psnr",
    "affine_fit_psnr_torch": "affine_psnr",
    "DEPTH_ERROR_NAMES": "depth",
    "DepthErrors": "depth",
    "DepthErrorsBatch": "depth",
    "depth_errors": "depth",
    "depth_errors_torch": "depth",
    "mean_depth_errors": "depth",
    "FLAG_NAMES": "fidelity",
    "MEASURE_KEYS": "fidelity",
    "ArtefactEnergy": "fidelity",
    "ColourExposure": "fidelity",
    "ParticleCount": "fidelity",
    "StructureFidelity": "fidelity",
    "artefact_energy": "fidelity",
    "artefact_ratio": "fidelity",
    "colour_exposure": "fidelity",
    "count_flags": "fidelity",
    "flags": "fidelity",
    "join_flags": "fidelity",
    "particle_count": "fidelity",
    "restoration_measures": "fidelity",
    "structure_fidelity": "fidelity",
    "SSIMWindow": "reference",
    "ciede2000": "reference",
    "psnr": "reference",
    "psnr_torch": "reference",
    "ssim": "reference",
    "ssim_torch": "reference",
    "pil_bicubic_resize": "resize",
    "UCIQE_PRESETS": "uciqe",
    "UCIQEBatch": "uciqe",
    "UCIQEPreset": "uciqe",
    "UCIQEResult": "uciqe",
    "uciqe": "uciqe",
    "uciqe_torch": "uciqe",
    "UIQM_PRESETS": "uiqm",
    "UIQMBatch": "uiqm",
    "UIQMPreset": "uiqm",
    "UIQMResult": "uiqm",
    "uiqm": "uiqm",
    "uiqm_torch": "uiqm",
}
"""Where each name lives (module of this package)."""

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


class _Package(types.ModuleType):
    """This package: a submodule named like the function it defines (``uiqm``, ``uciqe``) does not take the
    function's name here when it is imported (the function keeps it, as when this file imported them all)."""

    def __setattr__(self, name: str, value: Any) -> None:
        if isinstance(value, types.ModuleType) and _LAZY.get(name) == name:
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(f"murk.metrics.{_LAZY[name]}"), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'murk.metrics' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
