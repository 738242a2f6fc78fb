"""The job contract shared by every batch command: one ``errors.jsonl`` schema and one summary.

``errors.jsonl`` (in the output folder; rewritten by every run, absent when nothing failed) holds one JSON
object per failure, always with the same fields::

    {"input": "<path or source>", "stage": "<read|decode|restore|write|...>", "error": "<message>",
     "frame": 12, "variant": 3, "index": 40}      # frame/variant/index only when they apply

A script that drives murk reads every command's failures the same way (:func:`read_errors`).
:class:`JobSummary` holds what a batch command did (processed, skipped, failed, notes, wall time); each
command returns one and the CLI prints it with :func:`summary_line`. Exit codes: 0 when nothing failed,
1 when some inputs failed (:attr:`JobSummary.exit_code`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

from murk.io.jsonl import append_jsonl, read_jsonl, write_jsonl

ERRORS_FILE = "errors.jsonl"

_OPTIONAL = ("frame", "variant", "index")


@dataclass(frozen=True)
class ErrorRecord:
    """One failure: the input it concerns, the stage that failed, the message, and where inside the input."""

    input: str
    stage: str
    error: str
    frame: int | None = None
    variant: int | None = None
    index: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "input", str(self.input))  # a Path is fine; the record holds text

    def to_json(self) -> dict[str, Any]:
        """The ``errors.jsonl`` line: the three required fields plus the optional ones that are set."""
        out: dict[str, Any] = {"input": self.input, "stage": self.stage, "error": self.error}
        for key in _OPTIONAL:
            value = getattr(self, key)
            if value is not None:
                out[key] = int(value)
        return out

    @classmethod
    def from_json(cls, record: dict[str, Any]) -> ErrorRecord:
        """Parse one ``errors.jsonl`` line (unknown keys are an error: the schema is closed)."""
        unknown = set(record) - {"input", "stage", "error", *_OPTIONAL}
        if unknown:
            raise ValueError(f"errors.jsonl record has unknown field(s) {sorted(unknown)}: {record}")
        missing = [k for k in ("input", "stage", "error") if k not in record]
        if missing:
            raise ValueError(f"errors.jsonl record lacks {missing}: {record}")
        return cls(
            input=str(record["input"]),
            stage=str(record["stage"]),
            error=str(record["error"]),
            **{k: (None if record.get(k) is None else int(record[k])) for k in _OPTIONAL},
        )


class ErrorLog:
    """Appends one record per failure to ``<folder>/errors.jsonl`` as it happens (a killed run keeps what it
    recorded). :meth:`start` removes an earlier run's file, so the file lists the latest run's failures only;
    the file is created only when something fails. With ``summary``, every record is also counted there
    (:meth:`JobSummary.add_failure`)."""

    def __init__(self, folder: str | Path, name: str = ERRORS_FILE, summary: JobSummary | None = None) -> None:
        self.path = Path(folder) / name
        self.count = 0
        self.summary = summary
        self._once: set[tuple[str, str, str]] = set()

    def start(self) -> ErrorLog:
        self.path.unlink(missing_ok=True)
        self.count = 0
        self._once.clear()
        return self

    def add_once(self, record: ErrorRecord) -> None:
        """:meth:`add`, unless this run already recorded the same input, stage and error (a failure met again at
        every evaluation of a training run is one failure)."""
        key = (record.input, record.stage, record.error)
        if key not in self._once:
            self._once.add(key)
            self.add(record)

    def add(self, record: ErrorRecord) -> None:
        append_jsonl(self.path, [record.to_json()])
        self.count += 1
        if self.summary is not None:
            self.summary.add_failure(record)
            self.summary.errors_path = self.path

    @property
    def written(self) -> Path | None:
        """The file's path when at least one record was written in this run, else None."""
        return self.path if self.count else None


def write_errors(folder: str | Path, records: list[ErrorRecord], name: str = ERRORS_FILE) -> Path | None:
    """Replace ``<folder>/errors.jsonl`` with ``records`` atomically (remove it when there are none)."""
    path = Path(folder) / name
    if records:
        write_jsonl(path, [r.to_json() for r in records])
        return path
    path.unlink(missing_ok=True)
    return None


def read_errors(path: str | Path) -> list[ErrorRecord]:
    """Read an ``errors.jsonl`` written by any murk command ([] when it does not exist)."""
    return [ErrorRecord.from_json(r) for r in read_jsonl(path)]


_S = TypeVar("_S", bound="JobSummary")


@dataclass
class JobSummary:
    """What a batch command did. ``failed`` counts the records in ``errors_path``; ``failures`` holds them
    (in memory, for the command's printout). Commands with more to say subclass it (extra fields only)."""

    command: str = "job"
    processed: int = 0
    skipped: int = 0
    failed: int = 0
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0
    out: Path | None = None
    errors_path: Path | None = None
    failures: list[ErrorRecord] = field(default_factory=list, repr=False)
    started: float = field(default_factory=time.perf_counter, repr=False)

    def add_failure(self, record: ErrorRecord) -> None:
        """Count one failure (the caller writes it, or :meth:`write_errors` does at the end)."""
        self.failures.append(record)
        self.failed += 1

    def write_errors(self, folder: str | Path, name: str = ERRORS_FILE) -> Path | None:
        """Replace ``<folder>/<name>`` with this run's failures (remove it when there are none) and point
        ``errors_path`` at it."""
        self.failed = len(self.failures)
        self.errors_path = write_errors(folder, self.failures, name)
        return self.errors_path

    def note(self, text: str) -> None:
        """Add a note once (repeats are dropped)."""
        if text not in self.notes:
            self.notes.append(text)

    def finish(self: _S) -> _S:
        """Stamp the wall time since the summary was created."""
        self.wall_s = time.perf_counter() - self.started
        return self

    @property
    def exit_code(self) -> int:
        """0 when nothing failed, 1 when some inputs failed (the CLI's exit status)."""
        return 1 if self.failed else 0

    def to_json(self) -> dict[str, Any]:
        return {
            "command": self.command,
            "processed": self.processed,
            "skipped": self.skipped,
            "failed": self.failed,
            "notes": list(self.notes),
            "wall_s": round(self.wall_s, 3),
            "out": None if self.out is None else str(self.out),
            "errors": None if self.errors_path is None else str(self.errors_path),
        }


class FolderSummary(JobSummary):
    """A job summary of a command that writes one output folder, ``out``."""

    @property
    def out_dir(self) -> Path:
        """The output folder (the working folder when ``out`` is not set)."""
        return Path(self.out or ".")


def summary_line(summary: JobSummary, unit: str = "item", detail: str = "") -> str:
    """The one-line summary every command prints:
    ``<command>: N <unit>s processed, N skipped (already done), N failed (see errors.jsonl) in T s[; detail]``."""
    one = unit[:-1] if unit.endswith("s") else unit
    parts = [f"{summary.processed} {one if summary.processed == 1 else one + 's'} processed"]
    if summary.skipped:
        parts.append(f"{summary.skipped} skipped (already done)")
    if summary.failed:
        where = f" (see {summary.errors_path})" if summary.errors_path else ""
        parts.append(f"{summary.failed} failed{where}")
    line = f"{summary.command}: " + ", ".join(parts) + f" in {summary.wall_s:.1f} s"
    return f"{line}; {detail}" if detail else line
