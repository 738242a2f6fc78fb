"""``murk snow extract`` under faults (issue 13): an output inside its input folder, previews of inputs sharing
a stem, a full disk, error records of earlier runs."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.io import read_jsonl
from murk.snow.bank import load_bank

from .._faults import assert_nothing_partial, fill_disk, one_line_error

runner = CliRunner()


def _frame(path: Path, shift: int = 0) -> Path:
    """A dark frame with three bright 4x4 particles."""
    f = np.full((64, 96, 3), 20, np.uint8)
    for y, x in ((10, 20), (40, 60), (30, 80)):
        f[y + shift : y + shift + 4, x : x + 4] = 230
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), f)
    return path


def _extract(*args: str):
    return runner.invoke(app, ["snow", "extract", *args, "--open-px", "0", "--close-px", "0"])


def test_previews_inside_the_input_folder_are_left_out_of_the_footage(tmp_path: Path) -> None:
    """Issue 31: the preview folder may lie in the footage folder; neither the first run nor a rerun reads the
    previews back as footage."""
    foot = tmp_path / "footage"
    _frame(foot / "f1.png")
    bank = foot / "bank.npz"
    for _ in range(2):  # the first run, then the rerun with the previews in place
        r = _extract(str(foot), "--out", str(bank))
        assert r.exit_code == 0, r.output
        assert [s["path"] for s in load_bank(bank).meta["sources"]] == [str(foot / "f1.png")]
        assert sorted(p.name for p in (foot / "bank_preview").iterdir()) == ["f1.jpg"]
    line = one_line_error(_extract(str(foot / "bank_preview"), "--out", str(foot / "bank.npz")))
    assert f"the preview folder {foot / 'bank_preview'}: this is the input folder" in line


def test_inputs_sharing_a_stem_get_one_preview_each(tmp_path: Path) -> None:
    _frame(tmp_path / "in" / "a" / "x.png")
    _frame(tmp_path / "in" / "b" / "x.png", shift=2)
    r = _extract(str(tmp_path / "in"), "--out", str(tmp_path / "bank.npz"))
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "bank_preview").iterdir()) == ["a_x.jpg", "b_x.jpg"]


@pytest.mark.parametrize("full", ["bank.npz", "x.jpg"])
def test_full_disk_stops_with_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, full: str) -> None:
    _frame(tmp_path / "in" / "x.png")
    fill_disk(monkeypatch, only=full)
    line = one_line_error(_extract(str(tmp_path / "in"), "--out", str(tmp_path / "out" / "bank.npz")))
    where = tmp_path / "out" / ("bank.npz" if full == "bank.npz" else "bank_preview/x.jpg")
    assert line == f"error: {where}: no space left on device"
    assert not (tmp_path / "out" / "bank.npz").exists()
    assert_nothing_partial(tmp_path / "out")


def test_errors_jsonl_lists_the_latest_run_only(tmp_path: Path) -> None:
    _frame(tmp_path / "in" / "x.png")
    (tmp_path / "in" / "bad.png").write_bytes(b"not a png")
    errors = tmp_path / "bank_errors.jsonl"
    assert _extract(str(tmp_path / "in"), "--out", str(tmp_path / "bank.npz")).exit_code == 1
    assert [Path(e["input"]).name for e in read_jsonl(errors)] == ["bad.png"]
    (tmp_path / "in" / "bad.png").unlink()
    r = _extract(str(tmp_path / "in"), "--out", str(tmp_path / "bank.npz"))
    assert r.exit_code == 0, r.output
    assert not errors.exists()


def test_video_footage_is_read_through_io_video_every_nth_frame(tmp_path: Path) -> None:
    """Issue 14: snow extract decodes video with murk.io.video (one list of video suffixes: .wmv included)."""
    from murk.io.video import VIDEO_SUFFIXES

    assert ".wmv" in VIDEO_SUFFIXES and ".flv" in VIDEO_SUFFIXES
    frames = [cv2.imread(str(_frame(tmp_path / f"f{i}.png", shift=i))) for i in range(6)]
    video = tmp_path / "dive.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (96, 64))
    for f in frames:
        writer.write(f)
    writer.release()
    r = _extract(str(video), "--out", str(tmp_path / "bank.npz"), "--every", "2")
    assert r.exit_code == 0, r.output
    assert [s["frame"] for s in load_bank(tmp_path / "bank.npz").meta["sources"]] == [0, 2, 4]
    assert sorted(p.name for p in (tmp_path / "bank_preview").iterdir()) == [
        "dive_f000000.jpg",
        "dive_f000002.jpg",
        "dive_f000004.jpg",
    ]
    assert "snow extract: 3 frames processed" in r.output
