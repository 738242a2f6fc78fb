"""Sources of murk live: files paced at their frame rate, bags at their recorded speed, stamps, loop, errors."""

from __future__ import annotations

import itertools
from pathlib import Path

import pytest

from murk.errors import InputFileError
from murk.live.source import PacedSource, describe, open_live_source, reopener
from tests.live._live import clip


def test_file_is_paced_at_its_frame_rate_and_stamped(tmp_path: Path) -> None:
    path = clip(tmp_path, n=6, fps=20.0)
    with PacedSource(open_live_source(str(path))) as source:
        frames = list(source)
    assert [f.index for f in frames] == list(range(6))
    start = frames[0].source_ns
    # source time: the playback start plus the frame's position (exactly i / fps)
    assert [f.source_ns - start for f in frames] == [round(i / 20.0 * 1e9) for i in range(6)]
    # never delivered before its time (a lower bound: a busy machine can only make it later)
    for f in frames:
        assert f.capture_ns - frames[0].capture_ns >= round(f.index / 20.0 * 1e9) - 2_000_000
    assert source.end_reason == "end"
    assert all(f.image is not None and f.image.shape == (48, 64, 3) for f in frames)


def test_loop_restarts_a_file_with_increasing_frame_numbers_and_times(tmp_path: Path) -> None:
    path = clip(tmp_path, n=4, fps=50.0)
    source = PacedSource(open_live_source(str(path)), reopen=reopener(str(path), None), loop=True)
    try:
        frames = [source.read() for _ in range(10)]
    finally:
        source.close()
    assert [f.index for f in frames] == list(range(10))
    times = [f.source_ns for f in frames]
    assert all(b > a for a, b in itertools.pairwise(times))
    assert source.frame_count is None  # a looped file has no end


def test_stop_interrupts_the_wait_for_the_next_frame(tmp_path: Path) -> None:
    path = clip(tmp_path, n=3, fps=0.5)  # 2 s between frames
    source = PacedSource(open_live_source(str(path)))
    assert source.read() is not None
    source.stop()
    assert source.read() is None
    source.close()


def test_bag_replay_keeps_header_stamps_and_recorded_spacing(tmp_path: Path) -> None:
    pytest.importorskip("rosbags")
    from tests._rosbags import BagBuilder, frames, stamp_ns

    bag = BagBuilder(tmp_path / "dive.bag", "ros1").image("/cam/image", frames(3), "rgb8", frame_id="cam0").close()
    with PacedSource(open_live_source(str(bag), topic="/cam/image")) as source:
        got = list(source)
        assert "ROS bag" in describe(str(bag), source.source)
    assert [f.source_ns for f in got] == [stamp_ns(i) for i in range(3)]
    assert {f.frame_id for f in got} == {"cam0"}
    # replayed at recorded speed (100 ms apart): never early
    assert got[2].capture_ns - got[0].capture_ns >= 200_000_000 - 2_000_000


def test_bad_sources_are_named(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match=r"missing\.mp4"):
        open_live_source(str(tmp_path / "missing.mp4"))
    path = clip(tmp_path, n=2)
    with pytest.raises(ValueError, match=r"--topic /x: .*not a ROS bag"):
        open_live_source(str(path), topic="/x")
