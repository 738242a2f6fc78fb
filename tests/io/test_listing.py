"""Recursive listings survive directory-symlink loops and list each real file once (issue 13); they never follow a
loop, and keep each broken or looping link for its one error record (issue 49)."""

from __future__ import annotations

import glob
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.enhance.api import resolve_input
from murk.io import list_images
from murk.io.listing import describe_unusable, glob_files, is_folder_loop, real_path, walk_files

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
    # a ** glob never follows a loop either (issue 49; before, sub/**/*.png reached x.png through sub/up): it
    # gives sub's own image and, for a batch command, the loops it did not follow, each to be recorded once
    matched = resolve_input(str(root / "sub" / "**" / "*.png")).images
    assert matched == tuple(root / "sub" / n for n in ("again", "up", "upup", "y.png"))


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


def _links(root: Path) -> dict[str, Path]:
    """The symlink loops and chains of the outside attack corpus (issue 49), beside root/good.png and
    root/sub/deep.png: a self link, a link to its own folder, a link to the parent, a chain to a missing file
    and a chain that cycles."""
    for rel in ("good.png", "sub/deep.png"):
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(root / rel), np.zeros((2, 2, 3), np.uint8))
    links = {
        "self.png": "self.png",
        "loop": ".",
        "sub/up": "..",
        "a.png": "b.png",
        "b.png": "c.png",
        "c.png": "missing.png",
        "x.png": "y.png",
        "y.png": "x.png",
    }
    for rel, target in links.items():
        (root / rel).symlink_to(target)
    return {rel: root / rel for rel in links}


@symlinks
def test_a_walk_keeps_each_broken_or_looping_link_once_and_never_follows_a_loop(tmp_path: Path) -> None:
    root = tmp_path / "in"
    links = _links(root)
    good = [root / "good.png", root / "sub" / "deep.png"]
    assert list_images(root, recursive=True) == good  # a listing for reading: the files, each once
    assert walk_files(root, recursive=True) == good
    assert list_images(root, recursive=True, unusable=True) == sorted([*good, *links.values()])
    # without recursion the folder's own links are kept, and the folder links are not walked, so not kept
    assert list_images(root, unusable=True) == sorted([root / "good.png", *(p for p in links.values() if p.suffix)])
    assert glob_files(str(root / "**" / "*.png"), unusable=True) == sorted([*good, *links.values()])
    assert glob_files(str(root / "*.png"), unusable=True) == sorted(
        [root / "good.png", *(p for r, p in links.items() if "/" not in r and p.suffix)]
    )
    assert glob_files(str(root / "**" / "*.png")) == good


@symlinks
def test_each_broken_or_looping_link_says_what_it_is_and_what_to_do(tmp_path: Path) -> None:
    links = _links(tmp_path / "in")
    why = {rel: describe_unusable(p) for rel, p in links.items()}
    assert (
        why["self.png"]
        == "a symbolic link loop (self.png -> self.png): it never reaches a file; fix or remove the link"
    )
    assert (
        why["x.png"]
        == "a symbolic link loop (x.png -> y.png -> x.png): it never reaches a file; fix or remove the link"
    )
    assert why["a.png"] == (
        "broken symbolic link (a.png -> b.png -> c.png -> missing.png: the last target does not exist): fix or "
        "remove the link"
    )
    assert why["c.png"] == "broken symbolic link (its target missing.png does not exist): fix or remove the link"
    for rel, target in (("loop", tmp_path / "in"), ("sub/up", tmp_path / "in")):
        assert why[rel] is not None and why[rel].startswith(f"a folder loop ({Path(rel).name} -> "), why[rel]
        assert f"which is {target}" in why[rel] and why[rel].endswith(
            "not followed, the files there are taken once under their own paths; remove the link"
        )
    assert describe_unusable(tmp_path / "in" / "good.png") is None


@symlinks
def test_real_path_never_raises_on_a_loop_and_folder_loops_are_links_to_an_ancestor(tmp_path: Path) -> None:
    links = _links(tmp_path / "in")
    assert real_path(links["self.png"]).name == "self.png"  # Path.resolve() raises RuntimeError here before 3.13
    assert real_path(links["a.png"]) == tmp_path / "in" / "missing.png"
    assert is_folder_loop(links["loop"]) and is_folder_loop(links["sub/up"])
    (tmp_path / "other").mkdir()
    (tmp_path / "in" / "linked").symlink_to(tmp_path / "other")  # a folder linked in from elsewhere: no loop
    assert not is_folder_loop(tmp_path / "in" / "linked") and not is_folder_loop(tmp_path / "in" / "sub")
    assert not is_folder_loop(links["self.png"])
