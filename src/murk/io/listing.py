"""Listing input files safely: recursive walks and ``**`` globs that never follow a symlink loop.

A recursive listing follows directory symlinks (datasets are often linked into a tree) but enters every real
directory once and never follows a link back to its own folder or an ancestor (``loop -> .``, ``a/up -> ..``),
so a loop cannot make it hang or list a file many times (``glob.glob(recursive=True)`` follows such a link
about 40 times, and two links make it hang). A file reached through several paths is listed once, under the
first of its paths in sorted order.

With ``unusable=True`` a listing also keeps the entries a user meant as inputs but that cannot be read as files:
broken symlinks (also at the end of a chain of links), symlink loops (``self.png -> self.png``, ``x -> y -> x``),
FIFOs, sockets and devices, and, in a recursive walk, the folder links it did not follow because they loop and
the subfolders it cannot list. The readers of murk refuse each with a message saying what it is and what to do
(:func:`describe_unusable`), so that a batch command records each as one error instead of crashing or silently
leaving it out.

Paths of listed entries are compared with :func:`real_path`, never ``Path.resolve()``: before Python 3.13 that
raises ``RuntimeError`` on a symlink loop.
"""

from __future__ import annotations

import fnmatch
import glob as globlib
import os
import stat
from collections.abc import Callable, Iterable, Sequence
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

    loops: list[Path] = []
    for dirpath, dirnames, filenames in os.walk(folder, followlinks=True, onerror=cannot_list):
        key = _dir_key(dirpath)
        if key is None or key in seen_dirs:  # reached again through a symlink: already walked
            dirnames[:] = []
            continue
        seen_dirs.add(key)
        keep = []
        for d in sorted(dirnames):
            sub = os.path.join(dirpath, d)
            if is_folder_loop(sub):  # never followed, whether or not its target was walked yet
                loops.append(Path(sub))
            elif _dir_key(sub) not in seen_dirs:
                keep.append(d)
        dirnames[:] = keep
        files.extend(Path(dirpath, f) for f in filenames)
    found = unique_files(sorted(p for p in files if p.is_file()))
    if unusable:
        found = sorted([*found, *(p for p in files if _special(p)), *unlisted, *loops])
    return found


def _special(path: Path) -> bool:
    """A directory entry that is neither a regular file (or a link to one) nor a directory."""
    try:
        return not path.is_file() and not path.is_dir() and (path.is_symlink() or path.exists())
    except OSError:
        return True


def real_path(path: str | Path) -> Path:
    """``path`` absolute with every symlink resolved, as far as it resolves; never raises.

    Use it instead of ``Path.resolve()`` on listed or user-given paths: before Python 3.13 ``resolve()`` raises
    ``RuntimeError`` on a symlink loop (``self.png -> self.png``), which ended folder walks in a traceback.
    """
    return Path(os.path.realpath(path))


def is_folder_loop(path: str | Path) -> bool:
    """Whether ``path`` is a symlink to its own folder or to an ancestor of it (``loop -> .``, ``a/up -> ..``):
    following it would walk the same folders again, without end."""
    if not os.path.islink(path) or not os.path.isdir(path):
        return False
    target = real_path(path)
    return real_path(Path(path).parent).is_relative_to(target)


def _link_chain(path: Path) -> tuple[list[str], bool]:
    """The targets a symlink leads through, as written in each link (``["b.png", "c.png", "missing.png"]``), and
    whether they loop (a link reached twice, or a folder loop on the way that stops resolution)."""
    chain: list[str] = []
    seen: set[tuple[int, int]] = set()
    cur = path
    for _ in range(64):  # the kernel gives up at 40 links
        try:
            st = os.lstat(cur)
        except FileNotFoundError:
            return chain, False
        except OSError:  # ELOOP in a folder on the way
            return chain, True
        if not stat.S_ISLNK(st.st_mode):
            return chain, False
        if (st.st_dev, st.st_ino) in seen:
            return chain, True
        seen.add((st.st_dev, st.st_ino))
        target = os.readlink(cur)
        chain.append(target)
        cur = Path(os.path.join(os.path.dirname(cur), target))
    return chain, True


