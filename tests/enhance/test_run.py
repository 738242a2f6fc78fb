"""murk enhance as one library call (murk.enhance.run): input classification, then the image or frame job."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.enhance.job_common import OutputOptions
from murk.enhance.post import PostRestorer
from murk.enhance.run import run_enhance, weights_line

from ._enhance_helpers import make_frames, make_video


def test_folder_runs_the_image_job_and_shows_progress(tmp_path: Path) -> None:
    folder = tmp_path / "in"
    folder.mkdir()
    for i, frame in enumerate(make_frames(3)):
        assert cv2.imwrite(str(folder / f"{i}.png"), np.ascontiguousarray(frame[:, :, ::-1]))
    seen: list[tuple[str, int | None, bool]] = []
    reports: list[int] = []

    class Display:
        def update(self, report) -> None:
            reports.append(report.processed)

    @contextlib.contextmanager
    def display(title: str, unit: str, total: int | None, live: bool):
        seen.append((unit, total, live))
        yield Display()

    inp, report = run_enhance(str(folder), tmp_path / "out", PostRestorer(), max_frames=2, display=display)
    assert inp.kind == "images" and report.processed == 2 and report.command == "enhance"
    assert report.to_json()["out"] == str(tmp_path / "out")
    assert seen == [("images", 2, False)] and reports[-1] == 2
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["0.png", "1.png"]
    assert weights_line(PostRestorer(), shipped=True) is None


def test_video_runs_the_frame_job(tmp_path: Path) -> None:
    video = make_video(tmp_path / "dive.avi", 4)
    inp, report = run_enhance(str(video), tmp_path / "out.avi", PostRestorer())
    assert inp.kind == "video" and report.processed == 4 and report.outputs == [tmp_path / "out.avi"]


def test_a_video_written_over_itself_is_refused_and_left_as_it_was(tmp_path: Path) -> None:
    video = make_video(tmp_path / "dive.avi", 3)
    before = video.read_bytes()
    for out in (video, tmp_path / "." / "dive.avi"):
        for overwrite in (False, True):
            with pytest.raises(ValueError, match=r"this is the input .*dive\.avi; writing it would destroy it"):
                run_enhance(str(video), out, PostRestorer(), OutputOptions(overwrite=overwrite))
    os.link(video, tmp_path / "linked.avi")  # a hard link is the same file under another name
    with pytest.raises(ValueError, match=r"this is the input .*dive\.avi; writing it would destroy it"):
        run_enhance(str(video), tmp_path / "linked.avi", PostRestorer(), OutputOptions(overwrite=True))
    assert video.read_bytes() == before


def test_an_out_with_a_suffix_murk_does_not_write_is_a_folder_and_says_so(tmp_path: Path) -> None:
    image = tmp_path / "a.png"
    assert cv2.imwrite(str(image), np.full((8, 8, 3), 90, np.uint8))
    _, report = run_enhance(str(image), tmp_path / "result.gif", PostRestorer())
    assert (tmp_path / "result.gif" / "a.png").is_file()
    assert any(n.startswith(f"--out {tmp_path / 'result.gif'}: .gif is not an image or video") for n in report.notes)
    _, again = run_enhance(str(image), tmp_path / "result.gif", PostRestorer())  # now an existing folder
    _, video_only = run_enhance(str(image), tmp_path / "v", PostRestorer(), OutputOptions(fps=5.0, depth_video=True))
    assert "--fps and --depth-video: for video outputs; not used for images" in video_only.notes
    _, plain = run_enhance(str(image), tmp_path / "plain", PostRestorer())
    assert not any("is a folder" in n for n in again.notes + plain.notes)
