"""What the training loop needs from each network kind (``model.kind``): build it (with its initialisation and
starting weights), run it on RGB in [0, 1], and read/write its checkpoints.

- ``jointid``: :mod:`murk.models.jointid`; input normalised with the recipe's mean/std; enhanced + depth;
  sizes multiples of 32.
- ``lite``: :mod:`murk.models.lite`; RGB in [0, 1] as is; enhanced only (no depth: the SILog term and the
  depth evaluation are skipped); sizes multiples of 16. Trained in its multi-branch form; checkpoints hold that
  form and are folded when loaded for inference.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import torch
from torch import Tensor, nn

from murk.train.config import ModelConfig


def has_depth(kind: str) -> bool:
    """Whether networks of ``kind`` estimate depth."""
    return kind == "jointid"


def size_multiple(kind: str) -> int:
    """Input height and width must be multiples of this."""
    if kind == "lite":
        from murk.models.lite.network import SIZE_MULTIPLE

        return SIZE_MULTIPLE
    from murk.models.jointid import SIZE_MULTIPLE as JOINTID_MULTIPLE

    return JOINTID_MULTIPLE


def build_network(config: ModelConfig) -> nn.Module:
    """The randomly initialised network of ``config`` (call after seeding torch), with the weights of
    ``config.init_checkpoint`` when given (strict)."""
    if config.kind == "lite":
        from murk.models.lite.network import build_lite

        model: nn.Module = build_lite(config.variant)
    else:
        from murk.models.jointid import VARIANTS, build_jointid
        from murk.models.jointid.network import icnr_init_

        model = build_jointid(replace(VARIANTS[config.variant], global_colour=config.global_colour))
        if config.init == "icnr":
            icnr_init_(model)
    if config.init_checkpoint:
        state, _ = read_network_checkpoint(config.kind, config.init_checkpoint, trust=config.trust_checkpoint)
        _load_init_state(model, state, config.init_checkpoint)
    model.input_balance_pct = config.input_balance_pct  # type: ignore[assignment]  # recorded in its checkpoints
    return model


def _load_init_state(model: nn.Module, state: dict[str, Tensor], path: str) -> None:
    """Load ``state`` strictly, except that a global colour head absent from the file keeps its identity start.

    Raises:
        InputFileError: names or shapes that do not match (beyond the missing head).
    """
    from murk.errors import InputFileError

    head = {n for n in model.state_dict() if n.startswith("global_colour_head.")}
    if head and not head & set(state):
        result = model.load_state_dict(state, strict=False)
        if result.unexpected_keys or set(result.missing_keys) != head:
            raise InputFileError(
                path,
                f"weights do not match the network: missing {sorted(set(result.missing_keys) - head)[:3]}, "
                f"unexpected {result.unexpected_keys[:3]}",
            )
        return
    try:
        model.load_state_dict(state, strict=True)
    except RuntimeError as exc:
        raise InputFileError(path, f"weights do not match the network ({str(exc).splitlines()[0]})") from exc


def load_teacher(spec: str, device: str | torch.device = "cpu") -> tuple[str, nn.Module]:
    """``(kind, network)`` of a distillation teacher (``loss.teacher``): ``lite`` / ``jointid`` (the shipped
    weights) or ``lite:PATH`` / ``jointid:PATH``, on ``device`` in eval mode with its input balance, gradients off.

    Raises:
        ValueError: another kind than lite or jointid.
        InputFileError: the checkpoint cannot be read as that kind.
    """
    kind, _, path = spec.partition(":")
    net: nn.Module
    if kind == "lite":
        from murk.data import shipped_lite_weights
        from murk.models.lite.checkpoint import load_lite

        net = load_lite(path or shipped_lite_weights(), device=device)
    elif kind == "jointid":
        from murk.data import shipped_jointid_weights
        from murk.models.jointid import load_checkpoint

        net = load_checkpoint(path or shipped_jointid_weights(), device=device)
    else:
        raise ValueError(f"teacher: expected lite, jointid, lite:PATH or jointid:PATH, got {spec!r}")
    net.requires_grad_(False)
    return kind, net.eval()


def frozen_parameter_names(kind: str, model: nn.Module) -> list[str]:
    """Parameters never used in ``forward`` (kept for checkpoint compatibility; frozen for DDP)."""
    if kind == "lite":
        return []
    from murk.models.jointid import unused_parameter_names

    return list(unused_parameter_names(model))


def trainable_parameter_names(config: ModelConfig, model: nn.Module) -> set[str]:
    """The parameters ``config.trainable`` lets the optimiser change: all, the depth head's, the enhancement head's
    or the colour head's."""
    if config.trainable == "depth_head":
        from murk.models.jointid import depth_head_parameter_names

        return set(depth_head_parameter_names(model))
    if config.trainable == "enhance_head":
        from murk.models.jointid import enhance_head_parameter_names

        return set(enhance_head_parameter_names(model))
    if config.trainable == "colour_head":
        return {n for n, _ in model.named_parameters() if n.startswith("global_colour_head.")}
    return {n for n, _ in model.named_parameters()}


def run_network(
    kind: str, net: nn.Module, images: Tensor, balance_pct: float | None = None
) -> tuple[Tensor, Tensor | None]:
    """``(enhanced, depth_m or None)`` of ``net`` for a batch (B, 3, H, W) of RGB in [0, 1], taken first through
    the simplest colour balance when ``balance_pct`` is set (``model.input_balance_pct``)."""
    if balance_pct is not None:
        from murk.restore_ops.balance import color_balance_torch

        images = color_balance_torch(images, balance_pct, balance_pct).to(images.dtype)
    if kind == "lite":
        return net(images), None
    from murk.models.jointid import normalize_input

    out = net(normalize_input(images))
    return out.enhanced, out.depth_m


def save_network(kind: str, model: nn.Module, path: str | Path, **meta: Any) -> Path:
    """Write a checkpoint of ``model`` in the format of ``kind`` (atomically; loadable with weights_only)."""
    if kind == "lite":
        from murk.models.lite.checkpoint import save_lite_checkpoint

        return save_lite_checkpoint(model, path, **meta)
    from murk.models.jointid import save_checkpoint

    return save_checkpoint(model, path, **meta)


def read_network_checkpoint(
    kind: str, path: str | Path, *, trust: bool = False
) -> tuple[dict[str, torch.Tensor], dict[str, Any]]:
    """The state dict (training form) and the metadata of a checkpoint of ``kind``.

    Raises:
        InputFileError: unreadable file, or a checkpoint of another kind or shape.
    """
    if kind == "lite":
        from murk.models.lite.checkpoint import read_lite_checkpoint

        state, info = read_lite_checkpoint(path, trust=trust)
        return state, info.meta
    from murk.models.jointid import read_checkpoint

    state, jinfo = read_checkpoint(path, trust=trust)
    return state, jinfo.meta
