"""ONNX export of Joint-ID as a graph of ONE input with dynamic batch, height and width, and an ONNX Runtime runner.

Graph contract (:class:`JointIDImageGraph`, what the ``jointid`` restorer computes): input ``image``
(B, 3, H, W) float32 RGB in [0, 1], any H, W >= 1; outputs ``depth_m`` (B, 1, H, W), metres, and ``enhanced``
(B, 3, H, W) in [0, 1]. Inside: the training recipe's normalisation, reflect padding to multiples of 32 (a gather
per axis, :func:`murk.models.padding.reflect_rows`), the network, the crop back and a clamp of ``enhanced``.
Model metadata ``murk.format`` = ``murk.jointid.image``. The TorchScript-based exporter is used
(``dynamo=False``): it needs no extra package (the torch.export-based one needs onnxscript).

Reference: Yang, Kang, Lee, Cho, IEEE Sensors Journal 2023, doi:10.1109/JSEN.2023.3338730.
"""

from __future__ import annotations

import copy
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from murk.errors import InputFileError
from murk.io.atomic import atomic_path
from murk.models.balance_graph import color_balance_graph
from murk.models.jointid.checkpoint import unwrap
from murk.models.jointid.network import INPUT_MEAN, INPUT_STD, SIZE_MULTIPLE, normalize_input
from murk.models.onnx_session import onnx_session
from murk.models.padding import pad_to_multiple, reflect_rows
from murk.restore_ops.balance import color_balance_torch

INPUT_NAME = "image"
OUTPUT_NAMES = ("depth_m", "enhanced")
DEFAULT_OPSET = 17
FORMAT_KEY = "murk.format"
FORMAT = "murk.jointid.image"
"""The ``murk.format`` metadata of a one-input Joint-ID export."""
BALANCE_KEY = "murk.input_balance_pct"
"""The simplest colour balance the graph applies to its input (a number, or ``none``); absent in exports made
before it was recorded. The restorer needs it for the ``exposure`` step outside the graph."""


def _cpu_fp32(model: nn.Module) -> nn.Module:
    """The JointID inside ``model`` in fp32 on the CPU, in eval mode; a copy when that needs a conversion, so
    the caller's model (e.g. on a GPU, or training) is left as it is."""
    net = unwrap(model)
    if any(p.device.type != "cpu" or p.dtype != torch.float32 for p in net.parameters()) or net.training:
        net = copy.deepcopy(net).float().cpu().eval()
    return net


class JointIDImageGraph(nn.Module):
    """Joint-ID as the ``jointid`` restorer runs it (whole frames), on one input that the tracer follows for any
    size: frames (B, 3, H, W) RGB in [0, 1] -> ``(depth_m, enhanced)`` at the frame's size (see the module
    docstring); equal to :func:`restore_reference`."""

    mean: Tensor
    std: Tensor

    def __init__(self, model: nn.Module) -> None:
        super().__init__()
        self.model = model
        self.balance_pct: float | None = getattr(model, "input_balance_pct", None)
        self.register_buffer("mean", torch.tensor(INPUT_MEAN).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(INPUT_STD).view(1, 3, 1, 1), persistent=False)

    def forward(self, image: Tensor) -> tuple[Tensor, Tensor]:
        shape = torch._shape_as_tensor(image)  # traced: the graph pads and crops each frame by its own size
        h, w = shape[2], shape[3]
        h_pad = h + torch.remainder(-h, SIZE_MULTIPLE)
        w_pad = w + torch.remainder(-w, SIZE_MULTIPLE)
        top = torch.div(h_pad - h, 2, rounding_mode="floor")  # as murk.models.padding.padding_for
        left = torch.div(w_pad - w, 2, rounding_mode="floor")
        if self.balance_pct is not None:  # the input the network was trained on (model.input_balance_pct)
            image = color_balance_graph(image, self.balance_pct, self.balance_pct)
        x = (image - self.mean) / self.std
        x = x[:, :, reflect_rows(h, h_pad, top)][:, :, :, reflect_rows(w, w_pad, left)]
        out = self.model(x)
        depth = out.depth_m[:, :, top : top + h, left : left + w]
        return depth, out.enhanced[:, :, top : top + h, left : left + w].clamp(0.0, 1.0)


def restore_reference(model: nn.Module, x: Tensor) -> tuple[Tensor, Tensor]:
    """What the ``jointid`` restorer computes for frames ``x`` (B, 3, H, W) in [0, 1] (whole frames, fp32),
    written plainly: balance (when the network was trained so), normalise, reflect-pad to multiples of 32, the
    network, crop, clamp ``enhanced``."""
    balance = getattr(model, "input_balance_pct", None)
    if balance is not None:
        x = color_balance_torch(x, balance, balance)
    padded, pad = pad_to_multiple(normalize_input(x), SIZE_MULTIPLE, "reflect")
    out = model(padded)
    return pad.crop(out.depth_m), pad.crop(out.enhanced).clamp(0.0, 1.0)


