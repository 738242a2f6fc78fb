"""ONNX export of the comparison baselines (UDAformer, URSCT-SESR) for one frame size, verified with ONNX Runtime.

Both graphs have a dynamic batch but a FIXED height and width. The ops export (opset >= 14, TorchScript-based
exporter), but the size-dependent parts are traced as constants: UDAformer's window padding, shift masks and
odd-size paths (a graph exported at one size gives wrong results at another: checked), and URSCT-SESR's
square window grids and shift masks (the network itself is built for one size). Export one file per size
you need; for any frame size, run murk's torch restorers (``--method udaformer``/``ursct``), which pad and tile.

Graph contract: input ``image`` (B, 3, H, W) float32 as the network takes it (UDAformer: BGR in [0, 1];
URSCT-SESR: RGB in [0, 1]), output ``enhanced`` (B, 3, H, W), unclamped.
"""

from __future__ import annotations

import copy
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from murk.io.atomic import atomic_path
from murk.models.udaformer.network import UDAformer
from murk.models.ursct_sesr.network import SIZE_MULTIPLE, URSCT

INPUT_NAME = "image"
OUTPUT_NAME = "enhanced"
DEFAULT_OPSET = 17


@dataclass(frozen=True)
class OnnxExport:
    """What :func:`export_baseline_onnx` wrote: the file, its fixed size and the verification result."""

    path: Path
    size_hw: tuple[int, int]
    parameters: int
    max_abs_diff: dict[int, float]
    """Per verified batch size: max |ONNX Runtime - torch| (empty when not verified)."""


def _check_size(model: nn.Module, size_hw: tuple[int, int]) -> None:
    h, w = size_hw
    if h < 1 or w < 1:
        raise ValueError(f"size: expected a positive height and width, got {h}x{w}")
    if isinstance(model, URSCT) and (h != w or h % SIZE_MULTIPLE):
        raise ValueError(f"size: URSCT-SESR needs a square size that is a multiple of {SIZE_MULTIPLE}, got {h}x{w}")


def export_baseline_onnx(
    model: UDAformer | URSCT,
    path: str | Path,
    *,
    size_hw: tuple[int, int] = (256, 256),
    opset: int = DEFAULT_OPSET,
    verify: bool = True,
) -> OnnxExport:
    """Export ``model`` for (H, W) = ``size_hw`` with a dynamic batch, atomically; optionally run the file with
    ONNX Runtime at batch 1 and 2 on random inputs and compare with torch (fp32, CPU).

    Raises:
        TypeError: not a UDAformer or URSCT.
        ValueError: opset < 14, or a size the network cannot take.
        ImportError: ``verify`` without onnxruntime (install murk[onnx]).
    """
    if not isinstance(model, (UDAformer, URSCT)):
        raise TypeError(f"model: expected a UDAformer or a URSCT, got {type(model).__name__}")
    if opset < 14:
        raise ValueError(f"opset: expected >= 14, got {opset}")
    _check_size(model, size_hw)
    net = copy.deepcopy(model).float().cpu().eval()
    h, w = size_hw
    path = Path(path)
    dynamic = {INPUT_NAME: {0: "batch"}, OUTPUT_NAME: {0: "batch"}}
    with atomic_path(path) as tmp, warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore")  # tracer warnings about size-dependent Python values: the size is fixed
        torch.onnx.export(
            net,
            (torch.zeros(1, 3, h, w),),
            str(tmp),
            input_names=[INPUT_NAME],
            output_names=[OUTPUT_NAME],
            dynamic_axes=dynamic,
            opset_version=opset,
            dynamo=False,
        )
    diffs = verify_baseline_onnx(net, path, size_hw) if verify else {}
    return OnnxExport(path, (h, w), sum(p.numel() for p in net.parameters()), diffs)


def verify_baseline_onnx(model: nn.Module, path: str | Path, size_hw: tuple[int, int]) -> dict[int, float]:
    """Max |ONNX Runtime - torch| per batch size (1 and 2) on seeded random inputs of ``size_hw``."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(path), providers=["CPUExecutionProvider"])
    g = torch.Generator().manual_seed(0)
    out = {}
    for b in (1, 2):
        x = torch.rand(b, 3, *size_hw, generator=g)
        (y,) = session.run([OUTPUT_NAME], {INPUT_NAME: x.numpy()})
        with torch.no_grad():
            ref = model(x).numpy()
        out[b] = float(np.abs(y - ref).max())
    return out
