"""Listing input files safely: recursive walks and ``**`` globs that survive directory-symlink cycles.

A recursive listing follows directory symlinks (datasets are often linked into a tree) but enters every real
directory once, so a link back to an ancestor (``a/loop -> ..``) cannot make it loop or list a file many times
(``glob.glob(recursive=True)`` follows such a link about 40 times, and two links make it hang). A file reached
through several paths is listed once, under the first of its paths in sorted order.
"""

from __future__ import annotations

import fnmatch
import glob as globlib
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

_MAGIC = set("*?[")


def walk_files(folder: str | Path, *, recursive: bool = False) -> list[Path]:
    """Regular files in ``folder`` (sorted; symlinks to files included, broken links left out).

    With ``recursive=True`` every real directory below ``folder`` is entered once (cycles of directory symlinks
    are cut where they close) and every real file is listed once (deduplicated by resolved path). Without it
    only the folder's own entries are listed, each under its own name.
    """
    folder = Path(folder)
    if not recursive:
        return sorted(p for p in folder.iterdir() if p.is_file())
    seen_dirs: set[tuple[int, int]] = set()
    files: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(folder, followlinks=True):
        key = _dir_key(dirpath)
        if key is None or key in seen_dirs:  # reached again through a symlink: already walked
            dirnames[:] = []
            continue
        seen_dirs.add(key)
        dirnames[:] = [d for d in sorted(dirnames) if _dir_key(os.path.join(dirpath, d)) not in seen_dirs]
        files.extend(Path(dirpath, f) for f in filenames)
    return unique_files(sorted(p for p in files if p.is_file()))


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
