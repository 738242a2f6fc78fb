"""JSON-lines files: append one record per line, read back tolerating a torn last line.

Appending a single line with one ``write`` call is the crash-safe way to grow a log; a process killed in the
middle can leave only a partial last line, which :func:`read_jsonl` skips.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from murk.io.atomic import make_output_folder, no_space_as_error, write_text_atomic


def json_safe(obj: Any) -> Any:
    """A copy of nested dicts/lists/tuples in which non-finite floats (NaN, inf) become None (JSON null)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    return obj


def dumps(record: dict[str, Any]) -> str:
    """Serialise one record as a single JSON line (sorted keys, no NaN)."""
    return json.dumps(record, sort_keys=True, allow_nan=False, separators=(",", ":"))


def append_jsonl(path: str | Path, records: Iterable[dict[str, Any]]) -> None:
    """Append ``records`` to ``path`` in one write, flushed and fsynced (a full disk raises ``OutputError``)."""
    text = "".join(dumps(r) + "\n" for r in records)
    if not text:
        return
    path = Path(path)
    with no_space_as_error(path):
        make_output_folder(path.parent)
        with open(path, "a", encoding="utf-8") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())


def read_jsonl(path: str | Path) -> list[dict[str, Any]]:
    """Read every complete record of ``path`` ([] if the file does not exist); a torn last line is skipped."""
    path = Path(path)
    if not path.exists():
        return []
    out = []
    lines = path.read_text(encoding="utf-8").splitlines()
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            if i == len(lines) - 1:
                break  # torn last line of a killed run
            raise ValueError(f"{path}: line {i + 1} is not valid JSON") from None
    return out


def write_jsonl(path: str | Path, records: Iterable[dict[str, Any]]) -> None:
    """Replace ``path`` atomically with ``records``, one per line."""
    write_text_atomic(path, "".join(dumps(r) + "\n" for r in records))
