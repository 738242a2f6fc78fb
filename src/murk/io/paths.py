"""Planning output paths: where a command may write, and one distinct name per input.

Checks shared by ``murk synth``, ``murk enhance``, ``murk snow extract``, ``murk compare`` and the commands that
write one file (a bank, a table):

- :func:`check_output_location` refuses an output folder that is an input folder, and, where the command would
  read its own outputs back (a recursive listing on a rerun) or leave an inconsistent dataset (``murk synth``
  into its own RGB-D folder: ``depth/`` rewritten, resized by ``--size``, beside an ``rgb/`` that is not), one
  inside an input folder or one whose output subfolders hold inputs. The refusal is a one-line usage error
  (exit code 2) naming both paths, given before anything is written.
- :func:`check_output_file` refuses an output file that is one of the command's input files.
- :func:`output_names` gives every input a distinct output name, so that ``a/x.jpg`` and ``b/x.png`` never
  write the same ``x.png`` (the second silently replacing the first).

Paths are compared after resolving symlinks, so a link to the input folder is the input folder.
"""

from __future__ import annotations

import os
from collections import Counter
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Literal

Overlap = Literal["refuse", "allow"]


def check_output_file(
    out: str | Path, inputs: Iterable[str | Path | None], *, option: str = "--out", suffixes: Sequence[str] = ()
) -> None:
    """Refuse an output FILE ``out`` (a report, a bank, a table, a video) that would replace a file the command
    reads: one of the input files ``inputs`` (the same path once symlinks are resolved or, ``out`` existing, the
    same file: a hard link, another spelling on a case-insensitive file system), or, for an input folder, an
    existing file inside it whose suffix is one of ``suffixes`` (the kinds of file the command reads from folders).
    ``None`` inputs are skipped.

    Raises:
        ValueError: one line naming ``option``, ``out`` and the input.
    """
    out_real = Path(os.path.realpath(out))
    exists = Path(out).is_file()
    read_here = exists and Path(out).suffix.lower() in suffixes
    for inp in inputs:
        if inp is None:
            continue
        real = Path(os.path.realpath(inp))
        if real == out_real or (exists and _same_file(out, inp)):  # a hard link; a case-insensitive spelling
            raise ValueError(
                f"{option} {out}: this is the input {inp}; writing it would destroy it; choose another file"
            )
        if read_here and real.is_dir() and out_real.is_relative_to(real):
            raise ValueError(
                f"{option} {out}: an input file of {inp}; writing it would destroy it; choose another file"
            )


def _same_file(a: str | Path, b: str | Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them is not there (or cannot be looked at): not the same file
        return False


def check_output_location(
    out: str | Path,
    inputs: Iterable[str | Path],
    *,
    option: str = "--out",
    inside: Overlap = "refuse",
    writes: Sequence[str] = (),
    why: str = "the command would read its own outputs back as inputs",
) -> None:
    """Refuse an output folder ``out`` that overlaps the input folders ``inputs``.

    ``out`` equal to an input is always refused. ``inside="refuse"`` also refuses ``out`` below an input folder
    (for commands that list their inputs recursively and do not leave their outputs out). ``writes`` names the
    subfolders of ``out`` the command writes into (``murk synth``: ``clean``, ``depth``, ...): an input in one
    of them would be overwritten or mixed with outputs. An input folder elsewhere below ``out`` is fine.

    Raises:
        ValueError: one line naming ``option``, ``out``, the input and ``why``.
    """
    out_real = Path(os.path.realpath(out))
    for inp in inputs:
        real = Path(os.path.realpath(inp))
        if out_real == real:
            raise ValueError(
                f"{option} {out}: this is the input folder {inp}; choose another folder ({why}, or overwrite "
                "the inputs)"
            )
        if inside == "refuse" and out_real.is_relative_to(real):
            raise ValueError(f"{option} {out}: inside the input folder {inp}; {why}; choose a folder outside it")
        for sub in writes:
            if real.is_relative_to(out_real / sub):
                raise ValueError(
                    f"{option} {out}: the input folder {inp} lies in its output folder {Path(out) / sub}; {why}; "
                    "choose a folder that does not hold the inputs"
                )


def output_names(
    paths: Sequence[Path], *, root: Path | None = None, sep: str = "_", safe: Callable[[str], str] | None = None
) -> dict[Path, str]:
    """A distinct output name (no suffix) per input path, stable for a given set of inputs.

    Without ``root`` the name is the file stem; where stems collide (``a/x.jpg``, ``b/x.png``) the parent
    folder is prefixed (``a_x``, ``b_x``). With ``root`` the name is the path relative to ``root`` without its
    suffix (``sub/x``), which already differs between folders. Names still shared (``x.jpg`` and ``x.png`` in
    one folder) get the suffix (``x_jpg``, ``x_png``), then a counter. Names that do not collide are left as
    they are, so outputs keep their inputs' names whenever possible.

    Args:
        paths: the inputs (each listed once).
        root: the folder the outputs mirror, or None for flat outputs named by stem.
        sep: the separator of the added parts.
        safe: applied to an added parent-folder name (e.g. to keep it file-name safe).
    """
    fix = safe or (lambda s: s)
    if root is None:
        names = {p: p.stem for p in paths}
        widen: list[Callable[[Path, str], str]] = [lambda p, n: f"{fix(p.parent.name)}{sep}{n}"]
    else:
        names = {
            p: (p.relative_to(root) if p.is_relative_to(root) else Path(p.name)).with_suffix("").as_posix()
            for p in paths
        }
        widen = []
    widen.append(lambda p, n: f"{n}{sep}{p.suffix.lstrip('.')}")
    for step in widen:
        counts = Counter(names.values())
        names = {p: step(p, n) if counts[n] > 1 else n for p, n in names.items()}
    counts, seen = Counter(names.values()), Counter[str]()
    taken = {n for n, c in counts.items() if c == 1}
    for p in paths:
        name = names[p]
        if counts[name] > 1:
            while f"{name}{sep}{seen[name] + 1}" in taken:
                seen[name] += 1
            seen[name] += 1
            names[p] = f"{name}{sep}{seen[name]}"
            taken.add(names[p])
    return names
