"""Joint-ID checkpoint I/O: murk's own format and the official release (``joint_id_ckpt.pth``).

Formats read by :func:`load_checkpoint` (all with ``torch.load(weights_only=True)`` unless ``trust=True``):

- murk: ``{"format": "murk.jointid", "format_version": 1, "config": {...}, "state_dict": {...},
  "meta": {...}, "murk_version": "..."}``, written atomically by :func:`save_checkpoint`;
- official: a dict whose ``"model"`` entry is the state dict with keys prefixed ``structure.``. That file
  also pickles a numpy array, which ``weights_only=True`` refuses by default; exactly the numpy globals needed
  to rebuild a plain array (``_reconstruct``, ``ndarray``, ``dtype``) are allowed, nothing else;
- a bare state dict (official or murk names).

Weights always load with ``strict=True``: a name or shape mismatch is an error that names the file.

Reference: Yang, Kang, Lee, Cho, IEEE Sensors Journal 2023, doi:10.1109/JSEN.2023.3338730.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import torch
from torch import nn

from murk.errors import InputFileError
from murk.models.checkpoint_io import (
    check_state_dict,
    input_balance_of,
    read_network_config,
    strip_prefixes,
    write_network_checkpoint,
)
from murk.models.checkpoint_io import is_state_dict as _is_state_dict
from murk.models.checkpoint_io import torch_load as _torch_load_io
from murk.models.jointid.network import VARIANTS, JointID, JointIDConfig, variant_name
from murk.models.wrapped import unwrap_as

FORMAT = "murk.jointid"
FORMAT_VERSION = 1
_PREFIXES = ("module.", "_orig_mod.", "structure.")

Source = Literal["murk", "official", "state_dict"]


@dataclass(frozen=True)
class CheckpointInfo:
    """What :func:`read_checkpoint` found: the file's format, the network configuration and the metadata."""

    source: Source
    config: JointIDConfig
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def variant(self) -> str | None:
        """``"base"``, ``"tiny"`` or None for a custom configuration."""
        return variant_name(self.config)


def unwrap(model: nn.Module) -> JointID:
    """The :class:`JointID` inside a DistributedDataParallel / DataParallel / ``torch.compile`` wrapper.

    Raises:
        TypeError: no JointID inside ``model``.
    """
    return unwrap_as(model, JointID)


def save_checkpoint(model: nn.Module, path: str | Path, **meta: Any) -> Path:
    """Write ``model`` (weights, configuration) and ``meta`` to ``path`` in murk's format, atomically.

    Args:
        model: a :class:`JointID`, possibly wrapped (DDP, ``torch.compile``).
        path: output file (``.pt``/``.pth`` by convention); parent folders are created.
        **meta: metadata (epoch, step, losses, optimizer state, ...): numbers, strings, None, tensors and
            lists/dicts of them, so that the file loads with ``weights_only=True``.

    Raises:
        TypeError: ``model`` is not a JointID, or a metadata value has another type.
    """
    net = unwrap(model)
    return write_network_checkpoint(
        path, net, format_name=FORMAT, format_version=FORMAT_VERSION, variant=variant_name(net.config), meta=meta
    )


def _strip(key: str) -> str:
    return strip_prefixes(key, _PREFIXES)


def _expected_shapes(config: JointIDConfig) -> dict[str, tuple[int, ...]]:
    with torch.device("meta"):
        model = JointID(config)
    return {k: tuple(v.shape) for k, v in model.state_dict().items()}


def _match_variant(state: dict[str, torch.Tensor]) -> JointIDConfig:
    """The registered variant whose names and shapes differ least from ``state`` (exact match: 0)."""
    shapes = {k: tuple(v.shape) for k, v in state.items()}

    def distance(config: JointIDConfig) -> int:
        expected = _expected_shapes(config)
        return len(expected.keys() ^ shapes.keys()) + sum(expected[k] != shapes[k] for k in expected.keys() & shapes)

    return min(VARIANTS.values(), key=distance)


