"""Every built-in restoration method, declared once (:class:`murk.enhance.declare.Method`): its name, its options
(types, ranges, defaults, one line of help each), what it needs and the import path of its implementation.

The registry (:mod:`murk.enhance.restorer`) registers :data:`BUILTIN` on first use; ``murk enhance --help``
(:func:`methods_help`), ``murk live``'s method menu, the options table of docs/enhance.md (:func:`options_table`,
pinned by ``tests/enhance/test_methods.py``) and the spec checker read the same declarations. This module imports
only the standard library and :mod:`murk.enhance.choices`: an unknown method or a misspelt option is refused before
torch, OpenCV or a network is loaded (``murk enhance --method jointd`` answers at once).

A weights file that is given but missing is reported before torch (or ONNX Runtime) is imported, with the message
its loader gives, by each network method's preflight (run before its implementation is imported, and by
:func:`murk.enhance.restorer.check` with ``files=True``: ``murk live`` checks its method so before it opens its
source).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from murk.enhance.choices import (
    DEFAULT_DEPTH_AREA_PX,
    DEFAULT_LITE_BLEND,
    DEFAULT_OVERLAP,
    DEFAULT_REFINE,
    DEFAULT_REFINE_GUARD,
)
from murk.enhance.declare import NEEDS, Method, Need, Option, Preset, opt
from murk.enhance.spec import names, parse_method


def _check_weights(checkpoint: str | Path | None, onnx: str | Path | None, *, runs_onnx: bool) -> None:
    """Raise the loader's InputFileError for a given weights file that is not there (``runs_onnx``: a path ending
    in ``.onnx`` runs with ONNX Runtime). Nothing to check when neither is given (the shipped weights) or both
    are (the implementation refuses that)."""
    from murk.errors import InputFileError
    from murk.models.checkpoint_io import checkpoint_file

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


def weights_file(
    checkpoint: str | Path | None, onnx: str | Path | None, shipped: Callable[[], Path], missing: str
) -> str | Path:
    """The weights file ``jointid`` and ``lite`` load: ``onnx``, else ``checkpoint`` (as given), else the file
    murk ships (``shipped()``).

    Raises:
        ValueError: both ``checkpoint`` and ``onnx`` given, or neither and the shipped file is missing (``missing``
            says so; ``{path}`` in it is replaced by the shipped file's path).
    """
    if checkpoint is not None and onnx is not None:
        raise ValueError("checkpoint/onnx: give one of them, not both")
    if onnx is not None:
        return onnx
    if checkpoint is not None:
        return checkpoint
    path = shipped()
    if not path.is_file():
        raise ValueError(missing.format(path=path))
    return path


def network_weights(*, checkpoint: str | Path | None = None, onnx: str | Path | None = None, **_: Any) -> None:
    """Preflight of ``jointid`` and ``lite``: a given checkpoint or ONNX file is there."""
    _check_weights(checkpoint, onnx, runs_onnx=True)


def baseline_weights(*, checkpoint: str | Path | None = None, onnx: str | Path | None = None, **_: Any) -> None:
    """Preflight of ``udaformer`` and ``ursct``: a given checkpoint is there (an onnx file is refused by the
    implementation: these run the torch network)."""
    if onnx is None:
        _check_weights(checkpoint, None, runs_onnx=False)


def detail_weights(*, weights: str | Path | None = None, **_: Any) -> None:
    """Preflight of ``detail``: a given weights file is there."""
    from murk.errors import InputFileError

    if weights is not None and not Path(weights).is_file():
        raise InputFileError(weights, "detail network weights not found")


def water_weights(*, estimator: str | Path | None = None, **_: Any) -> None:
    """Preflight of ``water``: a given estimator file is there."""
    from murk.errors import InputFileError

    if estimator is not None and not Path(estimator).is_file():
        raise InputFileError(estimator, "water estimator weights not found")


# ----------------------------------------------------------------------------- options several methods share

DEVICE = opt("device", "str | torch.device", "cpu", "where it runs: cpu, cuda or cuda:N")
CHECKPOINT = opt(
    "checkpoint", "str | Path | None", None, "weights file (.pt/.pth; .onnx runs with ONNX Runtime); default: shipped"
)
ONNX = opt("onnx", "str | Path | None", None, "an .onnx export to run with ONNX Runtime (instead of checkpoint)")
PRECISION = opt("precision", "Precision", "fp32", "arithmetic: fp32, or bf16/fp16 autocast")
TILE = opt("tile", "int | None", None, "tile side in pixels for large frames (None or 0: whole frames)", low=0)
OVERLAP = opt("overlap", "int | None", DEFAULT_OVERLAP, "overlap of neighbouring tiles in pixels", low=0)
TRUST = opt("trust_checkpoint", "bool", False, "read a checkpoint that pickles more than weights (a flag only)")
BATCH = opt("batch", "int | None", None, "at most this many frames (or tiles) per forward pass", low=1)
TEMPORAL = opt("temporal", "float", 0.0, "weight in [0, 1) of the past frames in a video's average (0: off)", low=0)
REFINE_EPS = opt("refine_eps", "float", 1e-4, "the affine transfer's regulariser (> 0)")
REFINE_GUARD = opt(
    "refine_guard",
    "float",
    DEFAULT_REFINE_GUARD,
    "top-hat luma in [0, 1) from which a removed particle is kept (0: off)",
)

EXPOSURE = opt(
    "exposure",
    "Exposure | None",
    None,
    "input: keep the balanced input's mean luma; network: the network's own (None: input; an .onnx: as it records)",
)

DEPTH_AREA = opt(
    "depth_area",
    "int",
    DEFAULT_DEPTH_AREA_PX,
    "depth of a frame of over twice this many pixels from a pass at about this area (0: the frame's own pass)",
    low=0,
)


def _refine(default: float) -> Option:
    return opt("refine", "float", default, "affine transfer onto the input: window radius / long side (0: off)", low=0)


NETWORK: tuple[Need, ...] = ("torch", "weights", "onnxruntime")
BASELINE_OPTIONS = (
    opt("checkpoint", "str | Path | None", None, "the weights file (required; murk ships none, docs/baselines.md)"),
    opt("onnx", "str | Path | None", None, "refused: the baselines run the torch network"),
    DEVICE,
    opt("precision", "str", "fp32", "arithmetic: fp32, or bf16/fp16 autocast"),
    opt("policy", "Policy", "native", "native (any size, tiles) or official (the published 256x256 test script)"),
    TILE,
    OVERLAP,
    BATCH,
    TRUST,
)


def _classical(name: str, help: str, *options: Option) -> Method:
    """A method of :mod:`murk.enhance.classical` (numpy and OpenCV; implemented by ``make_<name>``)."""
    return Method(name, f"murk.enhance.classical:make_{name}", options, help=help)


# ---------------------------------------------------------------------------------------------- the methods

CLASSICAL: tuple[Method, ...] = (
    _classical("greyworld", "grey-world white balance (Buchsbaum 1980)",
               opt("strength", "float", 1.0, "share of the grey-world gains applied (0: none)", low=0, high=1)),
    _classical("colorbalance", "simplest colour balance (Limare et al. 2011)",
               opt("low", "float", 1.0, "per cent of each channel's pixels saturated to 0", low=0, high=49),
               opt("high", "float", 1.0, "per cent of each channel's pixels saturated to 1", low=0, high=49)),
    _classical("clahe", "CLAHE of CIE L* (a*, b* kept)",
               opt("clip", "float", 2.0, "OpenCV's clip limit (> 0)"),
               opt("tiles", "int", 8, "tiles per side, 1-64", low=1, high=64)),
    _classical("udcp", "Underwater Dark Channel Prior (Drews et al. 2013)",
               opt("patch", "int", 15, "dark-channel window in pixels, 1-255", low=1, high=255),
               opt("omega", "float", 0.95, "share of the haze removed", low=0, high=1),
               opt("t_min", "float", 0.1, "floor of the transmission", low=1e-3, high=1)),
    _classical("desnow", "marine snow taken out: small bright particles replaced by the background around them",
               opt("threshold", "float", 0.1, "contrast that makes a blob snow, as a share of the frame's luma spread",
                   low=1e-3, high=0.99),
               opt("size", "float", 0.03, "largest particle's diameter, share of the long side", low=1e-3, high=0.25),
               opt("max_elongation", "float", 3.0, "longest particle, in widths (longer: a cable, an edge)", low=1),
               opt("crowd", "float", 0.05, "largest share of its surroundings that bright blobs may cover",
                   low=1e-3, high=1)),
)  # fmt: skip
"""The classical methods (numpy and OpenCV, never torch)."""

BUILTIN: tuple[Method | Preset, ...] = (
    *CLASSICAL,
    Method(
        "post",
        "murk.enhance.post:make_post",
        (
            DEVICE,
            opt("preset", "PostPreset", "real", "real (30 % of the equalisation, lambda 0.1) or paper (Eq. 9 exactly)"),
            opt("sigma_px", "float | None", None, "LoG sigma in pixels (default: the preset's)", low=0),
            opt("lam", "float | None", None, "edge-enhancement weight lambda (default: the preset's)", low=0),
            opt("he", "HEMode | None", None, "equalise luma (y), each channel (rgb) or CLAHE on luma"),
            opt("clahe_clip", "float | None", None, "CLAHE clip limit (he=clahe)"),
            opt("clahe_tiles", "int | tuple[int, int] | None", None, "CLAHE tiles: per side, or (columns, rows)"),
            opt("he_strength", "float | None", None, "share of the equalisation applied (default: the preset's)"),
            TEMPORAL,
        ),
        help="histogram equalisation + LoG edge enhancement (Eq. 9; torch only on CUDA)",
    ),
    Method(
        "jointid_net",
        "murk.enhance.jointid_restorer:create_jointid",
        (
            CHECKPOINT,
            ONNX,
            DEVICE,
            PRECISION,
            TILE,
            OVERLAP,
            TRUST,
            BATCH,
            opt("compile", "bool", False, "torch.compile the network (GPU; slow first frames)"),
            opt("cuda_graph", "bool", False, "replay a CUDA graph per frame size (CUDA; fixed-size video)"),
            _refine(DEFAULT_REFINE),
            REFINE_EPS,
            REFINE_GUARD,
            EXPOSURE,
            DEPTH_AREA,
        ),
        help="Joint-ID alone: restoration (with refine) and metric depth (shipped weights)",
        needs=NETWORK,
        preflight="murk.enhance.methods:network_weights",
    ),
    Preset(
        "jointid",
        "jointid_net|lite@lite_blend",
        (opt("lite_blend", "float", DEFAULT_LITE_BLEND, "weight of lite's restoration averaged in", low=0, high=1),),
        help="Joint-ID: restoration and metric depth (shipped weights; lite blended in)",
        passes=("device", "exposure"),
    ),
    Method(
        "lite",
        "murk.enhance.lite_restorer:create_lite",
        (
            CHECKPOINT,
            ONNX,
            DEVICE,
            opt("precision", "str", "fp32", "fp32 only"),
            TRUST,
            BATCH,
            opt("threads", "int | None", None, "ONNX Runtime's intra-op threads", low=1),
            TEMPORAL,
            _refine(0.0),
            REFINE_EPS,
            REFINE_GUARD,
            EXPOSURE,
        ),
        help="the small real-time restorer (shipped weights; murk's default)",
        needs=NETWORK,
        preflight="murk.enhance.methods:network_weights",
    ),
    Method(
        "water",
        "murk.enhance.water_restorer:create_water",
        (
            opt(
                "base", "str", "jointid", "the method that gives the distance map and the colour (jointid, jointid_net)"
            ),
            opt(
                "strength",
                "float",
                0.25,
                "share of Eq. (1)'s inversion applied (0: the base's colour only)",
                low=0,
                high=1,
            ),
            opt("t_min", "float", 0.1, "floor of the transmission exp(-a d) in the inversion", low=1e-3, high=1),
            opt("estimator", "str | Path | None", None, "water estimator weights (.npz); default: shipped"),
            DEVICE,
            EXPOSURE,
            DEPTH_AREA,
        ),
        help="Eq. (1) inverted with the estimated water and Joint-ID's distance, in the network's colour",
        needs=("torch", "weights"),
        preflight="murk.enhance.methods:water_weights",
    ),
    Method(
        "detail",
        "murk.enhance.detail_restorer:create_detail",
        (
            opt("strength", "float", 1.0, "share of the learned residual added (0: none)", low=0, high=2),
            opt("weights", "str | Path | None", None, "detail network weights (.npz); default: shipped"),
            DEVICE,
        ),
        help="a learned local residual after a restorer (lite+detail): takes out marine snow and some forward-scatter "
        "blur, keeps the colour; slow at full resolution",
        needs=("torch", "weights"),
        preflight="murk.enhance.methods:detail_weights",
    ),
    Method(
        "udaformer",
        "murk.enhance.udaformer_restorer:create_udaformer",
        BASELINE_OPTIONS,
        help="UDAformer, a comparison baseline (its checkpoint required)",
        needs=("torch", "weights"),
        preflight="murk.enhance.methods:baseline_weights",
    ),
    Method(
        "ursct",
        "murk.enhance.ursct_restorer:create_ursct",
        BASELINE_OPTIONS,
        help="URSCT-SESR, a comparison baseline (its checkpoint required)",
        needs=("torch", "weights"),
        preflight="murk.enhance.methods:baseline_weights",
    ),
)
"""The built-in methods and presets, registered by :mod:`murk.enhance.restorer` on first use."""


def methods_help(methods: tuple[Method | Preset, ...] = BUILTIN) -> str:
    """One line per method for ``--help``: ``name: what it does (needs ...)``; a preset: ``name = its spec: what
    it does (needs what its methods need)``."""
    by_name = {m.name: m for m in methods}
    lines = []
    for m in methods:
        needs = [n for n in _needs(m, by_name) if n != "onnxruntime"]
        spec = f" = {m.spec}" if isinstance(m, Preset) else ""
        lines.append(f"{m.name}{spec}: {m.help}" + (f" (needs {', '.join(needs)})" if needs else ""))
    return "; ".join(lines)


def _needs(method: Method | Preset, by_name: dict[str, Method | Preset]) -> tuple[Need, ...]:
    """What ``method`` needs; a preset, what the methods of its spec among ``by_name`` need."""
    if isinstance(method, Method):
        return method.needs
    found = [n for name in names(parse_method(method.spec, named_weights=True)) if name in by_name
             for n in _needs(by_name[name], by_name)]  # fmt: skip
    return tuple(n for n in NEEDS if n in found)


def options_table(methods: tuple[Method | Preset, ...] = BUILTIN) -> str:
    """The options of every method as the markdown table of docs/enhance.md (a preset: its own options, after a row
    saying that it takes those of its first method)."""
    rows = ["| method | option | type | default | range | what it does |", "|---|---|---|---|---|---|"]
    for m in methods:
        first = f"`{m.name}`"
        if isinstance(m, Preset):
            others = ", ".join(f"`{n}`" for n in dict.fromkeys(names(parse_method(m.spec, named_weights=True))[1:]))
            passed = f", {', '.join(f'`{p}`' for p in m.passes)} also to {others}" if m.passes else ""
            spec = m.spec.replace("|", "\\|")
            rows.append(f"| {first} | those of `{m.first}` | | | | `{spec}`: its options go to `{m.first}`{passed} |")
            first = ""
        for o in m.options:
            kind = o.type.replace("|", "\\|")
            rows.append(f"| {first} | `{o.name}` | `{kind}` | `{o.default!r}` | {_range(o)} | {o.help} |")
            first = ""
    return "\n".join(rows)


def _range(o: Option) -> str:
    if o.low is not None and o.high is not None:
        return f"[{o.low:g}, {o.high:g}]"
    if o.low is not None:
        return f">= {o.low:g}"
    return "" if o.high is None else f"<= {o.high:g}"
