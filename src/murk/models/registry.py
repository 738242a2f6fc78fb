"""A small registry of the networks murk can build by name (``build_model("jointid", variant="tiny")``).

Builders are referenced as ``"module:function"`` strings and imported on first use, so listing the models
does not import torch.
"""

from __future__ import annotations

import importlib
from typing import Any

_BUILDERS: dict[str, str] = {
    "jointid": "murk.models.jointid.network:build_jointid",
    "lite": "murk.models.lite.network:build_lite",
    "udaformer": "murk.models.udaformer.network:build_udaformer",
    "ursct": "murk.models.ursct_sesr.network:build_ursct",
}


def available_models() -> list[str]:
    """Names of the registered networks."""
    return sorted(_BUILDERS)


def register_model(name: str, builder: str) -> None:
    """Register ``builder`` (``"package.module:function"``) under ``name``.

    Raises:
        ValueError: empty name or a builder string without ``:``.
    """
    if not name:
        raise ValueError("name: expected a non-empty model name")
    if ":" not in builder:
        raise ValueError(f"builder: expected 'package.module:function', got {builder!r}")
    _BUILDERS[name] = builder


def build_model(name: str, **kwargs: Any) -> Any:
    """Build the network ``name`` with the builder's keyword arguments (e.g. ``variant="tiny"``).

    Raises:
        ValueError: unknown name (the known ones are listed).
    """
    if name not in _BUILDERS:
        raise ValueError(f"name: unknown model {name!r}; available: {', '.join(available_models())}")
    module, func = _BUILDERS[name].split(":")
    return getattr(importlib.import_module(module), func)(**kwargs)
