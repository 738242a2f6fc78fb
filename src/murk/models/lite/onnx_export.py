"""ONNX export of the ``lite`` restorer as a graph of ONE input (dynamic batch, height and width) and an ONNX Runtime
runner.

Graph contract: input ``image`` (B, 3, H, W) float32 RGB in [0, 1], any H, W >= 1 (no normalisation, no size
multiple); output ``enhanced`` (B, 3, H, W), the restored frames clamped to [0, 1]: what ``murk enhance --method
lite`` computes before any post-processing. The working image is made inside the graph
(:mod:`murk.models.lite.graph`): an ``If`` on the frame's area (more than ``work_area_px`` pixels) picks the
``downsample`` branch (area-downsampling by a gather per axis) or the ``native`` one (reflect padding to
multiples of 16 by a gather per axis, cropped back); both run the folded network and apply its maps at full
resolution. Model metadata: ``murk.format`` = ``murk.lite.image``, ``murk.work_area_px`` and ``murk.exposure``
(``input`` when the maps keep the input's exposure, :func:`~murk.models.lite.network.keep_exposure`, the
restorer's default; ``network`` otherwise, and for exports from before it existed).

Each branch is traced with the TorchScript-based exporter (``dynamo=False``: no extra package needed) and the two
are joined into one model with ``onnx``. Operators: Conv, LeakyRelu, AveragePool, ReduceMean, ReduceSum,
ReduceMax, Resize (bilinear), Tanh, Exp, Mul, Add, Sub, Div, Slice, Concat, Gather, Range, Shape, Sqrt, Round,
Mod, Where, Clip, If and a few more of shape arithmetic; opset >= 13.
"""

from __future__ import annotations

import copy
import math
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from murk.errors import InputFileError
from murk.io.atomic import atomic_path
from murk.models.lite.graph import LiteImageGraph, LitePath, restore_reference
from murk.models.lite.network import LiteNet, reparameterize, unwrap
from murk.models.onnx_session import onnx_session

INPUT_NAME = "image"
OUTPUT_NAME = "enhanced"
FORMAT_KEY = "murk.format"
FORMAT = "murk.lite.image"
"""The ``murk.format`` metadata of a one-input lite export."""
WORK_AREA_KEY = "murk.work_area_px"
EXPOSURE_KEY = "murk.exposure"
"""``input`` (the graph keeps the input's exposure) or ``network``; absent in earlier exports (``network``)."""
DEFAULT_OPSET = 17
MIN_OPSET = 13
VERIFY_TOLERANCE = 1e-4
"""Max absolute difference (enhanced, in [0, 1] units) allowed between ONNX Runtime and torch."""
VERIFY_SIZES = ((64, 48), (97, 131), (192, 320), (480, 640))
"""(H, W) of the random frames an export is verified on: native (even and odd sizes, padded inside the graph) and
downsampled (one odd-sized)."""

_AXES = {0: "batch", 2: "height", 3: "width"}


def _inference_copy(model: nn.Module, keep_exposure: bool) -> LiteNet:
    """The folded network in fp32 on the CPU in eval mode (a new module; the caller's is not changed)."""
    net = unwrap(model)
    folded = copy.deepcopy(net) if net.folded else reparameterize(net)
    folded.input_balance_pct = net.input_balance_pct  # not a weight: carried by hand
    folded.keep_exposure = keep_exposure
    return folded.float().cpu().eval()


def _trace(net: LiteNet, path: LitePath, size_hw: tuple[int, int], opset: int) -> Any:
    """One branch of the graph: :class:`LiteImageGraph` traced on a frame of ``size_hw`` along ``path``."""
    import onnx

    with tempfile.TemporaryDirectory(prefix="murk-lite-onnx-") as tmp, warnings.catch_warnings():
        file = Path(tmp) / f"{path}.onnx"
        warnings.simplefilter("ignore", DeprecationWarning)  # the legacy exporter announces its successor
        warnings.simplefilter("ignore", torch.jit.TracerWarning)  # the path choice, fixed per branch
        torch.onnx.export(
            LiteImageGraph(net, path).eval(),
            (torch.zeros(1, 3, *size_hw),),
            str(file),
            dynamo=False,
            input_names=[INPUT_NAME],
            output_names=[OUTPUT_NAME],
            dynamic_axes={INPUT_NAME: _AXES, OUTPUT_NAME: _AXES},
            opset_version=opset,
            do_constant_folding=True,
        )
        return onnx.load(str(file))