def read_checkpoint(path: str | Path, *, trust: bool = False) -> tuple[dict[str, torch.Tensor], CheckpointInfo]:
    """Read a Joint-ID checkpoint: the state dict (murk names, no prefix) and what the file says about it.

    Args:
        path: a murk checkpoint, the official ``joint_id_ckpt.pth`` or a bare state dict.
        trust: load with ``weights_only=False`` (runs arbitrary pickled code: only for files you trust).

    Raises:
        InputFileError: missing or unreadable file, a pickle that ``weights_only`` refuses (the message names
            ``--trust-checkpoint``), or names/shapes that do not match the network.
    """
    path = Path(path)
    obj = _torch_load_io(path, trust=trust)
    if isinstance(obj, Mapping) and obj.get("format") == FORMAT:
        config = read_network_config(
            path, obj, JointIDConfig.from_dict, format_version=FORMAT_VERSION, kind="murk checkpoint", net="network"
        )
        raw, source, meta = obj.get("state_dict"), "murk", dict(obj.get("meta") or {})
    elif isinstance(obj, Mapping) and "model" in obj:
        raw, source, config = obj["model"], "official", None
        meta = {k: v for k, v in obj.items() if k != "model" and isinstance(v, (bool, int, float, str))}
    elif _is_state_dict(obj):
        raw, source, config, meta = obj, "state_dict", None, {}
    else:
        raise InputFileError(
            path, "not a Joint-ID checkpoint (expected murk's format, a dict with 'model', or a state dict)"
        )
    if not _is_state_dict(raw):
        raise InputFileError(path, "the checkpoint's weights are not a state dict of tensors")
    state = {_strip(k): v for k, v in raw.items()}
    if config is None:
        config = _match_variant(state)
    check_state_dict(path, state, _expected_shapes(config), f"Joint-ID ({variant_name(config) or 'custom'})")
    return state, CheckpointInfo(source, config, meta)  # type: ignore[arg-type]


def load_checkpoint(path: str | Path, *, trust: bool = False, device: str | torch.device = "cpu") -> JointID:
    """Build the network a checkpoint describes, load its weights (strict) and return it in eval mode.

    Args:
        path: a murk checkpoint (any variant), the official ``joint_id_ckpt.pth`` (``checkpoint['model']``)
            or a bare state dict.
        trust: allow arbitrary pickled objects (``weights_only=False``); the CLI flag is
            ``--trust-checkpoint``.
        device: where the model is moved.

    Raises:
        InputFileError: see :func:`read_checkpoint`.
    """
    state, info = read_checkpoint(path, trust=trust)
    with torch.device("meta"):  # no throw-away initialisation of 150M parameters
        model = JointID(info.config)
    state = {k: v.float() if v.is_floating_point() else v for k, v in state.items()}
    model.load_state_dict(state, strict=True, assign=True)
    model.input_balance_pct = input_balance_of(info.meta)
    return model.to(device).eval()


def slim_checkpoint(src: str | Path, dst: str | Path, *, dtype: torch.dtype = torch.float16, **meta: Any) -> Path:
    """A weights-only copy of a checkpoint for distribution: floating-point weights stored as ``dtype`` (half
    the size in fp16; :func:`load_checkpoint` returns float32 again), the optimiser state and other training
    metadata dropped, ``meta`` (plain data: provenance, metrics) recorded instead. Loads with
    ``weights_only=True``.

    Raises:
        InputFileError: ``src`` cannot be read (see :func:`read_checkpoint`).
    """
    model = load_checkpoint(src)
    return save_checkpoint(model.to(dtype), dst, **meta)


def average_checkpoints(
    srcs: Sequence[str | Path],
    dst: str | Path,
    *,
    weights: Sequence[float] | None = None,
    dtype: torch.dtype = torch.float16,
    **meta: Any,
) -> Path:
    """The weighted average of the weights of checkpoints of one network (a "model soup": Wortsman et al., "Model
    soups: averaging weights of multiple fine-tuned models improves accuracy without increasing inference time",
    ICML 2022), written like :func:`slim_checkpoint` (floating-point weights as ``dtype``, ``meta`` recorded).

    Averaged in float32 with ``weights`` (default: equal; they must be >= 0 and sum to 1); integer buffers come from
    the first checkpoint. The checkpoints must share the architecture and the input balance.

    Raises:
        ValueError: fewer than two checkpoints, bad weights, or checkpoints that differ in architecture or input
            balance (the message names the file).
        InputFileError: a checkpoint cannot be read (see :func:`read_checkpoint`).
    """
    if len(srcs) < 2:
        raise ValueError(f"average_checkpoints: expected at least two checkpoints, got {len(srcs)}")
    w = [1.0 / len(srcs)] * len(srcs) if weights is None else [float(x) for x in weights]
    if len(w) != len(srcs) or min(w) < 0 or abs(sum(w) - 1.0) > 1e-6:
        raise ValueError(f"weights: expected {len(srcs)} values >= 0 that sum to 1, got {list(w)}")
    models = [load_checkpoint(s) for s in srcs]
    first = models[0]
    for src, m in zip(srcs[1:], models[1:], strict=True):
        if m.config != first.config:
            raise ValueError(f"{src}: another architecture than {srcs[0]} ({variant_name(m.config)})")
        if m.input_balance_pct != first.input_balance_pct:
            raise ValueError(
                f"{src}: input_balance_pct {m.input_balance_pct} differs from {srcs[0]}'s {first.input_balance_pct}"
            )
    states = [m.state_dict() for m in models]
    averaged = {
        k: sum(wi * st[k].float() for wi, st in zip(w, states, strict=True)) if v.is_floating_point() else v
        for k, v in states[0].items()
    }
    first.load_state_dict(averaged, strict=True)
    return save_checkpoint(first.to(dtype), dst, **meta)
