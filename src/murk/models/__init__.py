"""Networks (Joint-ID; the comparison baselines UDAformer and URSCT-SESR) and a small registry to build them by name."""

from murk.models.registry import available_models, build_model, register_model

__all__ = ["available_models", "build_model", "register_model"]
