"""What ``murk export`` does: a checkpoint (Joint-ID, ``lite``, or one of the paper's baselines) to an ONNX file,
verified with ONNX Runtime against torch (:func:`export_checkpoint`).

Every graph takes ONE input, ``image`` (B, 3, H, W) float32 RGB in [0, 1], and returns what murk's restorer
returns for it (normalisation, padding, working image and clamping are inside the graph):

- Joint-ID (murk's checkpoints or the official ``.pth``): dynamic batch, height and width (any size), outputs
  ``depth_m`` and ``enhanced`` (:mod:`murk.models.jointid.onnx_export`).
- ``lite`` (told apart by the file's format): dynamic batch, height and width (any size), output ``enhanced``
  (:mod:`murk.models.lite.onnx_export`).
- ``udaformer``, ``ursct``: ONE frame size, dynamic batch, output ``enhanced`` (:mod:`murk.models.baseline_onnx`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from murk.models.checkpoint_io import checkpoint_file

ExportModel = Literal["auto", "udaformer", "ursct"]
EXPORT_MODELS: tuple[str, ...] = ("auto", "udaformer", "ursct")

VERIFY_TOLERANCE = 1e-3
"""Max absolute difference (depth in metres, enhanced in [0, 1]) allowed between ONNX Runtime and torch."""

_JOINTID_SIZES = ((61, 97), (96, 64))
"""(H, W) of the two random frames a Joint-ID export is verified on (the first padded inside the graph)."""


@dataclass(frozen=True)
class ExportCheck:
    """One verification run: ``label`` says on what input (``"64x96"``, ``"batch 2 at 40x24"``), ``max_abs_diff``
    maps each output of the graph to max |ONNX Runtime - torch|."""

    label: str
    max_abs_diff: dict[str, float]


@dataclass(frozen=True)
class ExportedModel:
    """What :func:`export_checkpoint` wrote."""

    path: Path
    kind: str
    """``jointid``, ``lite``, ``udaformer`` or ``ursct``."""
    parameters: int
    """Parameters of the exported network (``lite``: folded)."""
    checks: tuple[ExportCheck, ...]
    """Empty when not verified."""
    fixed_size_hw: tuple[int, int] | None = None
    """The only (H, W) the graph takes (the baselines); None for dynamic height and width."""


def max_opset() -> int:
    """The highest ONNX opset the installed torch's TorchScript-based exporter (the one murk uses) writes."""
    try:
        from torch.onnx import _constants

        return int(_constants.ONNX_TORCHSCRIPT_EXPORTER_MAX_OPSET)
    except (ImportError, AttributeError):  # a torch without the constant: let its exporter decide
        return 10**6