def _describe_link(path: Path) -> str:
    """Why the symlink ``path`` leads to no file: a loop, or a chain that ends at a path that does not exist."""
    chain, loops = _link_chain(path)
    arrows = " -> ".join([path.name, *chain])
    if loops:
        return f"a symbolic link loop ({arrows}): it never reaches a file; fix or remove the link"
    if len(chain) == 1:
        return f"broken symbolic link (its target {chain[0]} does not exist): fix or remove the link"
    return f"broken symbolic link ({arrows}: the last target does not exist): fix or remove the link"


def can_list(folder: str | Path) -> bool:
    """Whether this process may list and enter ``folder`` (read and execute permission)."""
    return os.access(folder, os.R_OK | os.X_OK)


def describe_unusable(path: str | Path) -> str | None:
    """Why ``path`` cannot be read as an input file, or None when it is a readable-looking regular file.

    The reasons: it does not exist (or vanished), it is a broken symlink (naming its target, or the chain of links
    that ends at a missing one), a symlink loop (``self.png -> self.png``, ``x.png -> y.png -> x.png``), a link
    back to its own folder or an ancestor (a folder loop, not followed), a folder (one that cannot be listed says
    so), a FIFO, a socket or a device. Each says what the user can do about it.
    """
    path = Path(path)
    try:
        if path.is_symlink() and not path.exists():
            return _describe_link(path)
        if is_folder_loop(path):
            return (
                f"a folder loop ({path.name} -> {os.readlink(path)}, which is {real_path(path)} and holds this link): "
                "not followed, the files there are taken once under their own paths; remove the link"
            )
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


def glob_files(pattern: str, *, unusable: bool = False) -> list[Path]:
    """Regular files matching a glob pattern, sorted, each real file once.

    Same matching rules as ``glob.glob(pattern, recursive=True)`` (``**`` = any number of folders; ``*`` and
    ``**`` do not match names starting with a dot), but a ``**`` walk goes through :func:`walk_files`, so
    directory-symlink cycles are never followed.

    With ``unusable=True`` the matching entries that cannot be read as files (broken links, symlink loops,
    FIFOs, devices) are kept, and so are the folder loops and unlistable folders of a ``**`` walk that the
    pattern would have entered (see :func:`walk_files`).
    """
    parts = Path(pattern).parts
    if "**" not in parts:
        listed = sorted(map(Path, globlib.glob(pattern)))
        found = unique_files(p for p in listed if p.is_file())
        return sorted([*found, *(p for p in listed if _special(p))]) if unusable else found
    n_root = next(i for i, part in enumerate(parts) if _MAGIC & set(part))
    root, pats = Path(*parts[:n_root]) if n_root else Path("."), parts[n_root:]
    if not root.is_dir():
        return []
    out = []
    for p in walk_files(root, recursive=True, unusable=unusable):
        rel = p.relative_to(root).parts
        if _match(rel, pats) or (unusable and p.is_dir() and _enters(rel, pats)):
            out.append(p)
    return out


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


def _globstar(parts: Sequence[str], rest: Sequence[str], test: Callable[[Sequence[str], Sequence[str]], bool]) -> bool:
    """``**`` followed by ``rest``: whether ``test(parts[i:], rest)`` holds for some i, ``**`` taking the
    components before i, none of them hidden (glob.glob's rule)."""
    for i in range(len(parts) + 1):
        if test(parts[i:], rest):
            return True
        if i < len(parts) and parts[i].startswith("."):
            return False
    return False


def _match(parts: Sequence[str], pats: Sequence[str]) -> bool:
    """Whether path components ``parts`` match pattern components ``pats`` (glob.glob's rules, see above)."""
    if not pats:
        return not parts
    head = pats[0]
    if head == "**":
        return _globstar(parts, pats[1:], _match)
    if not parts or (parts[0].startswith(".") and not head.startswith(".")):
        return False
    return fnmatch.fnmatch(parts[0], head) and _match(parts[1:], pats[1:])


def _enters(parts: Sequence[str], pats: Sequence[str]) -> bool:
    """Whether a file below the folder ``parts`` could match ``pats`` (so a walk for them enters the folder)."""
    if not pats:
        return False
    if not parts:
        return True
    head = pats[0]
    if head == "**":
        if len(pats) == 1:
            return not any(part.startswith(".") for part in parts)
        return _globstar(parts, pats[1:], _enters)
    if parts[0].startswith(".") and not head.startswith("."):
        return False
    return fnmatch.fnmatch(parts[0], head) and _enters(parts[1:], pats[1:])
