"""murk: underwater robots seeing construction sites through murky water.

Realistic synthetic underwater data (Jerlov absorption and backscatter, depth-dependent forward scattering,
marine snow cut from real footage), Joint-ID restoration with HE + LoG post-processing, and underwater image
quality metrics that reproduce the published codebases.

Source paper: Yun, Yang, Lee, Park, Choi, Cho, "Robust Image Processing Techniques for Construction
Environment Monitoring Using Underwater Robots".

The main operations are re-exported here and imported on first use, so ``import murk`` stays fast.
"""

from __future__ import annotations

import importlib
from typing import Any

from murk._perf import prefer_passive_openmp, tune_allocator
from murk._version import __version__

_LAZY = {
    # synthesis
    "synthesize": "murk.synth.render",
    "render": "murk.synth.render",
    "render_batch_torch": "murk.synth.render",
    "sample_variant": "murk.synth.params",
    "SynthConfig": "murk.synth.config",
    "run_synthesis": "murk.synth.runner",
    # marine snow
    "extract_particles": "murk.snow.extract",
    "load_bank": "murk.snow.bank",
    "save_bank": "murk.snow.bank",
    "composite_snow": "murk.snow.composite",
    # procedural scenes
    "sample_scene": "murk.scenes",
    "render_scene": "murk.scenes",
    "write_scenes": "murk.scenes.dataset",
    # metrics
    "uiqm": "murk.metrics",
    "uciqe": "murk.metrics",
    "psnr": "murk.metrics",
    "ssim": "murk.metrics",
    "depth_errors": "murk.metrics",
    "restoration_measures": "murk.metrics",
    # restoration
    "post_process": "murk.enhance.post",
    "create_restorer": "murk.enhance.restorer",
    "restorer_options": "murk.enhance.restorer",
    "build_jointid": "murk.models.jointid",
    "load_checkpoint": "murk.models.jointid",
    "save_checkpoint": "murk.models.jointid",
    "shipped_jointid_weights": "murk.data",
    "load_udaformer": "murk.models.udaformer",
    "load_ursct": "murk.models.ursct_sesr",
    # training and evaluation
    "TrainConfig": "murk.train.config",
    "train": "murk.train.loop",
    "run_compare": "murk.report.compare",
    "run_study": "murk.report.study",
    # io
    "read_rgb": "murk.io",
    "write_rgb": "murk.io",
    "read_depth": "murk.io",
}

__all__ = ["__version__", "prefer_passive_openmp", "tune_allocator", *_LAZY]


_RENAMED = {"create_restorer": "create", "restorer_options": "options_of"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), _RENAMED.get(name, name))
        globals()[name] = value
        return value
    raise AttributeError(f"module 'murk' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
