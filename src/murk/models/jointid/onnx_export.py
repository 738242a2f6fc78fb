"""ONNX export of Joint-ID with dynamic batch, height and width (multiples of 32), and an ONNX Runtime runner.

The graph is the network's ``forward``: input ``image`` is the *normalised* batch (B, 3, H, W) (see
``normalize_input``), outputs ``depth_m`` (B, 1, H, W) and ``enhanced`` (B, 3, H, W). The TorchScript-based
exporter is used (``dynamo=False``): it needs no extra package (the torch.export-based one needs onnxscript).

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
from murk.models.jointid.checkpoint import unwrap

INPUT_NAME = "image"
OUTPUT_NAMES = ("depth_m", "enhanced")
DEFAULT_OPSET = 17


def _cpu_fp32(model: nn.Module) -> nn.Module:
    """The JointID inside ``model`` in fp32 on the CPU, in eval mode; a copy when that needs a conversion, so
    the caller's model (e.g. on a GPU, or training) is left as it is."""
    net = unwrap(model)
    if any(p.device.type != "cpu" or p.dtype != torch.float32 for p in net.parameters()) or net.training:
        net = copy.deepcopy(net).float().cpu().eval()
    return net


class _Plain(nn.Module):
    """Returns a plain tuple (exporters and runtimes do not know NamedTuple)."""

    def __init__(self, model: nn.Module) -> None:
        super().__init__()
        self.model = model

    def forward(self, x: Tensor) -> tuple[Tensor, Tensor]:
        out = self.model(x)
        return out.depth_m, out.enhanced


def export_onnx(
    model: nn.Module,
    path: str | Path,
    *,
    opset: int = DEFAULT_OPSET,
    sample_size: tuple[int, int] = (64, 96),
) -> Path:
    """Export ``model`` to an ONNX file (atomic write) with dynamic batch/height/width.

    Args:
        model: a JointID (optionally wrapped); exported in fp32 on the CPU in eval mode (from a copy when the
            model is elsewhere or in training mode; the caller's model is not changed).
        path: the ``.onnx`` file to write.
        opset: ONNX opset (>= 14 for scaled dot-product attention).
        sample_size: (H, W) of the tracing input, multiples of 32; the graph accepts any multiple of 32.

    Raises:
        ValueError: opset < 14 or a sample size that is not a positive multiple of 32.
    """
    if opset < 14:
        raise ValueError(f"opset: expected >= 14 (attention export), got {opset}")
    h, w = sample_size
    if h < 32 or w < 32 or h % 32 or w % 32:
        raise ValueError(f"sample_size: expected positive multiples of 32, got {sample_size}")
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
            _Plain(net),
            (x,),
            str(tmp),
            dynamo=False,
            input_names=[INPUT_NAME],
            output_names=list(OUTPUT_NAMES),
            dynamic_axes=dynamic,
            opset_version=opset,
            do_constant_folding=True,
        )
    return path


class OnnxJointID:
    """Runs an exported Joint-ID file with ONNX Runtime: ``runner(x) -> (depth_m, enhanced)`` on tensors.

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
        try:
            import onnxruntime as ort
        except ImportError as exc:
            raise ImportError("onnxruntime is needed to run .onnx models: pip install 'murk[onnx]'") from exc
        path = Path(path)
        if not path.is_file():
            raise InputFileError(path, "ONNX model not found")
        providers = ["CPUExecutionProvider"]
        if str(device).startswith("cuda"):
            if "CUDAExecutionProvider" not in ort.get_available_providers():
                raise ValueError(
                    f"device: {device!r} needs onnxruntime-gpu (CUDAExecutionProvider); "
                    f"available: {ort.get_available_providers()}"
                )
            providers.insert(0, "CUDAExecutionProvider")
        opts = ort.SessionOptions()
        opts.add_session_config_entry("session.set_denormal_as_zero", "1")  # see jointid_restorer: denormals
        if threads is not None:
            opts.intra_op_num_threads = threads
            opts.inter_op_num_threads = 1
        try:
            self.session = ort.InferenceSession(str(path), opts, providers=providers)
        except Exception as exc:
            raise InputFileError(path, f"not a loadable ONNX model ({type(exc).__name__}: {exc})") from exc
        names = [i.name for i in self.session.get_inputs()]
        outs = [o.name for o in self.session.get_outputs()]
        if names != [INPUT_NAME] or outs != list(OUTPUT_NAMES):
            expected = "image -> depth_m, enhanced"
            raise InputFileError(
                path, f"not a murk Joint-ID export (inputs {names}, outputs {outs}; expected {expected})"
            )
        self.path = path

    def run_numpy(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(B, 3, H, W) float32 normalised input -> (depth_m, enhanced) float32 arrays."""
        depth, enhanced = self.session.run(list(OUTPUT_NAMES), {INPUT_NAME: np.ascontiguousarray(x, np.float32)})
        return depth, enhanced

    def __call__(self, x: Tensor) -> tuple[Tensor, Tensor]:
        depth, enhanced = self.run_numpy(x.detach().float().cpu().numpy())
        return torch.from_numpy(depth).to(x.device), torch.from_numpy(enhanced).to(x.device)

    def __repr__(self) -> str:
        return f"OnnxJointID({str(self.path)!r})"


def compare_onnx(model: nn.Module, runner: OnnxJointID, x: Tensor) -> dict[str, Any]:
    """Max absolute differences between the torch model (fp32, CPU) and the ONNX runner on ``x``."""
    net = _cpu_fp32(model)
    with torch.inference_mode():
        ref = net(x.float().cpu())
    depth, enhanced = runner(x.float().cpu())
    return {
        "depth_m": float((depth - ref.depth_m).abs().max()),
        "enhanced": float((enhanced - ref.enhanced).abs().max()),
    }
