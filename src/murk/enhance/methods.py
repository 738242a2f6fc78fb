"""The built-in methods that run torch (``post``, ``jointid``, ``lite``, ``udaformer``, ``ursct``), registered
as lazy factories: each declares the options of its method (the signature is the options contract of
:mod:`murk.enhance.options`) and imports its implementation only when called.

So the registry knows every method's name and options without importing torch or a network: an unknown method
or a misspelt option is refused at once (``murk enhance --method jointd`` answers before torch is loaded). Each
factory's signature equals that of the implementation's factory it calls (names, annotations, defaults; pinned
by ``tests/enhance/test_methods.py``). The classical methods (:mod:`murk.enhance.classical`: numpy and OpenCV)
register themselves.

A weights file that is given but missing is reported here, before torch (or ONNX Runtime) is imported, with the
message its loader gives: by the factory, and by each method's preflight, which
:func:`murk.enhance.restorer.check` runs with ``files=True`` (``murk live`` checks its method so before it opens
its source).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

from murk.enhance.choices import (
    DEFAULT_LITE_BLEND,
    DEFAULT_OVERLAP,
    DEFAULT_REFINE,
    DEFAULT_REFINE_GUARD,
    HEMode,
    Policy,
    PostPreset,
    Precision,
)
from murk.enhance.restorer import Restorer, register
from murk.errors import InputFileError
from murk.models.checkpoint_io import checkpoint_file

if TYPE_CHECKING:
    import torch


def _check_weights(checkpoint: str | Path | None, onnx: str | Path | None, *, runs_onnx: bool) -> None:
    """Raise the loader's InputFileError for a given weights file that is not there (``runs_onnx``: a path ending
    in ``.onnx`` runs with ONNX Runtime). Nothing to check when neither is given (the shipped weights) or both
    are (the factory refuses that)."""
    if checkpoint is not None and onnx is not None:
        return
    path = onnx if onnx is not None else checkpoint
    if path is None:
        return
    if runs_onnx and (onnx is not None or str(path).lower().endswith(".onnx")):
        if not Path(path).is_file():
            raise InputFileError(path, "ONNX model not found")
        return
    checkpoint_file(path)


def _network_weights(*, checkpoint: str | Path | None = None, onnx: str | Path | None = None, **_: Any) -> None:
    """Preflight of ``jointid`` and ``lite``: a given checkpoint or ONNX file is there."""
    _check_weights(checkpoint, onnx, runs_onnx=True)


def _baseline_weights(*, checkpoint: str | Path | None = None, onnx: str | Path | None = None, **_: Any) -> None:
    """Preflight of ``udaformer`` and ``ursct``: a given checkpoint is there (an onnx file is refused by the
    factory: these run the torch network)."""
    if onnx is None:
        _check_weights(checkpoint, None, runs_onnx=False)


@register("post")
def post(
    *,
    device: str | torch.device = "cpu",
    preset: PostPreset = "real",
    sigma_px: float | None = None,
    lam: float | None = None,
    he: HEMode | None = None,
    clahe_clip: float | None = None,
    clahe_tiles: int | tuple[int, int] | None = None,
    he_strength: float | None = None,
    temporal: float = 0.0,
) -> Restorer:
    """``post`` (Eq. 9): :func:`murk.enhance.post.make_post`."""
    options = dict(locals())
    from murk.enhance.post import make_post

    return make_post(**options)


@register("jointid", preflight=_network_weights)
def jointid(
    *,
    checkpoint: str | Path | None = None,
    onnx: str | Path | None = None,
    device: str | torch.device = "cpu",
    precision: Precision = "fp32",
    tile: int | None = None,
    overlap: int | None = DEFAULT_OVERLAP,
    trust_checkpoint: bool = False,
    batch: int | None = None,
    compile: bool = False,
    cuda_graph: bool = False,
    refine: float = DEFAULT_REFINE,
    refine_eps: float = 1e-4,
    refine_guard: float = DEFAULT_REFINE_GUARD,
    lite_blend: float = DEFAULT_LITE_BLEND,
) -> Restorer:
    """``jointid`` (the network restores and estimates depth): :func:`murk.enhance.jointid_restorer.create_jointid`."""
    options = dict(locals())
    _network_weights(checkpoint=checkpoint, onnx=onnx)
    from murk.enhance.jointid_restorer import create_jointid

    return create_jointid(**options)


@register("lite", preflight=_network_weights)
def lite(
    *,
    checkpoint: str | Path | None = None,
    onnx: str | Path | None = None,
    device: str | torch.device = "cpu",
    precision: str = "fp32",
    trust_checkpoint: bool = False,
    batch: int | None = None,
    threads: int | None = None,
    temporal: float = 0.0,
    refine: float = 0.0,
    refine_eps: float = 1e-4,
    refine_guard: float = DEFAULT_REFINE_GUARD,
) -> Restorer:
    """``lite`` (the small real-time restorer): :func:`murk.enhance.lite_restorer.create_lite`."""
    options = dict(locals())
    _network_weights(checkpoint=checkpoint, onnx=onnx)
    from murk.enhance.lite_restorer import create_lite

    return create_lite(**options)


@register("udaformer", preflight=_baseline_weights)
def udaformer(
    *,
    checkpoint: str | Path | None = None,
    onnx: str | Path | None = None,
    device: str | torch.device = "cpu",
    precision: str = "fp32",
    policy: Policy = "native",
    tile: int | None = None,
    overlap: int | None = DEFAULT_OVERLAP,
    batch: int | None = None,
    trust_checkpoint: bool = False,
) -> Restorer:
    """``udaformer`` (a comparison baseline): :func:`murk.enhance.udaformer_restorer.create_udaformer`."""
    options = dict(locals())
    _baseline_weights(checkpoint=checkpoint, onnx=onnx)
    from murk.enhance.udaformer_restorer import create_udaformer

    return create_udaformer(**options)


@register("ursct", preflight=_baseline_weights)
def ursct(
    *,
    checkpoint: str | Path | None = None,
    onnx: str | Path | None = None,
    device: str | torch.device = "cpu",
    precision: str = "fp32",
    policy: Policy = "native",
    tile: int | None = None,
    overlap: int | None = DEFAULT_OVERLAP,
    batch: int | None = None,
    trust_checkpoint: bool = False,
) -> Restorer:
    """``ursct`` (a comparison baseline): :func:`murk.enhance.ursct_restorer.create_ursct`."""
    options = dict(locals())
    _baseline_weights(checkpoint=checkpoint, onnx=onnx)
    from murk.enhance.ursct_restorer import create_ursct

    return create_ursct(**options)
