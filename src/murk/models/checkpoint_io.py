"""Safe reading of PyTorch checkpoint files, shared by every network murk loads (Joint-ID, UDAformer,
URSCT-SESR).

Files are read with ``torch.load(weights_only=True)``: tensors and plain data only, plus exactly the numpy
globals a plain numeric array needs (the official Joint-ID file pickles one). A file that pickles anything
else (an optimiser object, a model class), and a plain pickle written by ``pickle.dump``, is refused with a
message that names ``--trust-checkpoint`` (and, for ``murk live``, which has no such flag, the ONNX export) and
why; ``trust=True`` loads it with ``weights_only=False``, a plain pickle with ``pickle.load`` (this runs code from
the file: trusted files only).
"""

from __future__ import annotations

import pickle
import warnings
import zipfile
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeGuard, TypeVar

from murk._version import __version__
from murk.errors import InputFileError

if TYPE_CHECKING:
    import torch

C = TypeVar("C")
"""The configuration type of a network (what :func:`read_network_config` returns)."""


def numpy_array_globals() -> list[Any]:
    """The pickle globals a plain numeric numpy array needs, under the names numpy 1.x and 2.x write."""
    import numpy as np

    try:
        from numpy._core.multiarray import _reconstruct
    except ImportError:  # numpy < 2
        from numpy.core.multiarray import _reconstruct  # type: ignore[no-redef]
    numeric_dtype_classes = {type(np.dtype(code)) for code in "?bhilqBHILQefdgFDG"}  # no object/str/void
    return [
        (_reconstruct, "numpy.core.multiarray._reconstruct"),
        (_reconstruct, "numpy._core.multiarray._reconstruct"),
        np.ndarray,
        np.dtype,
        *sorted(numeric_dtype_classes, key=lambda c: c.__name__),
    ]


def _global_names(item: Any) -> list[str]:
    obj, name = item if isinstance(item, tuple) else (item, None)
    return [name or f"{obj.__module__}.{obj.__qualname__}"]


def unsafe_globals(path: Path) -> list[str]:
    """Pickle globals of a (zip-format) checkpoint outside torch's and our allow-list; [] when unknown."""
    import torch

    if not zipfile.is_zipfile(path):
        return []
    try:
        found = torch.serialization.get_unsafe_globals_in_checkpoint(path)
    except Exception:
        return []
    allowed = {name for item in numpy_array_globals() for name in _global_names(item)}
    return [g for g in found if g not in allowed]


def first_line(exc: BaseException) -> str:
    """A one-line reason: torch's weights-only errors bury it after 'WeightsUnpickler error:'."""
    text = str(exc).split("WeightsUnpickler error:")[-1]
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    return f"{type(exc).__name__}: {lines[0] if lines else ''}"


TRUST_HINT = (
    "If you made this file or trust where it comes from, allow it with --trust-checkpoint (murk enhance, "
    "compare, export), model.trust_checkpoint: true in a murk train config, or trust=True in Python (murk live "
    "has no such flag: for jointid or lite, export the file once with murk export --checkpoint FILE "
    "--trust-checkpoint --out model.onnx and run --method 'jointid?checkpoint=model.onnx'): the file is then "
    "unpickled in full, which runs any code it holds. It is off by default so that a checkpoint from elsewhere "
    "cannot run code on this machine; checkpoints written by murk never need it."
)
"""How a refused checkpoint can be allowed, and why it is refused by default (part of every refusal)."""

_TORCH_LEGACY_MAGIC = b"\x80\x02\x8a\nl\xfc\x9cF\xf9 j\xa8P\x19"
"""The first bytes of a file written by ``torch.save`` in the legacy (pre-1.6, non-zip) format: its pickled magic
number."""


def is_plain_pickle(path: Path) -> bool:
    """Whether ``path`` is a Python pickle written by ``pickle.dump`` (not by ``torch.save``, which writes a zip
    file, or in its legacy format a pickled magic number first). ``torch.load`` cannot read such a file."""
    try:
        with open(path, "rb") as f:
            head = f.read(len(_TORCH_LEGACY_MAGIC))
    except OSError:
        return False
    return head[:1] == b"\x80" and not head.startswith(_TORCH_LEGACY_MAGIC) and not zipfile.is_zipfile(path)


def pickle_globals(path: Path) -> list[str]:
    """The ``module.name`` globals a plain pickle refers to (read with :mod:`pickletools`, nothing is run);
    [] when the file cannot be parsed."""
    import pickletools

    found: list[str] = []
    strings: list[str] = []
    try:
        with open(path, "rb") as f:
            for op, arg, _ in pickletools.genops(f):
                if op.name == "GLOBAL" and isinstance(arg, str):
                    found.append(arg.replace(" ", "."))
                elif op.name == "STACK_GLOBAL" and len(strings) >= 2:
                    found.append(f"{strings[-2]}.{strings[-1]}")
                if isinstance(arg, str) and "UNICODE" in op.name:
                    strings.append(arg)
    except Exception:
        return []
    return sorted(set(found))


