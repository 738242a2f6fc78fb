"""``murk enhance`` as one library call: classify INPUT, then run the image job or the frame job on it
(:mod:`murk.enhance.inputs`, :mod:`murk.enhance.image_job`, :mod:`murk.enhance.frame_job`)."""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any, Protocol

from murk.enhance.bag import BagOptions
from murk.enhance.frame_job import enhance_frames
from murk.enhance.image_job import enhance_images
from murk.enhance.inputs import EnhanceInput, plan_images, resolve_input
from murk.enhance.job_common import EnhanceReport, OutputOptions, StopFn
from murk.enhance.restorer import Restorer, weights_used


class ProgressDisplay(Protocol):
    """What shows a run's progress: called with the report after every batch."""

    def update(self, report: EnhanceReport) -> Any: ...


DisplayFactory = Callable[[str, str, int | None, bool], AbstractContextManager[ProgressDisplay | None]]
"""``display(title, unit, total, live)``: a context manager around the run yielding its progress display
(``unit``: ``"images"`` or ``"frames"``)."""


RestorerOrBuilder = Restorer | Callable[[], Restorer]
"""A restorer, or a function that builds one (called once the input has been found)."""


def run_enhance(
    spec: str,
    out: Path,
    restorer: RestorerOrBuilder,
    options: OutputOptions | None = None,
    *,
    recursive: bool = False,
    batch: int = 1,
    max_frames: int | None = None,
    should_stop: StopFn | None = None,
    display: DisplayFactory | None = None,
    bag: BagOptions | None = None,
) -> tuple[EnhanceInput, EnhanceReport]:
    """Restore what ``spec`` designates (an image, a folder, a glob, a video file, a camera index, a stream URL,
    a ROS bag) into ``out``; ``max_frames`` caps images or frames. Returns the classified input and the run's
    report. ``bag`` holds the topic and output choices for a ROS bag (:mod:`murk.enhance.bag`).

    ``restorer`` is the method, or a function that builds it (e.g. ``lambda: create("jointid")``): that is called
    once the input and the output location have been checked, so that a missing input is reported at once, before
    a network (and torch) is loaded.

    Raises:
        InputFileError: nothing usable at ``spec``; ValueError: an output location or option that cannot work
            (bag options without a bag among them, a video's output that is the video itself).
    """
    from murk.io.paths import check_output_file
    from murk.io.rosbag import is_bag
    from murk.io.video import CaptureSource

    options = options or OutputOptions()
    shown = display or (lambda _title, _unit, _total, _live: contextlib.nullcontext(None))
    if is_bag(spec):
        return _run_bag(spec, out, restorer, options, bag or BagOptions(), batch, max_frames, should_stop, shown)
    if bag is not None and bag != BagOptions():
        raise ValueError(
            f"{spec}: --topic, --every, --out-topic, --depth-topic, --storage, --copy-topics need a ROS bag; leave "
            "them out for this input"
        )
    inp = resolve_input(spec, recursive=recursive, exclude=out)
    as_folder = _folder_note(out)
    if inp.kind == "images":
        jobs, out_dir = plan_images(inp, out, options.format)
        jobs = jobs[:max_frames] if max_frames else jobs
        method = _built(restorer)
        with shown(f"{method.name}: {inp.label}", "images", len(jobs), False) as d:
            report = enhance_images(
                jobs,
                method,
                out_dir,
                options,
                batch=batch,
                on_progress=None if d is None else d.update,
                should_stop=should_stop,
            )
        if as_folder:
            report.note(as_folder)
        unused = [
            flag for flag, set_ in (("--fps", options.fps is not None), ("--depth-video", options.depth_video)) if set_
        ]
        if unused:
            report.note(f"{' and '.join(unused)}: for video outputs; not used for images")
        return inp, report
    if inp.kind == "video":
        check_output_file(out, [str(inp.target)])  # a video written over its source, even with --overwrite
    with CaptureSource(inp.target) as source:  # type: ignore[arg-type]
        total = source.frame_count if max_frames is None else min(source.frame_count or max_frames, max_frames)
        method = _built(restorer)
        with shown(f"{method.name}: {inp.label}", "frames", total, source.live) as d:
            report = enhance_frames(
                source,
                method,
                out,
                options,
                batch=batch,
                max_frames=max_frames,
                on_progress=None if d is None else d.update,
                should_stop=should_stop,
            )
    if as_folder:
        report.note(as_folder)
    return inp, report


def _folder_note(out: Path) -> str:
    """What to tell a user whose ``--out`` looks like a file murk does not write (``result.gif``): it is a folder
    name to murk. Empty when ``out`` is an existing folder, has no suffix or one murk writes."""
    from murk.io.images import IMAGE_SUFFIXES
    from murk.io.video import VIDEO_SUFFIXES

    suffix = out.suffix.lower()
    if not suffix or out.is_dir() or suffix in IMAGE_SUFFIXES or suffix in VIDEO_SUFFIXES:
        return ""
    return f"--out {out}: {suffix} is not an image or video format murk writes, so {out} is a folder"


def _built(restorer: RestorerOrBuilder) -> Restorer:
    return restorer if isinstance(restorer, Restorer) else restorer()


def _run_bag(
    spec: str,
    out: Path,
    restorer: RestorerOrBuilder,
    options: OutputOptions,
    bag: BagOptions,
    batch: int,
    max_frames: int | None,
    should_stop: StopFn | None,
    shown: DisplayFactory,
) -> tuple[EnhanceInput, EnhanceReport]:
    from murk.enhance.bag import enhance_bag
    from murk.io.rosbag import BagSource

    with BagSource(spec, bag.topic, every=bag.every) as source:
        inp = EnhanceInput("bag", source.label, target=spec)
        total = source.frame_count if max_frames is None else min(source.frame_count or max_frames, max_frames)
        method = _built(restorer)
        with shown(f"{method.name}: {source.label}", "frames", total, False) as d:
            report = enhance_bag(
                source,
                method,
                out,
                options,
                bag=bag,
                batch=batch,
                max_frames=max_frames,
                on_progress=None if d is None else d.update,
                should_stop=should_stop,
            )
    return inp, report


def weights_line(restorer: Restorer, *, shipped: bool) -> str | None:
    """``<stage> weights: <file>`` for a method with learned weights (and, for the weights shipped with murk,
    which network they are; the weights of a network it builds on: ``water``'s Joint-ID; then each restoration with
    weights that a blend averages in, with the blend's weight: ``jointid``'s ``lite``; then each later stage of a chain
    with weights: ``lite+detail``'s ``detail``); None for a method without weights
    (:func:`murk.enhance.restorer.weights_used`)."""
    used = weights_used(restorer)
    stage = used.first
    if stage is None:
        return None
    what = {"jointid": "the 'small' Joint-ID murk trained", "lite": "the 'lite' network murk trained"}.get(stage.name)
    note = f" (shipped with murk: {what}, docs/models.md)" if shipped and what else ""
    if stage.base_weights:
        note += f"; distance and colour from the weights {stage.base_weights}"
    for other, blend in used.blended:
        weight = f"{blend.weight_label or 'weight'} {blend.weight:g}"
        note += f"; with {other.name}'s restoration blended in ({weight}): {other.weights}"
    for other in used.later:
        note += f"; then {other.name} weights: {other.weights}"
    return f"{stage.name} weights: {stage.weights}{note}"
