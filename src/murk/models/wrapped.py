"""The network inside the wrappers training puts around it: DistributedDataParallel and DataParallel (its
``module``) and ``torch.compile`` (its ``_orig_mod``), nested up to four deep."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from torch import nn

_Net = TypeVar("_Net")


def unwrap_as(model: nn.Module, cls: type[_Net]) -> _Net:
    """The ``cls`` inside ``model`` (``model`` itself when it is one).

    Raises:
        TypeError: no ``cls`` inside ``model``.
    """
    m: Any = model
    for _ in range(4):
        if isinstance(m, cls):
            return m
        m = getattr(m, "module", None) or getattr(m, "_orig_mod", None)
        if m is None:
            break
    raise TypeError(f"model: expected a {cls.__name__} (optionally wrapped by DDP or torch.compile), got {type(model)}")
