"""Recursive listings survive directory-symlink loops and list each real file once (issue 13)."""

from __future__ import annotations

import glob
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.enhance.pipeline import resolve_input
from murk.io import list_images
from murk.io.listing import glob_files, walk_files

symlinks = pytest.mark.skipif(not hasattr(os, "symlink") or os.name == "nt", reason="needs POSIX symlinks")


def _tree(root: Path) -> Path:
    """root/{x.png, sub/y.png, sub/.hidden/h.png, .dot.png, notes.txt} and a sibling folder other/w.png."""
    for rel in ("x.png", "sub/y.png", "sub/.hidden/h.png", ".dot.png", "../other/w.png"):
        p = root / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(p), np.zeros((2, 2, 3), np.uint8))
    (root / "notes.txt").write_text("not an image")
    return root


@symlinks
def test_symlink_loops_neither_hang_nor_repeat_files(tmp_path: Path) -> None:
    root = _tree(tmp_path / "in")
    (root / "sub" / "up").symlink_to("..")  # a cycle
    (root / "sub" / "upup").symlink_to("../..")  # a second one: glob.glob would take 2^40 steps
    (root / "sub" / "again").symlink_to(root / "sub")  # the same folder under another name
    (root / "alias.png").symlink_to(root / "x.png")  # the same file under another name
    (root / "linked").symlink_to(tmp_path / "other")  # a folder linked in from elsewhere: followed once
    files = list_images(root, recursive=True)
    real = [os.path.realpath(p) for p in files]
    assert len(real) == len(set(real)) == 4
    assert sorted(Path(r).name for r in real) == ["h.png", "w.png", "x.png", "y.png"]
    matched = resolve_input(str(root / "sub" / "**" / "*.png")).images
    real = [os.path.realpath(p) for p in matched]
    assert len(real) == len(set(real)) and {Path(r).name for r in real} >= {"x.png", "y.png"}  # x via the loop


def test_glob_files_matches_glob_glob_where_there_is_no_loop(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Reference: the standard library's glob.glob(recursive=True) (Python 3.11), on a tree without symlinks."""
    _tree(tmp_path / "in")
    monkeypatch.chdir(tmp_path)
    for pattern in ("in/**/*.png", "in/**", "**/*.png", "in/*.png", "in/s*/*.png", "in/**/.hidden/*.png", "*/**/y.*"):
        expected = sorted(Path(p) for p in glob.glob(pattern, recursive=True) if Path(p).is_file())
        assert glob_files(pattern) == expected, pattern
        absolute = str(tmp_path / pattern)
        assert glob_files(absolute) == sorted(Path(p) for p in glob.glob(absolute, recursive=True) if Path(p).is_file())
    assert glob_files("nothing/**/*.png") == []


def test_walk_files_without_recursion_keeps_every_name(tmp_path: Path) -> None:
    root = _tree(tmp_path / "in")
    if hasattr(os, "symlink") and os.name != "nt":
        (root / "alias.png").symlink_to(root / "x.png")  # a deliberate second name in the same folder is kept
    names = [p.name for p in walk_files(root)]
    assert names == sorted(names) and "x.png" in names and "sub" not in names
    assert ("alias.png" in names) == (root / "alias.png").exists()
