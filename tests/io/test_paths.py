"""The shared output planner (issue 13): output folders that overlap the inputs, distinct output names."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from murk.io.paths import check_output_location, output_names


def test_output_equal_to_an_input_folder_is_always_refused(tmp_path: Path) -> None:
    inp = tmp_path / "in"
    inp.mkdir()
    (tmp_path / "link").symlink_to(inp)
    for out in (inp, tmp_path / "link", tmp_path / "in" / "."):
        with pytest.raises(
            ValueError, match=rf"^--out {re.escape(str(out))}: this is the input folder {re.escape(str(inp))};"
        ):
            check_output_location(out, [inp], inside="allow")


def test_inside_and_written_subfolders_follow_the_command(tmp_path: Path) -> None:
    inp, out = tmp_path / "in", tmp_path / "in" / "sub" / "out"
    with pytest.raises(
        ValueError, match=rf"^OUT_DIR {re.escape(str(out))}: inside the input folder {re.escape(str(inp))}; "
    ):
        check_output_location(out, [inp], option="OUT_DIR", why="it would loop")
    check_output_location(out, [inp], inside="allow")  # a command that leaves its outputs out of the listing
    depth = tmp_path / "depth" / "raw"
    where = re.escape(str(tmp_path / "depth"))
    with pytest.raises(
        ValueError, match=rf"the input folder {re.escape(str(depth))} lies in its output folder {where}; "
    ):
        check_output_location(tmp_path, [inp, depth], writes=("clean", "depth"))
    check_output_location(tmp_path, [inp, tmp_path / "depth2"], writes=("clean", "depth"))  # not a subfolder
    check_output_location(tmp_path / "elsewhere", [inp, tmp_path / "other"], writes=("depth",))


def test_output_names_keep_names_and_widen_only_collisions() -> None:
    flat = [Path("a/x.jpg"), Path("b/x.png"), Path("b/y.jpg"), Path("c/z.jpg"), Path("c/z.png")]
    assert output_names(flat) == {
        Path("a/x.jpg"): "a_x",
        Path("b/x.png"): "b_x",
        Path("b/y.jpg"): "y",
        Path("c/z.jpg"): "c_z_jpg",
        Path("c/z.png"): "c_z_png",
    }
    root = Path("in")
    mirrored = [root / "x.jpg", root / "x.png", root / "sub" / "x.jpg", Path("elsewhere/q.png")]
    assert output_names(mirrored, root=root) == {
        root / "x.jpg": "x_jpg",
        root / "x.png": "x_png",
        root / "sub" / "x.jpg": "sub/x",
        Path("elsewhere/q.png"): "q",
    }


def test_output_names_counter_never_takes_an_existing_name() -> None:
    paths = [Path("p/x.jpg"), Path("q/p/x.jpg"), Path("p_x_jpg_1.png")]
    names = output_names(paths)
    assert len(set(names.values())) == 3 and names[Path("p_x_jpg_1.png")] == "p_x_jpg_1"
