"""An ONNX Runtime session for murk's exported networks (Joint-ID, lite): the file checked first, denormals
flushed to zero, the threads and the execution provider chosen. onnxruntime is imported on first use (the
``onnx`` extra)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from murk.errors import InputFileError


def onnx_session(path: Path, *, device: str = "cpu", threads: int | None = None) -> Any:
    """An ``onnxruntime.InferenceSession`` of ``path``.

    Args:
        path: the ``.onnx`` file.
        device: ``"cpu"`` or ``"cuda"`` (needs onnxruntime-gpu; the CPU provider stays the fallback).
        threads: intra-op threads (None = ONNX Runtime's default, all cores); one inter-op thread when given.

    Raises:
        ImportError: onnxruntime is not installed (``pip install 'murk[onnx]'``).
        InputFileError: the file is missing or ONNX Runtime cannot load it.
        ValueError: CUDA requested without the CUDA execution provider.
    """
    try:
        import onnxruntime as ort
    except ImportError as exc:
        raise ImportError("onnxruntime is needed to run .onnx models: pip install 'murk[onnx]'") from exc
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
        return ort.InferenceSession(str(path), opts, providers=providers)
    except Exception as exc:
        raise InputFileError(path, f"not a loadable ONNX model ({type(exc).__name__}: {exc})") from exc
