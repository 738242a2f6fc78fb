"""Helpers of the fault tests (issue 13): the one-line error contract, a simulated full disk, partial files."""

from __future__ import annotations

import errno
from pathlib import Path
from typing import Any

import cv2
import pytest

from murk.io import atomic
from murk.io.atomic import TMP_PREFIX


def one_line_error(res: Any, code: int = 2) -> str:
    """The command's only ``error:`` line, after checking the exit code and that no traceback was printed."""
    assert res.exit_code == code, res.output
    assert "Traceback" not in res.output and (res.exception is None or isinstance(res.exception, SystemExit))
    lines = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, res.output
    return lines[0]


def fill_disk(monkeypatch: pytest.MonkeyPatch, *, after: int = 0, only: str = "") -> list[str]:
    """Make murk's file writes fail like a full disk: after ``after`` successful writes (of files whose name
    contains ``only``), each write stores half of its bytes and raises ``OSError(ENOSPC)``. Returns the names of
    the final files whose write failed."""
    real = atomic._write_file
    state = {"ok": 0}
    failed: list[str] = []

    def write(path: Path, data: bytes, fsync: bool) -> None:
        if only in path.name and state["ok"] >= after:
            path.write_bytes(data[: len(data) // 2])
            failed.append(path.name.split("-", 3)[-1])  # .murk-tmp-<hex>-<name> -> <name>
            raise OSError(errno.ENOSPC, "No space left on device")
        if only in path.name:
            state["ok"] += 1
        real(path, data, fsync)

    monkeypatch.setattr(atomic, "_write_file", write)
    return failed


def assert_nothing_partial(folder: Path) -> None:
    """No temporary file is left and every image under ``folder`` decodes completely."""
    files = [p for p in folder.rglob("*") if p.is_file()]
    assert not [p for p in files if p.name.startswith(TMP_PREFIX)]
    for p in files:
        if p.suffix.lower() in (".png", ".jpg"):
            assert cv2.imread(str(p), cv2.IMREAD_UNCHANGED) is not None, p
