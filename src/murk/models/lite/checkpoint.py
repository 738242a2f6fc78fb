"""``lite`` checkpoint I/O: ``{"format": "murk.lite", "format_version": 1, "variant", "config", "state_dict",
"meta", "murk_version"}``, written atomically, read with ``torch.load(weights_only=True)``.

The state dict is always the TRAINING form (re-parameterisable blocks with their batch norms), so a checkpoint
can be trained further; :func:`load_lite` folds it for inference (:func:`~murk.models.lite.network.reparameterize`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from torch import nn

from murk.errors import InputFileError
from murk.models.checkpoint_io import (
    check_state_dict,
    input_balance_of,
    is_state_dict,
    read_network_config,
    strip_prefixes,
    torch_load,
    write_network_checkpoint,
)
from murk.models.lite.network import LiteConfig, LiteNet, reparameterize, unwrap, variant_name

FORMAT = "murk.lite"
FORMAT_VERSION = 1
_PREFIXES = ("module.", "_orig_mod.")


@dataclass(frozen=True)
class LiteCheckpointInfo:
    """What :func:`read_lite_checkpoint` found: the network configuration and the metadata."""

    config: LiteConfig
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def variant(self) -> str | None:
        """``"base"``, ``"wide"``, ``"tiny"`` or None for a custom configuration."""
        return variant_name(self.config)


def save_lite_checkpoint(model: nn.Module, path: str | Path, **meta: Any) -> Path:
    """Write ``model`` (training form: weights, configuration) and ``meta`` to ``path``, atomically.

    Args:
        model: a :class:`~murk.models.lite.network.LiteNet` in its training form, possibly wrapped (DDP,
            ``torch.compile``).
        path: output file; parent folders are created.
        **meta: metadata (step, metrics, optimiser state, ...): numbers, strings, None, tensors and lists/dicts of
            them, so that the file loads with ``weights_only=True``.

    Raises:
        TypeError: not a LiteNet, or a metadata value of another type.
        ValueError: a folded network (it cannot be trained further; save the training form).
    """
    net = unwrap(model)
    if net.folded:
        raise ValueError("model: a folded (re-parameterised) lite network; save the training form instead")
    return write_network_checkpoint(
        path, net, format_name=FORMAT, format_version=FORMAT_VERSION, variant=variant_name(net.config), meta=meta
    )


def is_lite_checkpoint(path: str | Path, *, trust: bool = False) -> bool:
    """True when ``path`` is a file in the ``murk.lite`` format (memory-mapped read: cheap for any size).

    ``trust``: a file that pickles other objects (an optimiser state) is unpickled in full to tell (runs code
    from the file: only for files the user trusts, as with ``--trust-checkpoint``)."""
    try:
        obj = torch.load(Path(path), map_location="cpu", weights_only=True, mmap=True)
    except Exception:
        if not trust:
            return False
        try:
            obj = torch_load(path, trust=True)
        except Exception:
            return False
    return isinstance(obj, Mapping) and obj.get("format") == FORMAT


def read_lite_checkpoint(
    path: str | Path, *, trust: bool = False
) -> tuple[dict[str, torch.Tensor], LiteCheckpointInfo]:
    """Read a ``lite`` checkpoint: the training-form state dict and what the file says about it.

    Raises:
        InputFileError: missing or unreadable file, a pickle that ``weights_only`` refuses, not the
            ``murk.lite`` format (e.g. a Joint-ID checkpoint: the message says to use ``--method jointid``), or
            names/shapes that do not match the configuration.
    """
    path = Path(path)
    obj = torch_load(path, trust=trust)
    if not isinstance(obj, Mapping) or obj.get("format") != FORMAT:
        found = obj.get("format") if isinstance(obj, Mapping) else None
        raise InputFileError(
            path,
            f"not a murk lite checkpoint (format {found!r}, expected {FORMAT!r}); Joint-ID weights run with "
            "--method jointid, lite weights come from 'murk train' with model.kind: lite",
        )
    config = read_network_config(
        path, obj, LiteConfig.from_dict, format_version=FORMAT_VERSION, kind="murk lite", net="lite network"
    )
    raw = obj.get("state_dict")
    if not is_state_dict(raw):
        raise InputFileError(path, "the checkpoint's weights are not a state dict of tensors")
    state = {strip_prefixes(k, _PREFIXES): v for k, v in raw.items()}
    with torch.device("meta"):
        expected = {k: tuple(v.shape) for k, v in LiteNet(config).state_dict().items()}
    check_state_dict(path, state, expected, f"lite ({variant_name(config) or 'custom'})")
    return state, LiteCheckpointInfo(config, dict(obj.get("meta") or {}))


def load_lite(
    path: str | Path, *, trust: bool = False, device: str | torch.device = "cpu", fold: bool = True
) -> LiteNet:
    """The network a ``lite`` checkpoint describes, in eval mode: folded for inference (default) or in its
    training form (``fold=False``).

    Raises:
        InputFileError: see :func:`read_lite_checkpoint`.
    """
    state, info = read_lite_checkpoint(path, trust=trust)
    model = LiteNet(info.config)
    model.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in state.items()}, strict=True)
    model.eval()
    if fold:
        model = reparameterize(model)
    model.input_balance_pct = input_balance_of(info.meta)
    return model.to(device)


def slim_lite_checkpoint(src: str | Path, dst: str | Path, **meta: Any) -> Path:
    """A weights-only copy of a ``lite`` checkpoint for distribution: the optimiser state and other training
    metadata dropped, ``meta`` (plain data: provenance, metrics) recorded instead; weights stay float32 (the
    whole network is under 0.5 MB). Loads with ``weights_only=True``.

    Raises:
        InputFileError: ``src`` cannot be read (see :func:`read_lite_checkpoint`).
    """
    return save_lite_checkpoint(load_lite(src, fold=False), dst, **meta)