def checkpoint_file(path: str | Path) -> Path:
    """``path`` as a Path when it is an existing file (checked before torch is imported: a usage error answers
    at once).

    Raises:
        InputFileError: the file does not exist, or is not a file.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "checkpoint not found" if not path.exists() else "not a file")
    return path


def torch_load(path: str | Path, *, trust: bool = False, hint: str = "") -> Any:
    """Read a checkpoint file onto the CPU, with ``weights_only=True`` unless ``trust``.

    Args:
        path: the file.
        trust: load with ``weights_only=False`` (runs arbitrary pickled code: only for files you trust).
        hint: appended to the refusal message (e.g. what the official file is known to pickle).

    Raises:
        InputFileError: missing or unreadable file, or a pickle that ``weights_only`` refuses (the message
            names ``--trust-checkpoint`` and the objects found).
    """
    import torch

    path = checkpoint_file(path)
    plain = is_plain_pickle(path)
    if trust:
        try:
            if plain:  # pickle.dump's file: torch.load cannot read it (no magic number); trusted, so unpickled
                with open(path, "rb") as f:
                    return pickle.load(f)  # the user vouched for this file with trust=True
            return torch.load(path, map_location="cpu", weights_only=False)
        except Exception as exc:
            raise InputFileError(path, f"not a readable PyTorch checkpoint ({first_line(exc)})") from exc
    if plain:
        what = ", ".join(pickle_globals(path)) or "Python objects"
        raise InputFileError(
            path,
            f"refusing to load it: a plain Python pickle (written by pickle.dump, not torch.save) of {what}, and "
            f"unpickling it can run code from the file. {TRUST_HINT}{' ' + hint if hint else ''}",
        )
    try:
        with torch.serialization.safe_globals(numpy_array_globals()), warnings.catch_warnings():
            warnings.filterwarnings("ignore", message="Detected pickle protocol")  # a refusal follows, not a hint
            return torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        unsafe = unsafe_globals(path)
        if not unsafe and "add_safe_globals" not in str(exc):  # not a refusal: a broken or foreign file
            raise InputFileError(path, f"not a readable PyTorch checkpoint ({first_line(exc)})") from exc
        what = ", ".join(unsafe) or "objects other than tensors and plain data"
        raise InputFileError(
            path,
            f"refusing to load it with weights_only=True: it pickles {what}, and unpickling arbitrary objects "
            f"can run code from the file. {TRUST_HINT}{' ' + hint if hint else ''}",
        ) from exc
    except Exception as exc:
        raise InputFileError(path, f"not a readable PyTorch checkpoint ({first_line(exc)})") from exc


def is_state_dict(obj: Any) -> TypeGuard[Mapping[str, torch.Tensor]]:
    """A non-empty mapping whose values are all tensors."""
    import torch

    return isinstance(obj, Mapping) and bool(obj) and all(isinstance(v, torch.Tensor) for v in obj.values())


def strip_prefixes(key: str, prefixes: Iterable[str]) -> str:
    """``key`` without any of ``prefixes`` at its start (repeatedly: ``module._orig_mod.x`` -> ``x``)."""
    prefixes = tuple(prefixes)
    changed = True
    while changed:
        changed = False
        for p in prefixes:
            if key.startswith(p):
                key, changed = key[len(p) :], True
    return key


def check_state_dict(
    path: Path, state: Mapping[str, torch.Tensor], expected: Mapping[str, tuple[int, ...]], what: str
) -> None:
    """Raise unless ``state`` has exactly the names and shapes of ``expected`` (a strict load would pass).

    Raises:
        InputFileError: missing/unexpected keys or shape mismatches (counted, with examples), naming ``what``.
    """
    missing = [k for k in expected if k not in state]
    unexpected = [k for k in state if k not in expected]
    wrong = [k for k in expected if k in state and tuple(state[k].shape) != tuple(expected[k])]
    if missing or unexpected or wrong:
        parts = []
        if missing:
            parts.append(f"{len(missing)} missing keys (e.g. {', '.join(missing[:3])})")
        if unexpected:
            parts.append(f"{len(unexpected)} unexpected keys (e.g. {', '.join(unexpected[:3])})")
        if wrong:
            k = wrong[0]
            parts.append(f"{len(wrong)} shape mismatches (e.g. {k}: {tuple(state[k].shape)} != {tuple(expected[k])})")
        raise InputFileError(path, f"not a {what} checkpoint: " + "; ".join(parts))


def extract_state_dict(
    obj: Any, path: Path, containers: tuple[str, ...], what: str
) -> tuple[dict[str, torch.Tensor], str]:
    """The state dict inside a loaded checkpoint: ``obj[key]`` for the first of ``containers`` present, or
    ``obj`` itself when it is a bare state dict. Returns (state dict, where it was found: a key or "state_dict").

    Raises:
        InputFileError: no state dict of tensors where expected.
    """
    if isinstance(obj, Mapping):
        for key in containers:
            if key in obj:
                if not is_state_dict(obj[key]):
                    raise InputFileError(path, f"the checkpoint's [{key!r}] is not a state dict of tensors")
                return dict(obj[key]), key
    if is_state_dict(obj):
        return dict(obj), "state_dict"
    keys = " or ".join(repr(k) for k in containers)
    raise InputFileError(
        path, f"not a {what} checkpoint (expected a dict with {keys} holding the weights, or a state dict)"
    )


def check_meta(name: str, value: Any) -> None:
    """Raise TypeError unless ``value`` is plain data that ``torch.load(weights_only=True)`` accepts (numbers,
    strings, None, tensors, lists/dicts of them), naming the offending entry."""
    import torch

    if value is None or isinstance(value, (bool, int, float, str, torch.Tensor)):
        return
    if isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            check_meta(f"{name}[{i}]", v)
        return
    if isinstance(value, dict):
        for k, v in value.items():
            if not isinstance(k, (str, int)):
                raise TypeError(f"{name}: expected str or int keys, got {type(k).__name__}")
            check_meta(f"{name}[{k!r}]", v)
        return
    raise TypeError(
        f"{name}: expected numbers, strings, None, tensors or lists/dicts of them (weights_only-safe), "
        f"got {type(value).__name__}"
    )


def write_checkpoint(path: str | Path, obj: dict[str, Any]) -> Path:
    """Write a checkpoint dict atomically (fsynced; a crash leaves no partial file under ``path``) after checking
    that its ``meta`` is weights_only-safe (:func:`check_meta`). Used by every murk checkpoint writer."""
    import os

    import torch

    from murk.io.atomic import atomic_path

    for key, value in obj.get("meta", {}).items():
        check_meta(f"meta[{key!r}]", value)
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            torch.save(obj, f)
            f.flush()
            os.fsync(f.fileno())
    return path


def write_network_checkpoint(
    path: str | Path, net: Any, *, format_name: str, format_version: int, variant: str | None, meta: dict[str, Any]
) -> Path:
    """Write murk's own checkpoint of a network (Joint-ID, lite) atomically with :func:`write_checkpoint`:
    ``{"format": format_name, "format_version", "murk_version", "variant", "config": net.config.to_dict(),
    "state_dict"`` (detached, on the CPU, contiguous) ``, "meta"`` (with the network's input balance:
    :func:`with_input_balance`) ``}``."""
    return write_checkpoint(
        path,
        {
            "format": format_name,
            "format_version": format_version,
            "murk_version": __version__,
            "variant": variant,
            "config": net.config.to_dict(),
            "state_dict": {k: v.detach().cpu().contiguous() for k, v in net.state_dict().items()},
            "meta": with_input_balance(net, meta),
        },
    )


def read_network_config(
    path: Path,
    obj: Mapping[str, Any],
    parse: Callable[[dict[str, Any]], C],
    *,
    format_version: int,
    kind: str,
    net: str,
) -> C:
    """The network configuration of murk's own checkpoint ``obj`` (:func:`write_network_checkpoint`), read back
    with ``parse`` (the config class's ``from_dict``) once its format version is the one expected.

    Raises:
        InputFileError: another ``format_version`` (``"{kind} format_version ... is not supported"``), or a
            missing or invalid ``config`` (``"invalid {net} configuration in the checkpoint (...)"``).
    """
    version = obj.get("format_version")
    if version != format_version:
        raise InputFileError(path, f"{kind} format_version {version!r} is not supported (expected {format_version})")
    try:
        return parse(dict(obj["config"]))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputFileError(path, f"invalid {net} configuration in the checkpoint ({exc})") from exc


INPUT_BALANCE_KEY = "input_balance_pct"
"""The checkpoint metadata key (and the network attribute) of the simplest colour balance a network's input takes
(``model.input_balance_pct`` of ``murk train``; :mod:`murk.restore_ops.balance`): the percentage saturated at each
end of each channel, or None."""


def input_balance_of(meta: Mapping[str, Any]) -> float | None:
    """The input colour balance a checkpoint's network was trained with: ``meta["input_balance_pct"]``, else the
    training configuration's ``model.input_balance_pct`` (checkpoints written by ``murk train``), else None."""
    value = meta.get(INPUT_BALANCE_KEY)
    if value is None:
        config = meta.get("config")
        model = config.get("model") if isinstance(config, Mapping) else None
        value = model.get(INPUT_BALANCE_KEY) if isinstance(model, Mapping) else None
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0.0 <= float(value) < 50.0:
        raise ValueError(f"{INPUT_BALANCE_KEY}: expected a percentage in [0, 50) or None, got {value!r}")
    return float(value)


def with_input_balance(model: Any, meta: dict[str, Any]) -> dict[str, Any]:
    """``meta`` with the network's ``input_balance_pct`` attribute recorded (when set and not already there)."""
    value = getattr(model, INPUT_BALANCE_KEY, None)
    if value is not None and INPUT_BALANCE_KEY not in meta:
        meta = {**meta, INPUT_BALANCE_KEY: float(value)}
    return meta