def export_checkpoint(
    checkpoint: str | Path,
    out: str | Path,
    *,
    model: str = "auto",
    size_hw: tuple[int, int] = (256, 256),
    opset: int = 17,
    verify: bool = True,
    trust: bool = False,
    tolerance: float = VERIFY_TOLERANCE,
    exposure: str | None = None,
) -> ExportedModel:
    """Export ``checkpoint`` to the ONNX file ``out`` and (``verify``) compare ONNX Runtime with torch.

    Args:
        checkpoint: a Joint-ID or ``lite`` checkpoint (``model="auto"``), or UDAformer / URSCT-SESR weights.
        out: the ``.onnx`` file to write (atomically).
        model: ``auto`` (Joint-ID or ``lite``, told apart by the file), ``udaformer`` or ``ursct``.
        size_hw: the baselines' fixed frame size (URSCT-SESR: square, a multiple of 128); ignored otherwise.
        opset: ONNX opset version (>= 14).
        verify: run the file with ONNX Runtime on random inputs and compare with torch.
        trust: allow arbitrary pickled objects in the checkpoint (trusted files only).
        tolerance: the largest difference accepted by the verification.
        exposure: ``lite`` only: ``input`` (the graph keeps the input's exposure, the ``lite`` restorer's default;
            None means it) or ``network`` (:func:`murk.models.lite.network.keep_exposure`). Refused for the other
            networks: Joint-ID's restorer applies its ``exposure`` option outside the graph.

    Raises:
        ValueError: ``out`` does not end in ``.onnx``, an unknown ``model``, an opset above :func:`max_opset`, a
            size the network cannot take, or
            ONNX Runtime differs from torch by more than ``tolerance`` (the file is written all the same).
        InputFileError: the checkpoint cannot be read (or holds pickled objects and ``trust`` is False).
        ImportError: ``verify`` without onnxruntime installed.
    """
    out = Path(out)
    if out.suffix.lower() != ".onnx":
        raise ValueError(f"out: expected a file name ending in .onnx, got {str(out)!r}")
    if model not in EXPORT_MODELS:
        raise ValueError(f"model: expected {', '.join(EXPORT_MODELS)}, got {model!r}")
    if exposure not in (None, "input", "network"):
        raise ValueError(f"exposure: expected input or network, got {exposure!r}")
    if exposure is not None and model != "auto":
        raise ValueError(f"exposure: applies to lite exports only, not to {model}; leave --exposure out")
    checkpoint_file(checkpoint)  # a missing file is reported before torch and the networks are imported
    top = max_opset()  # (imports torch)
    if opset > top:
        raise ValueError(f"opset: this torch exports opsets up to {top} (murk's exporter), got {opset}")
    if model != "auto":
        done = _export_baseline(model, checkpoint, out, size_hw, opset, verify, trust)
    else:
        from murk.models.lite.checkpoint import is_lite_checkpoint

        if is_lite_checkpoint(checkpoint, trust=trust):
            done = _export_lite(checkpoint, out, opset, verify, trust, keep_exposure=exposure != "network")
        elif exposure is not None:
            raise ValueError(
                f"exposure: applies to lite exports only, and {checkpoint} is a Joint-ID checkpoint (its restorer "
                "applies the exposure option outside the graph); leave --exposure out"
            )
        else:
            done = _export_jointid(checkpoint, out, opset, verify, trust)
    for check in done.checks:
        worst = max(check.max_abs_diff.values())
        if worst > tolerance:
            raise ValueError(
                f"{out}: ONNX Runtime differs from torch by {worst:.3g} at {check.label} (tolerance {tolerance}); "
                "the export is not trustworthy"
            )
    return done


def _export_jointid(checkpoint: str | Path, out: Path, opset: int, verify: bool, trust: bool) -> ExportedModel:
    import torch

    from murk.models.jointid import load_checkpoint
    from murk.models.jointid.onnx_export import OnnxJointID, compare_onnx, export_onnx

    net = load_checkpoint(checkpoint, trust=trust)
    export_onnx(net, out, opset=opset)
    checks = []
    if verify:
        runner = OnnxJointID(out)
        g = torch.Generator().manual_seed(0)
        for h, w in _JOINTID_SIZES:
            x = torch.rand(1, 3, h, w, generator=g)
            checks.append(ExportCheck(f"{h}x{w}", compare_onnx(net, runner, x)))
    return ExportedModel(out, "jointid", sum(p.numel() for p in net.parameters()), tuple(checks))


def _export_lite(
    checkpoint: str | Path, out: Path, opset: int, verify: bool, trust: bool, *, keep_exposure: bool
) -> ExportedModel:
    from murk.models.lite.onnx_export import export_lite_checkpoint

    # The lite export checks its own (tighter) tolerance while verifying.
    done = export_lite_checkpoint(checkpoint, out, opset=opset, verify=verify, trust=trust, keep_exposure=keep_exposure)
    checks = tuple(ExportCheck(f"{h}x{w}", {"enhanced": d}) for (h, w), d in done.max_abs_diff.items())
    return ExportedModel(out, "lite", done.parameters, checks)


def _export_baseline(
    name: str, checkpoint: str | Path, out: Path, size_hw: tuple[int, int], opset: int, verify: bool, trust: bool
) -> ExportedModel:
    from murk.models.baseline_onnx import export_baseline_onnx
    from murk.models.udaformer import UDAformer, load_udaformer
    from murk.models.ursct_sesr import URSCT, load_ursct
    from murk.models.ursct_sesr.network import SIZE_MULTIPLE

    h, w = size_hw
    net: UDAformer | URSCT
    if name == "udaformer":
        net = load_udaformer(checkpoint, trust=trust)
    else:
        if h != w or h % SIZE_MULTIPLE:
            raise ValueError(f"size: ursct needs a square size that is a multiple of {SIZE_MULTIPLE}, got {w}x{h}")
        net = load_ursct(checkpoint, trust=trust, img_size=h)
    done = export_baseline_onnx(net, out, size_hw=(h, w), opset=opset, verify=verify)
    checks = tuple(ExportCheck(f"batch {b} at {w}x{h}", {"enhanced": d}) for b, d in done.max_abs_diff.items())
    return ExportedModel(out, name, done.parameters, checks, fixed_size_hw=(h, w))