def export_onnx(
    model: nn.Module,
    path: str | Path,
    *,
    opset: int = DEFAULT_OPSET,
    sample_size: tuple[int, int] = (45, 70),
) -> Path:
    """Export ``model`` as the one-input graph of the module docstring (:class:`JointIDImageGraph`) to an ONNX
    file (atomic write) with dynamic batch/height/width.

    Args:
        model: a JointID (optionally wrapped); exported in fp32 on the CPU in eval mode (from a copy when the
            model is elsewhere or in training mode; the caller's model is not changed).
        path: the ``.onnx`` file to write.
        opset: ONNX opset (>= 14 for scaled dot-product attention).
        sample_size: (H, W) of the tracing input; the graph accepts any size.

    Raises:
        ValueError: opset < 14 or a sample size that is not positive.
    """
    import onnx

    if opset < 14:
        raise ValueError(f"opset: expected >= 14 (attention export), got {opset}")
    h, w = sample_size
    if h < 1 or w < 1:
        raise ValueError(f"sample_size: expected a positive height and width, got {sample_size}")
    net = _cpu_fp32(model)
    x = torch.zeros(1, 3, h, w)
    dynamic = {INPUT_NAME: {0: "batch", 2: "height", 3: "width"}}
    dynamic |= {name: {0: "batch", 2: "height", 3: "width"} for name in OUTPUT_NAMES}
    path = Path(path)
    with atomic_path(path) as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the legacy exporter announces its successor
        warnings.simplefilter("ignore", torch.jit.TracerWarning)
        # The exporter's note that strided slices are not constant-folded: an optimisation it skips, not a fault.
        warnings.filterwarnings("ignore", message="Constant folding - Only steps=1", category=UserWarning)
        torch.onnx.export(
            JointIDImageGraph(net).eval(),
            (x,),
            str(tmp),
            dynamo=False,
            input_names=[INPUT_NAME],
            output_names=list(OUTPUT_NAMES),
            dynamic_axes=dynamic,
            opset_version=opset,
            do_constant_folding=True,
        )
        graph = onnx.load(str(tmp))
        balance = getattr(net, "input_balance_pct", None)
        for key, value in ((FORMAT_KEY, FORMAT), (BALANCE_KEY, "none" if balance is None else repr(float(balance)))):
            entry = graph.metadata_props.add()
            entry.key, entry.value = key, value
        onnx.save(graph, str(tmp))
    return path


class OnnxJointID:
    """Runs an exported Joint-ID file with ONNX Runtime: ``runner(x) -> (depth_m, enhanced)`` on tensors
    (B, 3, H, W) RGB in [0, 1] of any size (normalisation and padding are in the graph).

    Args:
        path: the ``.onnx`` file.
        device: ``"cpu"`` or ``"cuda"`` (needs onnxruntime-gpu).
        threads: intra-op threads (None = ONNX Runtime's default, all cores).

    Raises:
        InputFileError: missing or invalid file.
        ValueError: CUDA requested without the CUDA execution provider.
        ImportError: onnxruntime is not installed (``pip install murk[onnx]``).
    """

    def __init__(self, path: str | Path, *, device: str = "cpu", threads: int | None = None) -> None:
        path = Path(path)
        self.session = onnx_session(path, device=device, threads=threads)
        names = [i.name for i in self.session.get_inputs()]
        outs = [o.name for o in self.session.get_outputs()]
        if names != [INPUT_NAME] or outs != list(OUTPUT_NAMES):
            expected = "image -> depth_m, enhanced"
            raise InputFileError(
                path, f"not a murk Joint-ID export (inputs {names}, outputs {outs}; expected {expected})"
            )
        if self.session.get_modelmeta().custom_metadata_map.get(FORMAT_KEY) != FORMAT:
            raise InputFileError(
                path,
                "a Joint-ID export from an earlier murk (a normalised input, sides multiples of 32); export it "
                "again with 'murk export' (one input: the image in [0, 1], any size)",
            )
        balance = self.session.get_modelmeta().custom_metadata_map.get(BALANCE_KEY)
        try:
            self.graph_balance_pct: float | None = None if balance in (None, "none") else float(balance)
        except ValueError as exc:
            raise InputFileError(path, f"not a murk Joint-ID export ({BALANCE_KEY!r} is {balance!r})") from exc
        """The balance the graph applies to its input (its ``murk.input_balance_pct`` metadata; None: none)."""
        self.balance_recorded = balance is not None
        """False for exports made before the balance was recorded (the restorer's ``exposure`` then needs a .pt)."""
        self.path = path

    def run_numpy(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(B, 3, H, W) float32 RGB in [0, 1], any H, W -> (depth_m, enhanced) float32 arrays."""
        depth, enhanced = self.session.run(list(OUTPUT_NAMES), {INPUT_NAME: np.ascontiguousarray(x, np.float32)})
        return depth, enhanced

    def __call__(self, x: Tensor) -> tuple[Tensor, Tensor]:
        depth, enhanced = self.run_numpy(x.detach().float().cpu().numpy())
        return torch.from_numpy(depth).to(x.device), torch.from_numpy(enhanced).to(x.device)

    def __repr__(self) -> str:
        return f"OnnxJointID({str(self.path)!r})"


def compare_onnx(model: nn.Module, runner: OnnxJointID, x: Tensor) -> dict[str, Any]:
    """Max absolute differences between torch (:func:`restore_reference`, fp32, CPU) and the ONNX runner on frames
    ``x`` (B, 3, H, W) in [0, 1]."""
    net = _cpu_fp32(model)
    with torch.inference_mode():
        ref_depth, ref_enhanced = restore_reference(net, x.float().cpu())
    depth, enhanced = runner(x.float().cpu())
    return {
        "depth_m": float((depth - ref_depth).abs().max()),
        "enhanced": float((enhanced - ref_enhanced).abs().max()),
    }
