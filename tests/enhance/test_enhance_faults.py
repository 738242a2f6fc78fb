"""``murk enhance`` under faults (issue 13): a full disk (images, video, frames), error records of earlier runs,
and inputs whose outputs would share a name."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.enhance.api import OutputOptions, enhance_frames
from murk.enhance.post import PostRestorer
from murk.io import read_jsonl
from murk.io import video as video_mod

from .._faults import assert_nothing_partial, fill_disk, one_line_error
from ._enhance_helpers import FakeSource, make_frames, make_video, read_video

runner = CliRunner()
_REAL_WRITER = cv2.VideoWriter


@pytest.fixture
def folder(tmp_path: Path, rng: np.random.Generator) -> Path:
    root = tmp_path / "dive"
    (root / "sub").mkdir(parents=True)
    for rel in ("a.png", "sub/b.png"):
        assert cv2.imwrite(str(root / rel), (rng.random((24, 32, 3)) * 255).astype(np.uint8))
    return root


def test_full_disk_on_images_stops_with_one_line(folder: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "out"
    fill_disk(monkeypatch, after=1, only=".png")
    line = one_line_error(runner.invoke(app, ["enhance", str(folder), "--out", str(out), "-r"]))
    assert line == f"error: {out / 'sub' / 'b.png'}: no space left on device"
    assert_nothing_partial(out)
    assert (out / "a.png").is_file() and not (out / "sub" / "b.png").exists()
    assert not (out / "errors.jsonl").exists()  # a full disk is not a bad input
    monkeypatch.undo()
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(out), "-r"])
    assert res.exit_code == 0 and "1 image processed, 1 skipped" in " ".join(res.output.split())


def test_full_disk_on_frames_stops_with_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    video = make_video(tmp_path / "clip.avi", 6)
    fill_disk(monkeypatch, after=2, only=".jpg")
    line = one_line_error(runner.invoke(app, ["enhance", str(video), "--out", str(tmp_path / "fr")]))
    assert line == f"error: {tmp_path / 'fr' / 'clip_000002.jpg'}: no space left on device"
    assert sorted(p.name for p in (tmp_path / "fr").iterdir()) == ["clip_000000.jpg", "clip_000001.jpg"]


class _FullDiskWriter:
    """OpenCV's VideoWriter on a disk that fills after 3 frames: it keeps reporting nothing."""

    def __init__(self, path: str, *args: object) -> None:
        self.real, self.n = _REAL_WRITER(path, *args), 0

    def isOpened(self) -> bool:
        return self.real.isOpened()

    def write(self, frame: np.ndarray) -> None:
        self.n += 1
        if self.n <= 3:
            self.real.write(frame)

    def release(self) -> None:
        self.real.release()


def test_full_disk_on_a_video_leaves_no_truncated_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    video = make_video(tmp_path / "clip.avi", 8)
    out = tmp_path / "out" / "enh.mp4"
    monkeypatch.setattr(video_mod.cv2, "VideoWriter", _FullDiskWriter)
    monkeypatch.setattr(video_mod.shutil, "disk_usage", lambda p: type("U", (), {"free": 4096})())
    args = ["enhance", str(video), "--out", str(out), "--video-backend", "opencv"]
    line = one_line_error(runner.invoke(app, args))
    assert line == f"error: {out}: no space left on device"
    assert list((tmp_path / "out").iterdir()) == []  # no truncated video under the final name, no temporary
    monkeypatch.undo()
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    assert len(read_video(out)) == 8


def test_errors_jsonl_lists_the_latest_run_only(folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    (folder / "bad.jpg").write_bytes(b"\xff\xd8\xff not a jpeg")
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(out)])
    assert res.exit_code == 1 and [Path(r["input"]).name for r in read_jsonl(out / "errors.jsonl")] == ["bad.jpg"]
    (folder / "bad.jpg").unlink()
    res = runner.invoke(app, ["enhance", str(folder), "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert not (out / "errors.jsonl").exists()


def test_errors_jsonl_of_frames_lists_the_latest_run_only(tmp_path: Path) -> None:
    frames = make_frames(5)
    out = tmp_path / "out" / "enh.avi"
    report = enhance_frames(FakeSource(frames, live=False, broken=(2,)), PostRestorer(), out)
    assert report.failed == 1 and len(read_jsonl(tmp_path / "out" / "errors.jsonl")) == 1
    options = OutputOptions(overwrite=True)
    report = enhance_frames(FakeSource(frames, live=False), PostRestorer(), out, options)
    assert report.failed == 0 and report.processed == 5
    assert not (tmp_path / "out" / "errors.jsonl").exists()


def test_inputs_whose_outputs_share_a_name_get_distinct_names(tmp_path: Path, fake_depth_method: list[dict]) -> None:
    root = tmp_path / "in"
    root.mkdir()
    for name, level in (("x.jpg", 60), ("x.png", 200)):
        assert cv2.imwrite(str(root / name), np.full((16, 16, 3), level, np.uint8))
    res = runner.invoke(app, ["enhance", str(root), "--out", str(tmp_path / "o1"), "--format", "png"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (tmp_path / "o1").iterdir()) == ["x_jpg.png", "x_png.png"]
    res = runner.invoke(app, ["enhance", str(root), "--out", str(tmp_path / "o2"), "-m", "fakedepth"])
    assert res.exit_code == 0, res.output
    assert sorted(p.name for p in (tmp_path / "o2").iterdir() if p.is_file()) == ["x.jpg", "x.png"]
    assert sorted(p.name for p in (tmp_path / "o2" / "depth").iterdir()) == ["x_jpg.png", "x_png.png"]


def test_output_above_the_input_may_not_write_into_it(tmp_path: Path) -> None:
    """dive/sub -r --out dive: sub/y.png of the input would be written to dive/sub/y.png, inside the input
    folder, and read back on the rerun."""
    root = tmp_path / "dive" / "sub"
    (root / "sub").mkdir(parents=True)
    for rel in ("x.png", "sub/y.png"):
        assert cv2.imwrite(str(root / rel), np.full((16, 16, 3), 90, np.uint8))
    out = tmp_path / "dive"
    line = one_line_error(runner.invoke(app, ["enhance", str(root), "--out", str(out), "-r"]))
    assert f"--out {out}: the output {out / 'sub' / 'y.png'} would land inside the input folder {root}" in line
    assert sorted(p.name for p in out.iterdir()) == ["sub"]  # nothing written
    res = runner.invoke(app, ["enhance", str(root), "--out", str(out)])  # not recursive: x.png -> dive/x.png
    assert res.exit_code == 0, res.output
    assert (out / "x.png").is_file()


def test_full_disk_on_a_videos_estimates_keeps_the_video(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The estimates are written after the video is committed: a full disk then stops the run with an error naming
    the estimates file, and leaves the finished video and no partial file."""
    from murk.enhance.restorer import Restored, Restorer
    from murk.errors import OutputError

    class Measures(Restorer):
        name = "measures"

        def restore(self, images: np.ndarray) -> Restored:
            return Restored(np.asarray(images, np.float32), facts=tuple({"mean": float(i.mean())} for i in images))

    fill_disk(monkeypatch, only="_estimates.jsonl")
    out = tmp_path / "v.avi"
    with pytest.raises(OutputError, match=r"v_estimates\.jsonl: no space left on device"):
        enhance_frames(FakeSource(make_frames(4), live=False), Measures(), out)
    assert len(read_video(out)) == 4 and not (tmp_path / "v_estimates.jsonl").exists()
    assert_nothing_partial(tmp_path)
