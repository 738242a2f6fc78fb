"""ONNX export of the comparison baselines (UDAformer, URSCT-SESR) for one frame size, verified with ONNX Runtime.

Both graphs have a dynamic batch but a FIXED height and width. The ops export (opset >= 14, TorchScript-based
exporter), but the size-dependent parts are traced as constants: UDAformer's window padding, shift masks and
odd-size paths (a graph exported at one size gives wrong results at another: checked), and URSCT-SESR's
square window grids and shift masks (the network itself is built for one size). Export one file per size
you need; for any frame size, run murk's torch restorers (``--method udaformer``/``ursct``), which pad and tile.

Graph contract (:class:`BaselineImageGraph`): ONE input ``image`` (B, 3, H, W) float32 RGB in [0, 1] at the
exported size, output ``enhanced`` (B, 3, H, W), the restored frames in RGB clamped to [0, 1]: what the
restorers' ``native`` policy computes for one whole frame (UDAformer: RGB -> BGR, reflect padding to a multiple
of 8 and the crop back happen inside the graph; URSCT-SESR: the network on the whole frame). murk's restorers
tile frames larger than that (UDAformer above 1024x1024 pixels, URSCT-SESR above its 256x256 tile); the graph
does not.
"""

from __future__ import annotations

import copy
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from murk.io.atomic import atomic_path
from murk.models.padding import pad_to_multiple
from murk.models.udaformer.network import WINDOW, UDAformer
from murk.models.ursct_sesr.network import SIZE_MULTIPLE, URSCT

INPUT_NAME = "image"
OUTPUT_NAME = "enhanced"
DEFAULT_OPSET = 17


class BaselineImageGraph(nn.Module):
    """A baseline on one whole frame as its restorer's ``native`` policy runs it: RGB (B, 3, H, W) in [0, 1] ->
    restored RGB clamped to [0, 1] (UDAformer: BGR inside, reflect-padded to a multiple of its window, cropped)."""

    def __init__(self, model: UDAformer | URSCT) -> None:
        super().__init__()
        self.model = model
        self.bgr = isinstance(model, UDAformer)

    def forward(self, image: Tensor) -> Tensor:
        x = image[:, [2, 1, 0]] if self.bgr else image  # the released UDAformer weights take BGR
        if self.bgr:  # the size is fixed: the padding is traced as constants
            x, pad = pad_to_multiple(x, WINDOW, "reflect")
            y = pad.crop(self.model(x))[:, [2, 1, 0]]
        else:
            y = self.model(x)
        return y.clamp(0.0, 1.0)


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
    """Export ``model`` as :class:`BaselineImageGraph` for (H, W) = ``size_hw`` with a dynamic batch, atomically;
    optionally run the file with ONNX Runtime at batch 1 and 2 on random inputs and compare with torch (fp32, CPU).

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
    net = BaselineImageGraph(copy.deepcopy(model).float().cpu().eval()).eval()
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
    """Max |ONNX Runtime - torch| per batch size (1 and 2) on seeded random inputs of ``size_hw``; ``model`` is
    what the graph computes (a :class:`BaselineImageGraph`)."""
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
