"""Atomic file writes: write to a temporary file in the same folder, then rename over the target.

A killed process leaves either the old file, or no file, never a half-written one. Temporary files keep
the target's extension and start with ``.murk-tmp-`` so that a resumed run can recognise and delete leftovers.

A full disk is one error everywhere: every write helper of murk (:func:`atomic_path` and what builds on it,
:func:`murk.io.jsonl.append_jsonl`, :class:`murk.io.video.VideoSink`) runs under :func:`no_space_as_error`,
which turns ``OSError`` ENOSPC/EDQUOT into :class:`murk.errors.OutputError` ``"PATH: no space left on
device"`` naming the final file (not the temporary one). Image encoders write to memory and Python writes the
bytes (:func:`write_bytes_atomic`): OpenCV's ``imwrite`` does not check ``fclose``, so on a full disk it can
report success for a truncated file.
"""

from __future__ import annotations

import contextlib
import errno
import os
import uuid
from collections.abc import Iterator
from pathlib import Path

from murk.errors import OutputError

TMP_PREFIX = ".murk-tmp-"
NO_SPACE_ERRNOS = frozenset(e for e in (errno.ENOSPC, getattr(errno, "EDQUOT", None)) if e is not None)
"""errno values that mean the device (or the user's quota) is full."""


def no_space_error(path: str | Path, code: int = errno.ENOSPC) -> OutputError:
    """The error murk raises when ``path`` cannot be written for lack of space."""
    quota = " (disk quota exceeded)" if code != errno.ENOSPC else ""
    return OutputError(code, f"no space left on device{quota}", str(path))


UNWRITABLE_ERRNOS = frozenset(
    e for e in (errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOTDIR, errno.EISDIR, errno.ENAMETOOLONG) if e
)
"""errno values that mean a path cannot be written at all (permissions, a read-only file system, a file where a
folder is expected, a name too long)."""


def unwritable_error(path: str | Path, exc: OSError, what: str = "output file") -> OutputError:
    """The error murk raises when the ``what`` at ``path`` cannot be written (names the folder to check)."""
    path = Path(path)
    reason = (exc.strerror or str(exc)).lower()
    if exc.errno in (errno.EACCES, errno.EPERM):
        hint = f"; check that the folder {path.parent} is writable by this user"
    elif exc.errno == errno.EROFS:
        hint = "; the file system is mounted read-only"
    elif exc.errno == errno.ENOTDIR:
        hint = "; a file stands where a folder of this path should be"
    else:
        hint = ""
    return OutputError(int(exc.errno or 0), f"cannot write the {what} ({reason}{hint})", str(path))


@contextlib.contextmanager
def no_space_as_error(path: str | Path, what: str = "output file") -> Iterator[None]:
    """Turn ``OSError`` raised inside the block into :class:`OutputError` naming ``path``: ENOSPC/EDQUOT as
    "no space left on device", permission and read-only errors as "cannot write the <what> (...)"."""
    try:
        yield
    except OutputError:
        raise
    except OSError as exc:
        if exc.errno in NO_SPACE_ERRNOS:
            raise no_space_error(path, int(exc.errno or 0)) from exc
        if exc.errno in UNWRITABLE_ERRNOS:
            raise unwritable_error(path, exc, what) from exc
        raise


def make_output_folder(path: str | Path, what: str = "output folder") -> Path:
    """Create the folder ``path`` (and its parents) if needed; return it.

    Raises:
        OutputError: it cannot be created (permission denied, read-only file system, a file in the way, no
            space), naming the folder and what it is for.
    """
    path = Path(path)
    if path.is_dir():
        return path
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError as exc:  # a file of that name
        raise OutputError(errno.EEXIST, f"cannot create the {what}: a file of this name exists", str(path)) from exc
    except OSError as exc:
        if exc.errno in NO_SPACE_ERRNOS:
            raise no_space_error(path, int(exc.errno or 0)) from exc
        reason = (exc.strerror or str(exc)).lower()
        parent = next((p for p in path.parents if p.exists()), None)
        hint = f"; check that {parent} is writable by this user" if exc.errno in (errno.EACCES, errno.EPERM) else ""
        raise OutputError(int(exc.errno or 0), f"cannot create the {what} ({reason}{hint})", str(path)) from exc
    return path


@contextlib.contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on a clean exit rename it onto ``path``, else delete it.

    Raises:
        OutputError: no space left on the device (or quota) while the block wrote the temporary file; the
            folder cannot be created or written (permission denied, read-only): the message names ``path``.
    """
    path = Path(path)
    tmp = path.with_name(f"{TMP_PREFIX}{uuid.uuid4().hex[:12]}-{path.name}")
    make_output_folder(path.parent)
    try:
        with no_space_as_error(path):
            yield tmp
            os.replace(tmp, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()


def _write_file(path: Path, data: bytes, fsync: bool) -> None:
    """Write ``data`` to a new file ``path``; errors of ``write`` and ``close`` (a full disk) are raised."""
    with open(path, "wb") as f:
        f.write(data)
        if fsync:
            f.flush()
            os.fsync(f.fileno())


def write_bytes_atomic(path: str | Path, data: bytes, *, fsync: bool = True) -> None:
    """Write ``data`` to ``path`` atomically (fsynced before the rename unless ``fsync=False``).

    Raises:
        OutputError: no space left on the device; nothing is left under ``path`` (an older file stays).
    """
    with atomic_path(path) as tmp:
        _write_file(tmp, data, fsync)


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    write_bytes_atomic(path, text.encode("utf-8"))


def remove_stale_temporaries(folder: str | Path) -> int:
    """Delete temporary files left by a killed run below ``folder``; return how many were removed."""
    folder = Path(folder)
    if not folder.is_dir():
        return 0
    count = 0
    for p in folder.rglob(f"{TMP_PREFIX}*"):
        with contextlib.suppress(FileNotFoundError):
            p.unlink()
            count += 1
    return count