def _as_branch(model: Any, prefix: str) -> Any:
    """``model``'s graph as the branch of an ``If``: no inputs (``image`` is the outer graph's), every other name
    prefixed so that the two branches and the outer graph share none."""
    graph = copy.deepcopy(model.graph)
    names = {v for node in graph.node for v in node.output} | {t.name for t in graph.initializer}
    names |= {v.name for v in graph.output} | {v.name for v in graph.value_info}
    rename = {v: f"{prefix}{v}" for v in names if v and v != INPUT_NAME}

    def new(v: str) -> str:
        return rename.get(v, v)

    for node in graph.node:
        if any(a.type in (a.GRAPH, a.GRAPHS) for a in node.attribute):  # the traced graphs have no control flow
            raise ValueError(f"lite export: unexpected subgraph in node {node.op_type}")
        node.name = f"{prefix}{node.name}"
        node.input[:] = [new(v) for v in node.input]
        node.output[:] = [new(v) for v in node.output]
    for seq in (graph.initializer, graph.output, graph.value_info):
        for item in seq:
            item.name = new(item.name)
    del graph.input[:]
    graph.name = prefix.strip("/")
    return graph


def _join_on_area(native: Any, downsample: Any, work_area_px: int) -> Any:
    """One model: ``If(H * W > work_area_px)`` runs ``downsample``, else ``native`` (the restorer's choice)."""
    from onnx import TensorProto, helper

    def const(name: str, values: list[int], dims: list[int]) -> Any:
        return helper.make_node("Constant", [], [name], value=helper.make_tensor(name, TensorProto.INT64, dims, values))

    nodes = [
        helper.make_node("Shape", [INPUT_NAME], ["/area/shape"], name="/area/Shape"),
        const("/area/starts", [2], [1]),
        const("/area/ends", [4], [1]),
        helper.make_node("Slice", ["/area/shape", "/area/starts", "/area/ends"], ["/area/hw"], name="/area/Slice"),
        helper.make_node("ReduceProd", ["/area/hw"], ["/area/pixels"], name="/area/ReduceProd", keepdims=0),
        const("/area/limit", [work_area_px], []),
        helper.make_node("Greater", ["/area/pixels", "/area/limit"], ["/area/large"], name="/area/Greater"),
        helper.make_node(
            "If",
            ["/area/large"],
            [OUTPUT_NAME],
            name="/If",
            then_branch=_as_branch(downsample, "/downsample/"),
            else_branch=_as_branch(native, "/native/"),
        ),
    ]
    graph = helper.make_graph(
        nodes, "lite", [copy.deepcopy(native.graph.input[0])], [copy.deepcopy(native.graph.output[0])]
    )
    model = helper.make_model(graph, opset_imports=list(native.opset_import), producer_name=native.producer_name)
    model.producer_version = native.producer_version
    model.ir_version = native.ir_version
    return model


def export_lite_onnx(
    model: nn.Module, path: str | Path, *, opset: int = DEFAULT_OPSET, keep_exposure: bool = True
) -> Path:
    """Export a ``lite`` network (training form or folded; it is folded first) as the one-input graph of the
    module docstring, atomically.

    Args:
        model: a LiteNet, optionally wrapped.
        path: the ``.onnx`` file to write.
        opset: ONNX opset (>= 13).
        keep_exposure: the graph keeps the input's exposure (:func:`~murk.models.lite.network.keep_exposure`;
            the ``lite`` restorer's default ``exposure=input``); False: the network's own (``exposure=network``).

    Raises:
        ValueError: opset < 13.
    """
    import onnx

    if opset < MIN_OPSET:
        raise ValueError(f"opset: expected >= {MIN_OPSET} (ReduceSum with axes as an input), got {opset}")
    net = _inference_copy(model, keep_exposure)
    area = net.config.work_area_px
    native = _trace(net, "native", (9, 13), opset)  # 9x13: padded on every side; any frame of <= 256 px is native
    if area > 0:
        side = math.isqrt(area) + 3  # side x (side + 7) > area: downsampled, windows of two sizes
        graph = _join_on_area(native, _trace(net, "downsample", (side, side + 7), opset), area)
    else:
        graph = native
    exposure = "input" if keep_exposure else "network"
    for key, value in ((FORMAT_KEY, FORMAT), (WORK_AREA_KEY, str(area)), (EXPOSURE_KEY, exposure)):
        entry = graph.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(graph, full_check=True)
    path = Path(path)
    with atomic_path(path) as tmp:
        onnx.save(graph, str(tmp))
    return path


