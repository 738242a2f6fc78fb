"""The enhance pipeline: inputs, outputs, resume, error records, depth outputs, videos and live streams."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.enhance.api import (
    OutputOptions,
    enhance_frames,
    enhance_images,
    plan_images,
    resolve_input,
)
from murk.enhance.post import PostRestorer, post_process
from murk.enhance.restorer import Restored, Restorer
from murk.errors import InputFileError
from murk.io import read_image, read_jsonl, read_rgb, to_uint
from murk.io.atomic import TMP_PREFIX
from murk.io.video import CaptureSource, Frame

from ._enhance_helpers import FakeDepth, FakeSource, make_frames, make_video, read_video


def _write_png(path: Path, rgb: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.ascontiguousarray(rgb[:, :, ::-1]))
    return path


@pytest.fixture
def photos(tmp_path: Path, rng: np.random.Generator) -> Path:
    """photos/a.png, photos/b.jpg (other size), photos/sub/c.png."""
    root = tmp_path / "photos"
    _write_png(root / "a.png", (rng.random((24, 32, 3)) * 200 + 20).astype(np.uint8))
    big = (rng.random((30, 40, 3)) * 200 + 20).astype(np.uint8)
    root.mkdir(exist_ok=True)
    assert cv2.imwrite(str(root / "b.jpg"), big)
    _write_png(root / "sub" / "c.png", (rng.random((24, 32, 3)) * 200 + 20).astype(np.uint8))
    return root


def _run(inp: str, out: Path, restorer: Restorer | None = None, recursive: bool = True, **opts: object):
    spec = resolve_input(inp, recursive=recursive, exclude=out)
    jobs, out_dir = plan_images(spec, out, opts.pop("format", None))  # type: ignore[arg-type]
    batch = int(opts.pop("batch", 1))  # type: ignore[call-overload]
    return enhance_images(jobs, restorer or PostRestorer(), out_dir, OutputOptions(**opts), batch=batch)  # type: ignore[arg-type]


# --- inputs -----------------------------------------------------------------------------------------------------


def test_resolve_input_kinds(photos: Path, tmp_path: Path) -> None:
    assert resolve_input(str(photos)).images == (photos / "a.png", photos / "b.jpg")
    assert len(resolve_input(str(photos), recursive=True).images) == 3
    single = resolve_input(str(photos / "a.png"))
    assert single.kind == "images" and single.root == photos
    video = make_video(tmp_path / "v.mp4", 3)
    assert resolve_input(str(video)).kind == "video"
    cam = resolve_input("0")
    assert cam.kind == "stream" and cam.target == 0 and cam.label == "camera 0"
    url = resolve_input("rtsp://user:pw@10.1.1.1/live")
    assert url.kind == "stream" and url.label == "rtsp://10.1.1.1/live" and url.target == "rtsp://user:pw@10.1.1.1/live"
    glob = resolve_input(str(photos / "**" / "*.png"))
    assert glob.root == photos and [p.name for p in glob.images] == ["a.png", "c.png"]


def test_resolve_input_errors(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="not found"):
        resolve_input(str(tmp_path / "nothing"))
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputFileError, match="no images found"):
        resolve_input(str(tmp_path / "empty"))
    (tmp_path / "empty" / "b.mp4").write_bytes(b"")
    (tmp_path / "empty" / "a.MOV").write_bytes(b"")
    with pytest.raises(InputFileError, match=r"no images found \(videos are restored one at a time: murk enhance"):
        resolve_input(str(tmp_path / "empty"))  # not "use --recursive"
    with pytest.raises(InputFileError, match="matches no image"):
        resolve_input(str(tmp_path / "*.png"))


def test_plan_images_paths_and_refusals(photos: Path, tmp_path: Path) -> None:
    spec = resolve_input(str(photos), recursive=True)
    jobs, out_dir = plan_images(spec, tmp_path / "out", "png")
    assert out_dir == tmp_path / "out"
    assert [j.dst.relative_to(out_dir).as_posix() for j in jobs] == ["a.png", "b.png", "sub/c.png"]
    assert [j.stem for j in jobs] == ["a", "b", "sub/c"]
    jobs, _ = plan_images(spec, tmp_path / "out")
    assert jobs[1].dst.name == "b.jpg"  # format kept by default
    with pytest.raises(ValueError, match="this is the input folder"):
        plan_images(spec, photos)
    one = resolve_input(str(photos / "a.png"))
    jobs, out_dir = plan_images(one, tmp_path / "x" / "result.jpg")
    assert jobs[0].dst == tmp_path / "x" / "result.jpg" and out_dir == tmp_path / "x"
    with pytest.raises(ValueError, match="would overwrite its input"):
        plan_images(one, photos / "a.png")
    with pytest.raises(ValueError, match="--format png contradicts"):
        plan_images(one, tmp_path / "r.jpg", "png")
    with pytest.raises(ValueError, match="images are written to a folder or an image file"):
        plan_images(spec, tmp_path / "x.mp4")
    with pytest.raises(ValueError, match=r"x\.png: 3 images are written to a folder, not to one image file"):
        plan_images(spec, tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()
    (tmp_path / "dir.png").mkdir()  # an existing folder that happens to end in .png stays a folder
    assert plan_images(spec, tmp_path / "dir.png")[1] == tmp_path / "dir.png"


# --- images -----------------------------------------------------------------------------------------------------


def test_grey_and_rgba_inputs_are_written_as_rgb_and_the_summary_says_so(tmp_path: Path) -> None:
    grey = (np.arange(40 * 50, dtype=np.uint32).reshape(40, 50) % 200).astype(np.uint8)
    (tmp_path / "in").mkdir()
    assert cv2.imwrite(str(tmp_path / "in" / "g.png"), grey)
    assert cv2.imwrite(str(tmp_path / "in" / "a.png"), np.dstack([grey, grey, grey, grey]))
    report = _run(str(tmp_path / "in"), tmp_path / "out")
    assert report.processed == 2
    for name in ("g.png", "a.png"):
        assert cv2.imread(str(tmp_path / "out" / name), cv2.IMREAD_UNCHANGED).shape == (40, 50, 3)
    assert "1 input image(s): grayscale (L) converted to RGB; their outputs are 3-channel RGB" in report.notes
    assert "1 input image(s): alpha channel of RGBA image dropped; their outputs are 3-channel RGB" in report.notes


def test_folder_outputs_equal_post_process_and_keep_size(photos: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    report = _run(str(photos), out, batch=4)  # a.png and sub/c.png share a size; b.jpg does not
    assert (report.processed, report.failed, report.skipped) == (3, 0, 0)
    for rel in ("a.png", "b.jpg", "sub/c.png"):
        src = read_rgb(photos / rel)
        raw, _ = read_image(out / rel)
        assert raw.shape == src.shape
        if rel.endswith(".png"):  # lossless: exactly the 8-bit rounding of Eq. (9)
            np.testing.assert_array_equal(raw, to_uint(post_process(src)))
    ms = report.stage_ms()
    assert set(ms) == {"read", "restore", "write"} and all(v >= 0 for v in ms.values())
    assert report.fps > 0 and report.errors_path is None and not (out / "errors.jsonl").exists()


def test_rerun_resumes_and_overwrite_redoes(photos: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    _run(str(photos), out)
    stamp = (out / "a.png").stat().st_mtime_ns
    again = _run(str(photos), out)
    assert (again.processed, again.skipped) == (0, 3)
    assert (out / "a.png").stat().st_mtime_ns == stamp
    (out / "sub" / "c.png").unlink()
    third = _run(str(photos), out)
    assert (third.processed, third.skipped) == (1, 2)
    forced = _run(str(photos), out, overwrite=True)
    assert forced.processed == 3


def test_corrupt_file_is_recorded_and_skipped(photos: Path, tmp_path: Path) -> None:
    (photos / "broken.png").write_bytes(b"\x89PNG\r\n\x1a\n garbage")
    out = tmp_path / "out"
    report = _run(str(photos), out)
    assert (report.processed, report.failed) == (3, 1)
    records = read_jsonl(out / "errors.jsonl")
    assert records == [
        {"input": str(photos / "broken.png"), "stage": "read", "error": "cannot decode image (unsupported format or "
         "corrupt file)"}
    ]  # fmt: skip
    assert report.errors_path == out / "errors.jsonl"


def test_sixteen_bit_png_stays_sixteen_bit_unless_format_says(tmp_path: Path) -> None:
    ramp = np.linspace(0, 1, 64 * 48, dtype=np.float32).reshape(48, 64)
    img16 = (np.stack([ramp, ramp[::-1], 0.5 * ramp], axis=-1) * 60000 + 2000).astype(np.uint16)
    _write_png(tmp_path / "in" / "deep.png", img16)
    _run(str(tmp_path / "in"), tmp_path / "o16")
    raw, info = read_image(tmp_path / "o16" / "deep.png")
    assert raw.dtype == np.uint16 and info.bit_depth == 16
    assert np.unique(raw[..., 1]).size > 1000  # real 16-bit content, not 8-bit scaled
    _run(str(tmp_path / "in"), tmp_path / "o8", format="jpg")
    raw8, info8 = read_image(tmp_path / "o8" / "deep.jpg")
    assert raw8.dtype == np.uint8 and info8.bit_depth == 8


def test_output_inside_the_input_folder_is_not_read_back(photos: Path) -> None:
    out = photos / "enhanced"
    first = _run(str(photos), out, overwrite=True)
    second = _run(str(photos), out, overwrite=True)
    assert first.processed == second.processed == 3
    assert not (out / "enhanced").exists()


def test_side_by_side_panels(photos: Path, tmp_path: Path) -> None:
    _run(str(photos / "a.png"), tmp_path / "sbs", side_by_side=True)
    panel = read_rgb(tmp_path / "sbs" / "a.png")
    src = read_rgb(photos / "a.png")
    assert panel.shape == (24, 64, 3)
    np.testing.assert_array_equal(panel[:, :32], src)  # the input on the left, untouched


def test_depth_outputs_are_written_when_the_method_returns_depth(photos: Path, tmp_path: Path) -> None:
    out = tmp_path / "out"
    report = _run(str(photos), out, restorer=FakeDepth())
    assert report.processed == 3
    depth_raw = cv2.imread(str(out / "depth" / "sub" / "c.png"), cv2.IMREAD_UNCHANGED)
    assert depth_raw.dtype == np.uint16 and depth_raw.shape == (24, 32)
    assert depth_raw[0, 0] == 1000 and depth_raw[-1, 5] == 4000  # millimetres
    preview = read_rgb(out / "depth_preview" / "a.jpg")
    assert preview.shape == (24, 32, 3)
    near, far = preview[0].mean(axis=0), preview[-1].mean(axis=0)
    assert near[0] > near[2] and near.sum() > far.sum()  # near (1 m) warm and bright, 4 m darker
    none = _run(str(photos), tmp_path / "nodepth", restorer=FakeDepth(), depth=False)
    assert none.processed == 3 and not (tmp_path / "nodepth" / "depth").exists()


def test_restore_failure_is_recorded_and_the_run_continues(photos: Path, tmp_path: Path) -> None:
    class Picky(Restorer):
        name = "picky"

        def restore(self, images: np.ndarray) -> Restored:
            if images.shape[1] == 30:
                raise ValueError("images: expected a height divisible by 8, got 30")
            return Restored(images)

    report = _run(str(photos), tmp_path / "out", restorer=Picky())
    assert (report.processed, report.failed) == (2, 1)
    (record,) = read_jsonl(tmp_path / "out" / "errors.jsonl")
    assert record["stage"] == "restore" and record["input"].endswith("b.jpg") and "divisible by 8" in record["error"]


# --- frames -----------------------------------------------------------------------------------------------------


def test_video_file_round_trip_keeps_count_size_and_rate(tmp_path: Path) -> None:
    video = make_video(tmp_path / "in.mp4", 12, fps=15.0)
    with CaptureSource(video) as src:
        report = enhance_frames(src, PostRestorer(), tmp_path / "out" / "enh.mp4", batch=5)
    assert (report.processed, report.total, report.failed) == (12, 12, 0)
    frames = read_video(tmp_path / "out" / "enh.mp4")
    assert len(frames) == 12 and frames[0].shape == (48, 64, 3)
    cap = cv2.VideoCapture(str(tmp_path / "out" / "enh.mp4"))
    assert cap.get(cv2.CAP_PROP_FPS) == pytest.approx(15.0)
    cap.release()
    assert report.outputs == [tmp_path / "out" / "enh.mp4"]
    again = enhance_frames(CaptureSource(video), PostRestorer(), tmp_path / "out" / "enh.mp4")
    assert again.skipped == 12 and again.processed == 0 and "exists" in again.notes[0]  # in frames


def test_broken_frame_is_recorded_and_replaced_by_the_previous_one(tmp_path: Path) -> None:
    src = FakeSource(make_frames(8), live=False, broken=(3,))
    report = enhance_frames(src, FakeDepth(), tmp_path / "v.avi", OutputOptions(depth=False))
    assert (report.processed, report.failed) == (7, 1)
    frames = read_video(tmp_path / "v.avi")
    assert len(frames) == 8  # length and timing kept
    red = [float(f[:, :, 0].mean()) for f in frames]
    assert abs(red[3] - red[2]) < 1 and abs(red[4] - (20 + 8 * 4)) < 4
    (record,) = read_jsonl(tmp_path / "errors.jsonl")
    assert record == {
        "input": "fake://source",
        "stage": "read",
        "frame": 3,
        "error": "frame could not be decoded; previous frame repeated in the video",
    }


def test_broken_leading_frames_take_the_first_good_frame_so_the_video_keeps_its_length(tmp_path: Path) -> None:
    src = FakeSource(make_frames(6), live=False, broken=(0, 1))
    report = enhance_frames(src, FakeDepth(), tmp_path / "v.avi", OutputOptions(depth_video=True))
    assert (report.processed, report.failed) == (4, 2)
    frames, depth = read_video(tmp_path / "v.avi"), read_video(tmp_path / "v_depth.avi")
    assert len(frames) == 6 and len(depth) == 6  # length and timing kept
    red = [float(f[:, :, 0].mean()) for f in frames]
    assert abs(red[0] - red[2]) < 1 and abs(red[1] - red[2]) < 1 and abs(red[3] - red[2]) > 4
    records = read_jsonl(tmp_path / "errors.jsonl")
    assert [r["frame"] for r in records] == [0, 1]
    assert all(r["error"].endswith("the next good frame takes its place in the video") for r in records)
    folder = enhance_frames(FakeSource(make_frames(4), live=False, broken=(0,)), FakeDepth(), tmp_path / "f")
    assert (folder.processed, folder.failed) == (3, 1)
    assert sorted(p.name for p in (tmp_path / "f").glob("*.jpg")) == [f"fake_00000{i}.jpg" for i in (1, 2, 3)]
    assert read_jsonl(tmp_path / "f" / "errors.jsonl")[0]["error"] == "frame could not be decoded"


def test_live_source_disconnecting_leaves_a_closed_playable_video(tmp_path: Path) -> None:
    src = FakeSource(make_frames(7), live=True)
    opts = OutputOptions(video_backend="opencv")
    # read_ahead=False: this fake camera bursts all frames at once, which read-ahead would rightly drop
    report = enhance_frames(src, PostRestorer(), tmp_path / "rec.avi", opts, batch=3, read_ahead=False)
    assert report.processed == 7 and report.total is None
    assert len(read_video(tmp_path / "rec.avi")) == 7
    assert any("disconnected" in n for n in report.notes)
    assert not list(tmp_path.glob(f"{TMP_PREFIX}*"))
    with pytest.raises(ValueError, match="exists; pass --overwrite"):
        enhance_frames(FakeSource(make_frames(2), live=True), PostRestorer(), tmp_path / "rec.avi", opts)


def test_stopping_a_live_recording_keeps_it_and_a_file_run_discards_it(tmp_path: Path) -> None:
    polls = iter(range(100))
    stop_after_4 = lambda: next(polls) >= 4  # noqa: E731
    live = enhance_frames(
        FakeSource(make_frames(10), live=True),
        PostRestorer(),
        tmp_path / "live.avi",
        should_stop=stop_after_4,
        read_ahead=False,
    )
    assert live.stopped and live.processed == 4 and len(read_video(tmp_path / "live.avi")) == 4
    polls = iter(range(100))
    stop_after_4 = lambda: next(polls) >= 4  # noqa: E731
    file_run = enhance_frames(
        FakeSource(make_frames(10), live=False), PostRestorer(), tmp_path / "file.avi", should_stop=stop_after_4
    )
    assert file_run.stopped and not (tmp_path / "file.avi").exists()
    assert not list(tmp_path.glob(f"{TMP_PREFIX}*")) and file_run.outputs == []
    assert any("interrupted" in n for n in file_run.notes)


class _Measures(Restorer):
    """Leaves each frame as it is and reports its mean, and a figure it could not measure (NaN)."""

    name = "measures"

    def restore(self, images: np.ndarray) -> Restored:
        facts = tuple({"mean": float(im.mean()), "unmeasured": float("nan")} for im in images)
        return Restored(np.asarray(images, np.float32), facts=facts)


def _stop_after(n: int):  # type: ignore[no-untyped-def]
    polls = iter(range(100))
    return lambda: next(polls) >= n


def test_estimates_follow_their_frames_when_a_run_stops(tmp_path: Path) -> None:
    """A file run writes its frames' estimates with the video; a stopped rerun with --overwrite keeps the previous
    video and its estimates as they were; a stopped live recording keeps the lines of the frames it kept. A figure
    that is not a number is written as null, and the frame counts as written."""
    done = enhance_frames(FakeSource(make_frames(6), live=False), _Measures(), tmp_path / "f.avi")
    rows = read_jsonl(tmp_path / "f_estimates.jsonl")
    assert done.processed == 6 and not done.failed and [r["frame"] for r in rows] == list(range(6))
    assert rows[0]["unmeasured"] is None and rows[0]["output"] == str(tmp_path / "f.avi")
    before = (tmp_path / "f_estimates.jsonl").read_bytes()
    again = enhance_frames(
        FakeSource(make_frames(10), live=False),
        _Measures(),
        tmp_path / "f.avi",
        OutputOptions(overwrite=True),
        should_stop=_stop_after(4),
    )
    assert again.stopped and len(read_video(tmp_path / "f.avi")) == 6  # the previous video, kept
    assert (tmp_path / "f_estimates.jsonl").read_bytes() == before and not list(tmp_path.glob(f"{TMP_PREFIX}*"))
    src = FakeSource(make_frames(10), live=True)
    enhance_frames(src, _Measures(), tmp_path / "live.avi", should_stop=_stop_after(4), read_ahead=False)
    rows = read_jsonl(tmp_path / "live_estimates.jsonl")
    assert [r["frame"] for r in rows] == [0, 1, 2, 3] and all(r["output"].endswith("live.avi") for r in rows)
    plain = enhance_frames(FakeSource(make_frames(3), live=False), PostRestorer(), tmp_path / "f.avi",
                           OutputOptions(overwrite=True))  # fmt: skip
    assert plain.processed == 3 and not (tmp_path / "f_estimates.jsonl").exists()  # a new video without estimates


def test_frames_output_max_frames_and_resume(tmp_path: Path) -> None:
    out = tmp_path / "frames"
    report = enhance_frames(FakeSource(make_frames(9), live=False), PostRestorer(), out, max_frames=5)
    assert report.processed == 5 and report.total == 5
    assert sorted(p.name for p in out.iterdir()) == [f"fake_{i:06d}.jpg" for i in range(5)]
    more = enhance_frames(FakeSource(make_frames(9), live=False), PostRestorer(), out)
    assert (more.processed, more.skipped) == (4, 5)
    png = enhance_frames(FakeSource(make_frames(2), live=False), PostRestorer(), tmp_path / "p", OutputOptions("png"))
    assert png.processed == 2 and (tmp_path / "p" / "fake_000001.png").is_file()


def test_video_depth_outputs_and_depth_video(tmp_path: Path) -> None:
    opts = OutputOptions(depth_video=True, side_by_side=True)
    report = enhance_frames(FakeSource(make_frames(4), live=False), FakeDepth(), tmp_path / "v.avi", opts)
    assert report.processed == 4
    assert report.outputs == [tmp_path / "v_depth.avi", tmp_path / "v.avi"]
    assert read_video(tmp_path / "v.avi")[0].shape == (48, 128, 3)  # side by side
    depth_frames = read_video(tmp_path / "v_depth.avi")
    assert len(depth_frames) == 4 and depth_frames[0].shape == (48, 64, 3)
    raw = cv2.imread(str(tmp_path / "depth" / "v_000002.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16 and raw[0, 0] == 1000
    assert (tmp_path / "depth_preview" / "v_000003.jpg").is_file()
    post_only = enhance_frames(FakeSource(make_frames(2), live=False), PostRestorer(), tmp_path / "p.avi", opts)
    assert any("returns no depth" in n for n in post_only.notes) and not (tmp_path / "p_depth.avi").exists()


def test_frame_pipeline_refuses_unwritable_video_suffix(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"cannot write \.webm videos"):
        enhance_frames(FakeSource(make_frames(2), live=False), PostRestorer(), tmp_path / "x.webm")
    with pytest.raises(ValueError, match="frames are written to a video file or a folder"):
        enhance_frames(FakeSource(make_frames(2), live=False), PostRestorer(), tmp_path / "x.png")
    with pytest.raises(ValueError, match="batch: expected >= 1"):
        enhance_frames(FakeSource(make_frames(2), live=False), PostRestorer(), tmp_path / "x.mp4", batch=0)


class _SlowPost(PostRestorer):
    """``post`` that takes at least 20 ms per call: restoration is the slow stage (for a file source, whose
    reader waits for room, so no outcome depends on how long it takes)."""

    def restore(self, images: np.ndarray):  # type: ignore[no-untyped-def]
        time.sleep(0.02)
        return super().restore(images)


class _BurstingCamera(FakeSource):
    """A live source that holds frame 1 until ``consumer_busy`` is set and sets ``ended`` at its end."""

    def __init__(self, frames: list[np.ndarray]) -> None:
        super().__init__(frames, live=True)
        self.consumer_busy, self.ended = threading.Event(), threading.Event()

    def read(self) -> Frame | None:
        if self._i == 1:
            assert self.consumer_busy.wait(60), "restoration never started"
        frame = super().read()
        if frame is None:
            self.ended.set()
        return frame


class _PostAfterTheBurst(PostRestorer):
    """``post`` whose first call waits until the camera has sent everything: restoration slower than the source
    by construction, however busy the machine is."""

    def __init__(self, camera: _BurstingCamera) -> None:
        super().__init__()
        self.camera = camera

    def restore(self, images: np.ndarray):  # type: ignore[no-untyped-def]
        self.camera.consumer_busy.set()
        assert self.camera.ended.wait(60), "the camera never reached its end"
        return super().restore(images)


def test_a_live_source_faster_than_restoration_drops_frames_and_says_how_many(tmp_path: Path) -> None:
    camera = _BurstingCamera(make_frames(40))
    report = enhance_frames(camera, _PostAfterTheBurst(camera), tmp_path / "live", OutputOptions("png"))
    written = sorted(p.name for p in tmp_path.joinpath("live").glob("fake_*.png"))
    # frame 0 is restored; 1..38 arrive while it is, each replacing the one waiting; 39, the newest, is kept
    assert (report.processed, report.dropped) == (2, 38)
    assert written == ["fake_000000.png", "fake_000039.png"]
    assert any("38 frame(s) dropped" in n for n in report.notes)


def test_a_file_source_loses_nothing_with_read_ahead(tmp_path: Path) -> None:
    report = enhance_frames(FakeSource(make_frames(12), live=False), _SlowPost(), tmp_path / "f", OutputOptions("png"))
    assert (report.processed, report.dropped) == (12, 0)
    assert len(list(tmp_path.joinpath("f").glob("fake_*.png"))) == 12


@pytest.mark.parametrize("out_name", ["v.avi", "frames"])
def test_overlapped_decode_restore_encode_writes_the_serial_bytes(tmp_path: Path, out_name: str) -> None:
    """Issue 29: read-ahead and write-behind threads change when frames are written, never what is written; a
    broken frame is still recorded and repeated in order."""
    frames = make_frames(9)
    outs = {}
    for overlap in (True, False):
        out = tmp_path / str(overlap) / out_name
        source = FakeSource(frames, live=False, broken=(4,))  # frame 4: repeated in the video, recorded
        report = enhance_frames(source, PostRestorer(), out, OutputOptions("png"), read_ahead=overlap)
        assert (report.processed, report.failed) == (8, 1)
        files = [out] if out.suffix else sorted(out.glob("*.png"))
        outs[overlap] = [f.read_bytes() for f in files]
        assert read_jsonl(out.parent / "errors.jsonl" if out.suffix else out / "errors.jsonl")[0]["frame"] == 4
    assert outs[True] == outs[False] and outs[True]
