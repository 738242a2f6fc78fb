"""Weights kept as ``.npz`` files (the water estimator, the detail network): float32 arrays plus ``meta`` (JSON text),
read without pickle, written atomically."""

from __future__ import annotations

import json
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from murk.errors import InputFileError

T = TypeVar("T")


def write_npz_weights(path: str | Path, arrays: dict[str, Any], meta: dict[str, Any] | None) -> Path:
    """Write ``arrays`` as float32 and ``meta`` as JSON text to ``path`` (through a temporary file beside it)."""
    target = Path(path)
    stored: dict[str, Any] = {k: np.asarray(v, np.float32) for k, v in arrays.items()}
    stored["meta"] = np.array(json.dumps(meta or {}, sort_keys=True))
    tmp = target.with_name(f".{target.name}.tmp")
    with tmp.open("wb") as fh:
        np.savez(fh, **stored)
    tmp.replace(target)
    return target


def read_npz_weights(
    path: str | Path, what: str, layout: str, build: Callable[[dict[str, np.ndarray], dict[str, Any]], T]
) -> T:
    """``build(arrays, meta)`` of the ``.npz`` file at ``path`` (arrays as stored; ``meta`` {} when absent).

    Raises:
        InputFileError: the file is missing (``"<what> weights not found"``), or it or ``build`` fails (``"not a
            murk <what> (<layout>): <why>"``).
    """
    p = Path(path)
    if not p.is_file():
        raise InputFileError(p, f"{what} weights not found")
    try:
        with np.load(p, allow_pickle=False) as z:
            if not isinstance(z, np.lib.npyio.NpzFile):
                raise ValueError("a single .npy array, not an .npz archive")
            arrays = {k: z[k] for k in z.files if k != "meta"}
            meta = json.loads(str(z["meta"])) if "meta" in z.files else {}
        if not isinstance(meta, dict):
            raise ValueError(f"meta: expected a JSON object, got {type(meta).__name__}")
        return build(arrays, meta)
    except (OSError, ValueError, KeyError, RuntimeError, TypeError, EOFError, zipfile.BadZipFile) as exc:
        # json's errors are ValueErrors; an empty file is an EOFError, a cut one a BadZipFile
        why = "not an .npz archive" if "pickle" in str(exc) else (str(exc).splitlines() or [type(exc).__name__])[0]
        raise InputFileError(p, f"not a murk {what} ({layout}): {why}") from exc
