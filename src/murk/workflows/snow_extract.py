"""``murk snow extract`` as a library call: list the footage, read its frames (images, and every N-th frame of
videos through :mod:`murk.io.video`), cut the particles (:func:`murk.snow.bank.extract_bank`), write the bank,
the previews and ``<bank>_errors.jsonl`` (the :mod:`murk.io.jobs` schema; rewritten by every run)."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from murk.io.jobs import ErrorRecord, JobSummary
from murk.snow.bank import ParticleBank


@dataclass
class SnowExtractSummary(JobSummary):
    """The job summary (``processed`` counts frames used) and the bank written."""

    command: str = "snow extract"
    bank: ParticleBank | None = None
    preview_dir: Path | None = None


def errors_path_of(bank_path: Path) -> Path:
    """Where the failures of an extraction go: ``<bank stem>_errors.jsonl`` beside the bank."""
    return bank_path.with_name(bank_path.stem + "_errors.jsonl")


def list_footage(inputs: Sequence[Path], exclude: Sequence[Path] = ()) -> list[Path | ErrorRecord]:
    """In input order: the files to read (image files and videos as given, the images of folders, recursively;
    each file once) and a record for each input that cannot be used. Images found in a folder below one of
    ``exclude`` (murk's own preview folder) are left out."""
    skip = [os.path.realpath(e) + os.sep for e in exclude]
    from murk.io.images import list_images
    from murk.io.rosbag import is_bag

    files: list[Path | ErrorRecord] = []
    problems = files
    seen: set[str] = set()
    for inp in inputs:
        if is_bag(inp):  # a ROS bag: its frames are read by read_footage
            inside = [inp]
        elif inp.is_dir():
            try:
                inside = list_images(inp, recursive=True, unusable=True)
            except OSError as exc:
                problems.append(ErrorRecord(str(inp), "list", f"{inp}: cannot list folder ({exc.strerror or exc})"))
                continue
            if not inside:
                problems.append(ErrorRecord(str(inp), "list", f"{inp}: folder holds no images"))
        elif inp.is_file() or os.path.lexists(inp):  # a FIFO, device or broken link: the reader records why
            inside = [inp]
        else:
            problems.append(ErrorRecord(str(inp), "list", f"{inp}: not found"))
            continue
        for f in inside:
            real = os.path.realpath(f)
            if f is not inp and any(real.startswith(e) for e in skip):
                continue
            if not os.path.isfile(f):  # a broken or looping link, a FIFO: each is recorded under its own name
                real = os.path.abspath(f)
            if real not in seen:
                seen.add(real)
                files.append(f)
    return files


def bank_previews(inputs: Sequence[Path]) -> list[Path]:
    """The preview folders of earlier banks inside the input folders (``X_preview/`` beside a bank ``X.npz``): their
    images are an image beside its mask, never footage."""
    found = []
    for inp in inputs:
        if inp.is_dir():
            for bank in inp.rglob("*"):
                preview = bank.with_name(bank.stem + "_preview")
                if bank.suffix.lower() == ".npz" and preview.is_dir():  # B.npz and B.NPZ alike
                    found.append(preview)
    return found


def read_footage(
    files: Sequence[Path | ErrorRecord], every: int, problems: list[ErrorRecord], topic: str | None = None
) -> Iterator[tuple[dict[str, Any], np.ndarray]]:
    """Yield (description, uint8 RGB) for image files and every ``every``-th frame of videos and of ROS bag
    topics (``topic``); records in ``files`` and what cannot be read are appended to ``problems`` in input
    order (a broken frame is recorded and the video or bag goes on)."""
    from murk.errors import InputFileError
    from murk.io.images import read_image
    from murk.io.rosbag import is_bag, iter_frames
    from murk.io.video import VIDEO_SUFFIXES, CaptureSource

    for f in files:
        if isinstance(f, ErrorRecord):
            problems.append(f)
            continue
        if is_bag(f):
            try:
                for bag_frame in iter_frames(f, topic, every=every):
                    if bag_frame.image is None:
                        why = f"{f}:{topic}: frame {bag_frame.index}: {bag_frame.error or 'cannot decode'}"
                        problems.append(ErrorRecord(f"{f}:{topic}", "decode", why, frame=bag_frame.index))
                        continue
                    img = bag_frame.image
                    yield (
                        {"path": str(f), "frame": bag_frame.message},
                        (img if img.dtype == np.uint8 else (img // 257).astype(np.uint8)),
                    )
            except InputFileError as exc:  # no such topic, unreadable bag: recorded like an unreadable file
                problems.append(ErrorRecord(str(f), "read", str(exc)))
            continue
        if f.suffix.lower() in VIDEO_SUFFIXES:
            try:
                source = CaptureSource(f)
            except InputFileError as exc:
                problems.append(ErrorRecord(str(f), "read", str(exc)))
                continue
            used = 0
            with source:
                for frame in source:
                    if frame.image is None:
                        why = f"{f}: frame {frame.index}: {frame.error or 'cannot decode'}"
                        problems.append(ErrorRecord(str(f), "decode", why, frame=frame.index))
                    elif frame.index % every == 0:
                        used += 1
                        yield {"path": str(f), "frame": frame.index}, frame.image
            if used == 0 and not any(p.input == str(f) for p in problems):
                problems.append(ErrorRecord(str(f), "read", f"{f}: video has no readable frame"))
            continue
        try:
            raw, _ = read_image(f)
        except (ValueError, OSError, MemoryError) as exc:  # unreadable or corrupt: recorded, skipped
            why = str(exc) if isinstance(exc, ValueError) else f"cannot read image ({exc})"
            problems.append(ErrorRecord(str(f), "read", why if why.startswith(str(f)) else f"{f}: {why}"))
            continue
        if raw.dtype != np.uint8:
            raw = (raw // 257).astype(np.uint8)
        yield {"path": str(f)}, raw


def extract_snow_bank(
    inputs: Sequence[Path],
    out: Path,
    config: Any,
    *,
    every: int = 10,
    topic: str | None = None,
    scale: tuple[float, float] = (0.3, 0.6),
    preview: bool = True,
    on_progress: Callable[[int, int | None], None] | None = None,
) -> SnowExtractSummary:
    """Cut marine-snow particles out of real footage into the bank ``out`` (.npz).

    With ``preview``, each source is written beside its mask into ``<bank stem>_preview/`` (white = kept
    particles, grey = components dropped by the area or elongation filters).

    Raises:
        ValueError: ``every`` < 1; ``scale`` not ``0 < a <= b``; ``out`` not a ``.npz`` file (so never an input
            image); the preview folder is an input folder; no particle was found (the message names the unreadable
            inputs first). A preview folder inside an input folder is fine: the recursive listing leaves its images
            out (and those of every earlier bank's preview folder, :func:`bank_previews`), on the first run and on
            reruns.
        OutputError: no space left on the device.
    """
    import cv2

    from murk.io.images import write_uint
    from murk.io.paths import check_output_location, output_names
    from murk.io.rosbag import is_bag
    from murk.snow.bank import extract_bank, save_bank

    if every < 1:
        raise ValueError(f"--every: expected >= 1, got {every}")
    if not 0.0 < scale[0] <= scale[1]:
        raise ValueError(f"--scale: expected 0 < a <= b (the smallest scale first, e.g. 0.3,0.6), got {scale}")
    if out.suffix.lower() != ".npz":
        raise ValueError(f"--out {out}: a particle bank is a .npz file; name it so (e.g. {out.with_suffix('.npz')})")
    preview_dir = out.with_name(out.stem + "_preview")
    if preview:  # the preview folder may lie inside an input folder: its images are left out of the listing
        check_output_location(
            preview_dir,
            [p for p in inputs if p.is_dir() and not is_bag(p)],
            option=f"--out {out}: the preview folder",
            inside="allow",
            why="its previews would be mixed with the footage",
        )
    summary = SnowExtractSummary(out=out, preview_dir=preview_dir if preview else None)
    files = list_footage(inputs, exclude=[preview_dir, *bank_previews(inputs)])
    problems: list[ErrorRecord] = []
    paths = [f for f in files if isinstance(f, Path)]
    names = {str(p): n for p, n in output_names(paths).items()}  # a/x.jpg and b/x.jpg: two previews

    def on_frame(desc: dict[str, Any], rgb: np.ndarray, ex: Any) -> None:
        summary.processed += 1
        if on_progress:
            on_progress(summary.processed, None)
        if not preview:
            return
        vis = np.zeros(rgb.shape[:2], np.uint8)
        if ex is not None:
            vis[ex.mask] = 90
            for p in ex.particles:
                h, w = p.mask.shape
                vis[p.y : p.y + h, p.x : p.x + w][p.mask] = 255
        panel = np.hstack([rgb, cv2.cvtColor(vis, cv2.COLOR_GRAY2RGB)])
        if panel.shape[1] > 1600:
            f = 1600 / panel.shape[1]
            panel = cv2.resize(panel, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
        name = names[desc["path"]] + (f"_f{desc['frame']:06d}" if "frame" in desc else "")
        write_uint(preview_dir / f"{name}.jpg", panel, jpeg_quality=90)

    try:
        report = extract_bank(read_footage(files, every, problems, topic), config, scale=scale, on_frame=on_frame)
    except ValueError as exc:  # no particle at all: say which inputs could not even be read
        message = _nothing_extracted(inputs, problems, summary.processed, str(exc))
        if preview and summary.processed:  # kept on purpose: the masks show why nothing was kept
            message += f"; the frames and their masks are in {preview_dir} (no bank written)"
        raise ValueError(message) from None
    save_bank(report.bank, out)
    summary.bank = report.bank
    for rec in [*problems, *report.problems]:
        summary.add_failure(rec)
    for warning in report.warnings:
        summary.note(warning)
    summary.write_errors(out.parent, errors_path_of(out).name)
    return summary.finish()


def _nothing_extracted(inputs: Sequence[Path], problems: list[ErrorRecord], frames: int, why: str) -> str:
    """The one-line error when no particle was found: names the inputs, and the unreadable ones first."""
    listed = "; ".join(p.error for p in problems[:3])
    more = f" and {len(problems) - 3} more" if len(problems) > 3 else ""
    if frames == 0:
        if not listed:
            names = ", ".join(map(str, inputs[:5])) + (f" and {len(inputs) - 5} more" if len(inputs) > 5 else "")
            return f"{names}: no image or video frame to extract particles from"
        return f"{listed}{more} (no image or video frame left to extract particles from)"
    return why + (f"; {len(problems)} input(s) could not be read: {listed}{more}" if problems else "")
