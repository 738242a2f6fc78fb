"""Exception types shared by every layer.

murk follows one validation style at public boundaries: ``TypeError`` for a wrong type, ``ValueError`` (or
one of the subclasses below) for a bad value. Messages name the parameter, what was expected and what was
given; for files they start with the path.
"""

from __future__ import annotations

from pathlib import Path


class ShapeError(ValueError):
    """An array has the wrong shape or number of channels."""


class InputFileError(ValueError):
    """A user-supplied file cannot be used. The message starts with the file's path."""

    def __init__(self, path: str | Path, problem: str) -> None:
        self.path = str(path)
        self.problem = problem
        super().__init__(f"{path}: {problem}")


class OutputError(OSError):
    """An output file could not be written: no space left on device (ENOSPC), disk quota exceeded (EDQUOT), or
    a writer that produced an incomplete file. Fatal for a run: commands stop with exit code 2 and leave nothing
    partial under a final name (a rerun after freeing space resumes).

    Built like ``OSError``: ``OutputError(errno, problem, path)`` (so that it pickles back from a worker process);
    ``str()`` is ``"PATH: problem"``.
    """

    def __str__(self) -> str:
        return f"{self.filename}: {self.strerror}"
