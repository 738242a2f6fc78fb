"""Listing input files safely: recursive walks and ``**`` globs that survive directory-symlink cycles.

A recursive listing follows directory symlinks (datasets are often linked into a tree) but enters every real
directory once, so a link back to an ancestor (``a/loop -> ..``) cannot make it loop or list a file many times
(``glob.glob(recursive=True)`` follows such a link about 40 times, and two links make it hang). A file reached
through several paths is listed once, under the first of its paths in sorted order.

With ``unusable=True`` a listing also keeps the entries a user meant as inputs but that cannot be read as files:
broken symlinks, FIFOs, sockets and devices, and (recursive) subfolders that cannot be listed. The readers of
murk refuse them with a message saying what they are (:func:`describe_unusable`), so that a batch command
records each as one error instead of silently leaving it out.
"""

from __future__ import annotations

import fnmatch
import glob as globlib
import os
import stat
from collections.abc import Iterable, Sequence
from pathlib import Path

_MAGIC = set("*?[")


def walk_files(folder: str | Path, *, recursive: bool = False, unusable: bool = False) -> list[Path]:
    """Regular files in ``folder`` (sorted; symlinks to files included, broken links left out).

    With ``recursive=True`` every real directory below ``folder`` is entered once (cycles of directory symlinks
    are cut where they close) and every real file is listed once (deduplicated by resolved path). Without it
    only the folder's own entries are listed, each under its own name.

    With ``unusable=True`` the broken symlinks, FIFOs, sockets and devices in the folder(s), and the subfolders
    a recursive walk cannot list, are listed too (see :func:`describe_unusable`).
    """
    folder = Path(folder)
    if not recursive:
        return sorted(p for p in folder.iterdir() if p.is_file() or (unusable and _special(p)))
    seen_dirs: set[tuple[int, int]] = set()
    files: list[Path] = []
    unlisted: list[Path] = []

    def cannot_list(exc: OSError) -> None:
        if exc.filename is not None and os.fspath(exc.filename) != os.fspath(folder):
            unlisted.append(Path(exc.filename))

    for dirpath, dirnames, filenames in os.walk(folder, followlinks=True, onerror=cannot_list):
        key = _dir_key(dirpath)
        if key is None or key in seen_dirs:  # reached again through a symlink: already walked
            dirnames[:] = []
            continue
        seen_dirs.add(key)
        dirnames[:] = [d for d in sorted(dirnames) if _dir_key(os.path.join(dirpath, d)) not in seen_dirs]
        files.extend(Path(dirpath, f) for f in filenames)
    found = unique_files(sorted(p for p in files if p.is_file()))
    if unusable:
        found = sorted([*found, *(p for p in files if _special(p)), *unlisted])
    return found


def _special(path: Path) -> bool:
    """A directory entry that is neither a regular file (or a link to one) nor a directory."""
    try:
        return not path.is_file() and not path.is_dir() and (path.is_symlink() or path.exists())
    except OSError:
        return True


def can_list(folder: str | Path) -> bool:
    """Whether this process may list and enter ``folder`` (read and execute permission)."""
    return os.access(folder, os.R_OK | os.X_OK)


def describe_unusable(path: str | Path) -> str | None:
    """Why ``path`` cannot be read as an input file, or None when it is a readable-looking regular file.

    The reasons: it does not exist (or vanished), it is a broken symlink (naming its target), a folder (one that
    cannot be listed says so), a FIFO, a socket or a device.
    """
    path = Path(path)
    try:
        if path.is_symlink() and not path.exists():
            return f"broken symbolic link (its target {os.readlink(path)} does not exist)"
        st = os.stat(path)
    except FileNotFoundError:
        return "file not found (missing, or removed after the folder was listed)"
    except OSError as exc:
        return f"cannot access it ({exc.strerror or exc})"
    if stat.S_ISREG(st.st_mode):
        return None
    if stat.S_ISDIR(st.st_mode):
        if not can_list(path):
            return "a folder that cannot be listed (permission denied): the files in it were not processed"
        return "a folder, not a file"
    kind = (
        "a FIFO (named pipe)"
        if stat.S_ISFIFO(st.st_mode)
        else "a socket"
        if stat.S_ISSOCK(st.st_mode)
        else "a device"
        if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode)
        else "a special file"
    )
    return f"{kind}, not a regular file: not read"


def glob_files(pattern: str) -> list[Path]:
    """Regular files matching a glob pattern, sorted, each real file once.

    Same matching rules as ``glob.glob(pattern, recursive=True)`` (``**`` = any number of folders; ``*`` and
    ``**`` do not match names starting with a dot), but a ``**`` walk goes through :func:`walk_files`, so
    directory-symlink cycles are entered once.
    """
    parts = Path(pattern).parts
    if "**" not in parts:
        return unique_files(sorted(p for p in map(Path, globlib.glob(pattern)) if p.is_file()))
    n_root = next(i for i, part in enumerate(parts) if _MAGIC & set(part))
    root, pats = Path(*parts[:n_root]) if n_root else Path("."), parts[n_root:]
    if not root.is_dir():
        return []
    return [p for p in walk_files(root, recursive=True) if _match(p.relative_to(root).parts, pats)]


def unique_files(paths: Iterable[Path]) -> list[Path]:
    """``paths`` without the later ones that resolve to a file already listed (order kept)."""
    seen: set[str] = set()
    out: list[Path] = []
    for p in paths:
        real = os.path.realpath(p)
        if real not in seen:
            seen.add(real)
            out.append(p)
    return out


def _dir_key(path: str) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def _match(parts: Sequence[str], pats: Sequence[str]) -> bool:
    """Whether path components ``parts`` match pattern components ``pats`` (glob.glob's rules, see above)."""
    if not pats:
        return not parts
    head = pats[0]
    if head == "**":
        for i in range(len(parts) + 1):
            if _match(parts[i:], pats[1:]):
                return True
            if i < len(parts) and parts[i].startswith("."):
                return False
        return False
    if not parts or (parts[0].startswith(".") and not head.startswith(".")):
        return False
    return fnmatch.fnmatch(parts[0], head) and _match(parts[1:], pats[1:])
