"""A full disk is one clear error at every write helper (issue 13): ``OutputError`` "PATH: no space left on
device" naming the final file, nothing partial under that name. The full disk is simulated by making the
writes raise ``OSError(ENOSPC)`` (or, for OpenCV's video writer, which reports nothing, by truncating)."""

from __future__ import annotations

import errno
import pickle
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.errors import OutputError
from murk.io import append_jsonl, read_jsonl, write_rgb, write_text_atomic
from murk.io import video as video_mod
from murk.io.atomic import no_space_as_error
from murk.io.video import VideoSink

from .._faults import assert_nothing_partial, fill_disk


def test_atomic_writes_raise_output_error_naming_the_final_file(tmp_path: Path, monkeypatch) -> None:
    write_text_atomic(tmp_path / "keep.txt", "old")
    failed = fill_disk(monkeypatch)
    with pytest.raises(OutputError, match=rf"^{re.escape(str(tmp_path / 'a.png'))}: no space left on device$") as info:
        write_rgb(tmp_path / "a.png", np.zeros((8, 8, 3), np.float32))
    assert info.value.errno == errno.ENOSPC and failed == ["a.png"]
    with pytest.raises(OutputError, match=r"keep\.txt: no space left on device"):
        write_text_atomic(tmp_path / "keep.txt", "new")
    assert (tmp_path / "keep.txt").read_text() == "old"  # the older file stays, the temporary one is gone
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]
    assert_nothing_partial(tmp_path)


def test_quota_and_other_errors(tmp_path: Path) -> None:
    with pytest.raises(OutputError, match=r"x: no space left on device \(disk quota exceeded\)"):
        with no_space_as_error(tmp_path / "x"):
            raise OSError(errno.EDQUOT, "Disk quota exceeded")
    with pytest.raises(OutputError, match=r"x: cannot write the output file \(permission denied; check that the"):
        with no_space_as_error(tmp_path / "x"):  # issue 31: the path that cannot be written is named
            raise PermissionError(errno.EACCES, "Permission denied")
    with pytest.raises(OSError, match="Input/output error") as info:  # neither full nor unwritable: left as it is
        with no_space_as_error(tmp_path / "x"):
            raise OSError(errno.EIO, "Input/output error")
    assert not isinstance(info.value, OutputError)
    err = OutputError(errno.ENOSPC, "no space left on device", "out/a.png")  # pickles back from a worker
    back = pickle.loads(pickle.dumps(err))
    assert type(back) is OutputError and str(back) == "out/a.png: no space left on device"


def test_append_jsonl_on_a_full_disk(tmp_path: Path, monkeypatch) -> None:
    log = tmp_path / "log.jsonl"
    append_jsonl(log, [{"a": 1}])

    def fsync(fd: int) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("murk.io.jsonl.os.fsync", fsync)
    with pytest.raises(OutputError, match=rf"^{re.escape(str(log))}: no space left on device$"):
        append_jsonl(log, [{"a": 2}])
    monkeypatch.undo()
    assert read_jsonl(log)[0] == {"a": 1}


_REAL_WRITER = cv2.VideoWriter


class _TruncatingWriter:
    """OpenCV's writer on a full disk: write() and release() report nothing; the file lacks what did not fit."""

    def __init__(self, path: str, fourcc: int, fps: float, size: tuple[int, int]) -> None:
        self.real = _REAL_WRITER(path, fourcc, fps, size)
        self.n = 0

    def isOpened(self) -> bool:
        return self.real.isOpened()

    def write(self, frame: np.ndarray) -> None:
        self.n += 1
        if self.n <= 2:
            self.real.write(frame)

    def release(self) -> None:
        self.real.release()


@pytest.mark.parametrize("free_bytes, message", [(0, "no space left on device"), (10**12, "the video writer failed")])
def test_opencv_video_that_lacks_frames_is_refused(tmp_path: Path, monkeypatch, free_bytes: int, message: str) -> None:
    monkeypatch.setattr(video_mod.cv2, "VideoWriter", _TruncatingWriter)
    monkeypatch.setattr(video_mod.shutil, "disk_usage", lambda p: type("U", (), {"free": free_bytes})())
    out = tmp_path / "clip.mp4"
    sink = VideoSink(out, 10.0, (32, 24))
    for i in range(6):
        sink.write(np.full((24, 32, 3), 40 * i, np.uint8))
    with pytest.raises(OutputError, match=rf"^{re.escape(str(out))}: {message}"):
        sink.close()
    assert list(tmp_path.iterdir()) == []  # neither the video nor its temporary file


def test_opencv_video_with_every_frame_passes_the_check(tmp_path: Path) -> None:
    with VideoSink(tmp_path / "clip.avi", 10.0, (32, 24)) as sink:
        for i in range(5):
            sink.write(np.full((24, 32, 3), 40 * i, np.uint8))
    assert cv2.VideoCapture(str(tmp_path / "clip.avi")).get(cv2.CAP_PROP_FRAME_COUNT) == 5


def test_pyav_video_on_a_full_disk(tmp_path: Path, monkeypatch) -> None:
    av = pytest.importorskip("av")
    out = tmp_path / "clip.mp4"
    sink = VideoSink(out, 10.0, (32, 24), backend="av")

    def mux(packet: object) -> None:
        raise av.error.OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(sink, "_container", type("C", (), {"mux": staticmethod(mux), "close": lambda self: None})())
    with pytest.raises(OutputError, match=rf"^{re.escape(str(out))}: no space left on device$"):
        for i in range(30):
            sink.write(np.full((24, 32, 3), 8 * i, np.uint8))
    sink.abort()
    assert list(tmp_path.iterdir()) == []
