"""Method specifications of ``murk compare``: ``[LABEL=]METHOD[:CHECKPOINT][?KEY=VALUE,...]``.

``METHOD`` is ``raw`` (the input itself) or any restorer of the enhance registry, chained with ``+``
(``post``, ``jointid``, ``jointid+post``, the paper's baselines ``udaformer`` and ``ursct``); ``CHECKPOINT`` is
the method's weights: for Joint-ID a murk checkpoint, the official ``joint_id_ckpt.pth``, or an ``.onnx``
export (without it Joint-ID uses the weights shipped with murk, the ``small`` model murk trained itself,
``docs/models.md``); for the baselines the file downloaded from their authors (``docs/baselines.md``).
Examples::

    raw
    post
    jointid+post
    original=jointid:joint_id_ckpt.pth
    retrained+post=jointid+post:runs/base-gpu/best.pt
    clahe=post?he=clahe,clahe_clip=3
    udaformer:weights/UDA.pt
    ursct-256=ursct:weights/model_bestSSIM.pth?policy=official

Options after ``?`` go to that method's restorer only (the options its factory declares, e.g. ``he``,
``sigma_px``, ``lam``, ``clahe_clip``, ``clahe_tiles`` for ``post``; ``precision``, ``tile``, ``overlap``,
``policy``, ... for the networks; ``murk.enhance.restorer.options_of(name)`` lists them). An option that no stage of the
method declares is an error naming the valid ones (``post?lamda=0.9`` suggests ``lam``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from murk.enhance.options import parse_spec


@dataclass(frozen=True)
class MethodSpec:
    """One method to compare: what the user wrote, a display label, the restorer spec and its checkpoint."""

    text: str
    label: str
    method: str
    checkpoint: str | None = None
    options: tuple[tuple[str, Any], ...] = ()


def parse_method(text: str) -> MethodSpec:
    """Parse ``[LABEL=]METHOD[:CHECKPOINT][?KEY=VALUE,...]`` (options: :func:`murk.enhance.options.parse_spec`).

    Raises:
        ValueError: empty parts, options that are not ``KEY=VALUE``, or ``trust_checkpoint`` in the spec.
    """
    raw = text.strip()
    body, options = parse_spec(raw)
    label, _, rest = body.partition("=") if "=" in body else ("", "", body)
    method, _, ckpt = rest.partition(":")
    method, ckpt, label = method.strip(), ckpt.strip(), label.strip()
    if not method:
        raise ValueError(f"--method: expected [LABEL=]METHOD[:CHECKPOINT], got {text!r}")
    if not label:
        label = method if not ckpt else f"{method}:{Path(ckpt).parent.name or Path(ckpt).stem}"
    return MethodSpec(raw, label, method, ckpt or None, tuple(options.items()))


def build_restorer(spec: MethodSpec, **shared: Any) -> Any:
    """The restorer of ``spec`` (None for ``raw``), built through the enhance registry.

    ``shared`` are the command's settings (device, precision, ...): each stage takes those it declares. The
    spec's own options and checkpoint must be options of the method (misspelt ones are an error).
    """
    from murk.enhance.restorer import create

    extra = _method_options(spec)
    return None if extra is None else create(spec.method, shared=shared, **extra)


def check_method(spec: MethodSpec, **shared: Any) -> None:
    """Raise what :func:`build_restorer` would raise about the method's names and options, without building it
    (no weights read, torch not imported)."""
    from murk.enhance.restorer import check

    extra = _method_options(spec)
    if extra is not None:
        check(spec.method, shared=shared, **extra)


def _method_options(spec: MethodSpec) -> dict[str, Any] | None:
    """The spec's options and checkpoint as keyword arguments of the registry; None for ``raw``."""
    if spec.method == "raw":
        if spec.options or spec.checkpoint:
            raise ValueError(
                f"--method {spec.text}: raw (the input itself) takes no checkpoint or options; write it as plain raw"
            )
        return None
    extra = dict(spec.options)
    if spec.checkpoint:
        key = "onnx" if spec.checkpoint.lower().endswith(".onnx") else "checkpoint"
        extra[key] = spec.checkpoint
    return extra
