"""ONNX export of the folded ``lite`` network (dynamic batch, height and width) and an ONNX Runtime runner.

The graph takes ``image``, RGB in [0, 1] (B, 3, H, W) (no normalisation), and ``work``, its working image
(B, 3, h, w) with h and w multiples of 16 (:func:`~murk.models.lite.network.work_image`: the image itself when it
has at most ``work_area_px`` pixels, else area-downsampled; the runner makes it), and returns ``enhanced``
(B, 3, H, W), not clamped (as the torch network). The network's ``work_area_px`` is stored in the model's
metadata (key ``murk.work_area_px``). The TorchScript-based exporter is used (``dynamo=False``: no
extra package needed). Operators: Conv, LeakyRelu, AveragePool, ReduceMean, Resize (bilinear), Tanh, Exp,
Mul, Add, Slice, Concat.
"""

from __future__ import annotations

import copy
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torch import Tensor, nn

from murk.errors import InputFileError
from murk.io.atomic import atomic_path
from murk.models.lite.network import SIZE_MULTIPLE, LiteNet, reparameterize, unwrap, work_image

INPUT_NAME = "image"
WORK_NAME = "work"
OUTPUT_NAME = "enhanced"
WORK_AREA_KEY = "murk.work_area_px"
DEFAULT_OPSET = 17
VERIFY_TOLERANCE = 1e-4
"""Max absolute difference (enhanced, in [0, 1] units) allowed between ONNX Runtime and torch."""


def _inference_copy(model: nn.Module) -> LiteNet:
    """The folded network in fp32 on the CPU in eval mode (a new module; the caller's is not changed)."""
    net = unwrap(model)
    folded = copy.deepcopy(net) if net.folded else reparameterize(net)
    return folded.float().cpu().eval()


def export_lite_onnx(
    model: nn.Module, path: str | Path, *, opset: int = DEFAULT_OPSET, sample_size: tuple[int, int] = (64, 96)
) -> Path:
    """Export a ``lite`` network (training form or folded; it is folded first) to ONNX, atomically.

    Args:
        model: a LiteNet, optionally wrapped.
        path: the ``.onnx`` file to write.
        opset: ONNX opset (>= 11).
        sample_size: (H, W) of the tracing input, multiples of 16; the graph accepts any size (the working
            image: multiples of 16).

    Raises:
        ValueError: opset < 11 or a sample size that is not a positive multiple of 16.
    """
    if opset < 11:
        raise ValueError(f"opset: expected >= 11 (bilinear Resize), got {opset}")
    h, w = sample_size
    if h < SIZE_MULTIPLE or w < SIZE_MULTIPLE or h % SIZE_MULTIPLE or w % SIZE_MULTIPLE:
        raise ValueError(f"sample_size: expected positive multiples of {SIZE_MULTIPLE}, got {sample_size}")
    net = _inference_copy(model)
    axes = {0: "batch", 2: "height", 3: "width"}
    work_axes = {0: "batch", 2: "work_height", 3: "work_width"}
    path = Path(path)
    with atomic_path(path) as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # the legacy exporter announces its successor
        warnings.simplefilter("ignore", torch.jit.TracerWarning)  # the input shape check
        # Traced with a working image of another size than the frame, so that the upsampling to the frame's
        # size is recorded from the frame's shape, not as a fixed scale.
        torch.onnx.export(
            net,
            (torch.zeros(1, 3, 2 * h, 2 * w), torch.zeros(1, 3, h, w)),
            str(tmp),
            dynamo=False,
            input_names=[INPUT_NAME, WORK_NAME],
            output_names=[OUTPUT_NAME],
            dynamic_axes={INPUT_NAME: axes, WORK_NAME: work_axes, OUTPUT_NAME: axes},
            opset_version=opset,
            do_constant_folding=True,
        )
        import onnx

        graph = onnx.load(str(tmp))
        entry = graph.metadata_props.add()
        entry.key, entry.value = WORK_AREA_KEY, str(net.config.work_area_px)
        onnx.save(graph, str(tmp))
    return path