class OnnxLite:
    """Runs an exported ``lite`` file with ONNX Runtime: ``runner(x) -> enhanced`` on (B, 3, H, W) tensors of any
    size (the whole restorer is in the graph; the output is clamped to [0, 1]).

    Args:
        path: the ``.onnx`` file.
        threads: intra-op threads (None = ONNX Runtime's default, all cores).

    Raises:
        ImportError: onnxruntime is not installed (``pip install 'murk[onnx]'``).
        InputFileError: missing or invalid file, or not a lite export.
    """

    def __init__(self, path: str | Path, *, threads: int | None = None) -> None:
        path = Path(path)
        self.session = onnx_session(path, threads=threads)
        ins = [i.name for i in self.session.get_inputs()]
        outs = [o.name for o in self.session.get_outputs()]
        meta = self.session.get_modelmeta().custom_metadata_map
        earlier = "a lite export from an earlier murk"
        again = "export it again with 'murk export' (one input: the image)"
        if ins == [INPUT_NAME, "work"] and outs == [OUTPUT_NAME]:
            raise InputFileError(path, f"{earlier} (a second input, the working image); {again}")
        if ins != [INPUT_NAME] or outs != [OUTPUT_NAME]:
            raise InputFileError(
                path, f"not a murk lite export (inputs {ins}, outputs {outs}; expected image -> enhanced)"
            )
        if meta.get(FORMAT_KEY) != FORMAT:
            raise InputFileError(path, f"{earlier} (no {FORMAT_KEY!r}: {FORMAT!r} metadata); {again}")
        try:
            self.work_area_px = int(meta[WORK_AREA_KEY])
        except (KeyError, ValueError) as exc:
            raise InputFileError(path, f"not a murk lite export (no valid {WORK_AREA_KEY!r} metadata)") from exc
        exposure = meta.get(EXPOSURE_KEY, "network")
        self.exposure_recorded = EXPOSURE_KEY in meta
        """False for exports made before the setting was recorded (they run with the network's own exposure)."""
        if exposure not in ("input", "network"):
            raise InputFileError(path, f"not a murk lite export ({EXPOSURE_KEY!r} is {exposure!r})")
        self.keep_exposure = exposure == "input"
        """Whether the graph keeps the input's exposure (its ``murk.exposure`` metadata)."""
        self.path = path

    def run_numpy(self, x: np.ndarray) -> np.ndarray:
        """(B, 3, H, W) float32 RGB in [0, 1], any H, W -> restored (B, 3, H, W) float32 in [0, 1]."""
        return self.session.run([OUTPUT_NAME], {INPUT_NAME: np.ascontiguousarray(x, np.float32)})[0]

    def __call__(self, x: Tensor) -> Tensor:
        return torch.from_numpy(self.run_numpy(x.detach().float().cpu().numpy())).to(x.device)

    def __repr__(self) -> str:
        return f"OnnxLite({str(self.path)!r})"


@dataclass(frozen=True)
class LiteExport:
    """What :func:`export_lite_checkpoint` did: the file, the folded parameter count and, per verified size
    (H, W), the max absolute difference between ONNX Runtime and torch."""

    path: Path
    parameters: int
    max_abs_diff: dict[tuple[int, int], float]


def export_lite_checkpoint(
    checkpoint: str | Path,
    out: str | Path,
    *,
    opset: int = DEFAULT_OPSET,
    verify: bool = True,
    trust: bool = False,
    tolerance: float = VERIFY_TOLERANCE,
    keep_exposure: bool = True,
) -> LiteExport:
    """Load a ``lite`` checkpoint, fold it, export it to ONNX and (``verify``) compare ONNX Runtime with torch
    (:func:`~murk.models.lite.graph.restore_reference`: what the restorer computes) on random frames of
    :data:`VERIFY_SIZES`. ``keep_exposure``: as :func:`export_lite_onnx`'s.

    Raises:
        InputFileError: the checkpoint cannot be read.
        ValueError: ``out`` does not end in ``.onnx``, or ONNX Runtime differs from torch by more than
            ``tolerance``.
        ImportError: ``verify`` without onnxruntime installed.
    """
    from murk.models.lite.checkpoint import load_lite

    out = Path(out)
    if out.suffix.lower() != ".onnx":
        raise ValueError(f"out: expected a file name ending in .onnx, got {str(out)!r}")
    model = load_lite(checkpoint, trust=trust)
    model.keep_exposure = keep_exposure  # what the reference computes below
    export_lite_onnx(model, out, opset=opset, keep_exposure=keep_exposure)
    diffs: dict[tuple[int, int], float] = {}
    if verify:
        runner = OnnxLite(out)
        g = torch.Generator().manual_seed(0)
        for h, w in VERIFY_SIZES:
            x = torch.rand(2, 3, h, w, generator=g)
            with torch.inference_mode():
                ref = restore_reference(model, x)
            diffs[(h, w)] = float((runner(x) - ref).abs().max())
            if diffs[(h, w)] > tolerance:
                raise ValueError(
                    f"{out}: ONNX Runtime differs from torch by {diffs[(h, w)]:.3g} at {h}x{w} (tolerance "
                    f"{tolerance}); the export is not trustworthy"
                )
    return LiteExport(out, sum(p.numel() for p in model.parameters()), diffs)
