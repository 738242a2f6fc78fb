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

Options after ``?`` go to that method's restorer only (the same names as ``murk enhance``'s options:
``he``, ``sigma_px``, ``lam``, ``clahe_clip``, ``clahe_tiles``, ``precision``, ``tile``, ``overlap``,
``policy``, ...).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any


@dataclass(frozen=True)
class MethodSpec:
    """One method to compare: what the user wrote, a display label, the restorer spec and its checkpoint."""

    text: str
    label: str
    method: str
    checkpoint: str | None = None
    options: tuple[tuple[str, Any], ...] = ()


def parse_method(text: str) -> MethodSpec:
    """Parse ``[LABEL=]METHOD[:CHECKPOINT]``.

    Raises:
        ValueError: empty parts.
    """
    raw = text.strip()
    body, _, opt_text = raw.partition("?")
    label, _, rest = body.partition("=") if "=" in body else ("", "", body)
    method, _, ckpt = rest.partition(":")
    options = tuple(_parse_option(o, text) for o in opt_text.split(",") if o.strip())
    if any(k == "trust_checkpoint" for k, _ in options):
        raise ValueError(
            f"--method {text}: trust_checkpoint cannot be set inside a method spec (specs end up in scripts and "
            "configs); pass --trust-checkpoint on the command line or trust_checkpoint=True in the API"
        )
    method, ckpt, label = method.strip(), ckpt.strip(), label.strip()
    if not method:
        raise ValueError(f"--method: expected [LABEL=]METHOD[:CHECKPOINT], got {text!r}")
    if not label:
        label = method if not ckpt else f"{method}:{Path(ckpt).parent.name or Path(ckpt).stem}"
    return MethodSpec(raw, label, method, ckpt or None, options)


def _parse_option(item: str, text: str) -> tuple[str, Any]:
    key, sep, value = item.partition("=")
    if not sep or not key.strip():
        raise ValueError(f"--method {text}: expected KEY=VALUE options after '?', got {item!r}")
    v = value.strip()
    for cast in (int, float):
        try:
            return key.strip(), cast(v)
        except ValueError:
            pass
    if v.lower() in ("true", "false"):
        return key.strip(), v.lower() == "true"
    return key.strip(), v


def build_restorer(spec: MethodSpec, **options: Any) -> Any:
    """The restorer of ``spec`` (None for ``raw``), built through the enhance registry."""
    if spec.method == "raw":
        return None
    from murk.enhance.restorer import create

    extra = {**options, **dict(spec.options)}
    if spec.checkpoint:
        key = "onnx" if spec.checkpoint.lower().endswith(".onnx") else "checkpoint"
        extra[key] = spec.checkpoint
    return create(spec.method, **extra)