class OnnxLite:
    """Runs an exported ``lite`` file with ONNX Runtime: ``runner(x) -> enhanced`` on (B, 3, H, W) tensors.

    Args:
        path: the ``.onnx`` file.
        threads: intra-op threads (None = ONNX Runtime's default, all cores).

    Raises:
        ImportError: onnxruntime is not installed (``pip install 'murk[onnx]'``).
        InputFileError: missing or invalid file, or not a lite export.
    """

    def __init__(self, path: str | Path, *, threads: int | None = None) -> None:
        try:
            import onnxruntime as ort
        except ImportError as exc:
            raise ImportError("onnxruntime is needed to run .onnx models: pip install 'murk[onnx]'") from exc
        path = Path(path)
        if not path.is_file():
            raise InputFileError(path, "ONNX model not found")
        opts = ort.SessionOptions()
        opts.add_session_config_entry("session.set_denormal_as_zero", "1")
        if threads is not None:
            opts.intra_op_num_threads = threads
            opts.inter_op_num_threads = 1
        try:
            self.session = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
        except Exception as exc:
            raise InputFileError(path, f"not a loadable ONNX model ({type(exc).__name__}: {exc})") from exc
        ins = [i.name for i in self.session.get_inputs()]
        outs = [o.name for o in self.session.get_outputs()]
        if ins == [INPUT_NAME] and outs == [OUTPUT_NAME]:
            raise InputFileError(
                path, "a lite export from an earlier murk (no working-image input); export it again with 'murk export'"
            )
        if ins != [INPUT_NAME, WORK_NAME] or outs != [OUTPUT_NAME]:
            raise InputFileError(
                path, f"not a murk lite export (inputs {ins}, outputs {outs}; expected image, work -> enhanced)"
            )
        meta = self.session.get_modelmeta().custom_metadata_map
        try:
            self.work_area_px = int(meta[WORK_AREA_KEY])
        except (KeyError, ValueError) as exc:
            raise InputFileError(path, f"not a murk lite export (no valid {WORK_AREA_KEY!r} metadata)") from exc
        self.path = path

    def run_numpy(self, x: np.ndarray, work: np.ndarray | None = None) -> np.ndarray:
        """(B, 3, H, W) float32 RGB in [0, 1] (and its working image; default: made here) -> enhanced
        (B, 3, H, W) float32."""
        if work is None:
            work = work_image(torch.from_numpy(np.asarray(x, np.float32)), self.work_area_px).numpy()
        feeds = {INPUT_NAME: np.ascontiguousarray(x, np.float32), WORK_NAME: np.ascontiguousarray(work, np.float32)}
        return self.session.run([OUTPUT_NAME], feeds)[0]

    def __call__(self, x: Tensor, work: Tensor | None = None) -> Tensor:
        w = None if work is None else work.detach().float().cpu().numpy()
        return torch.from_numpy(self.run_numpy(x.detach().float().cpu().numpy(), w)).to(x.device)

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
) -> LiteExport:
    """Load a ``lite`` checkpoint, fold it, export it to ONNX and (``verify``) compare ONNX Runtime with torch on
    two random inputs of different shapes.

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
    export_lite_onnx(model, out, opset=opset)
    diffs: dict[tuple[int, int], float] = {}
    if verify:
        runner = OnnxLite(out)
        g = torch.Generator().manual_seed(0)
        for h, w in ((64, 96), (96, 64), (192, 320)):  # the last one larger than the working area
            x = torch.rand(2, 3, h, w, generator=g)
            with torch.inference_mode():
                ref = model(x)
            diffs[(h, w)] = float((runner(x) - ref).abs().max())
            if diffs[(h, w)] > tolerance:
                raise ValueError(
                    f"{out}: ONNX Runtime differs from torch by {diffs[(h, w)]:.3g} at {h}x{w} (tolerance "
                    f"{tolerance}); the export is not trustworthy"
                )
    return LiteExport(out, sum(p.numel() for p in model.parameters()), diffs)
