"""Running a restorer over images, video files and live streams (what ``murk enhance`` delegates to).

This module gathers the public names of the modules that do the work, one job each: :mod:`murk.enhance.inputs`
(input classification, output planning), :mod:`murk.enhance.job_common` (options, report, restore call, depth outputs),
:mod:`murk.enhance.image_job` (image files) and :mod:`murk.enhance.frame_job` (videos, cameras, streams).

Inputs: an image, a folder of images (optionally recursive), a glob, a video file, a camera index or a stream
URL (:func:`resolve_input`). Images are restored in batches of equal size and written with their size, format
and bit depth (16-bit PNG/TIFF stays 16-bit unless another format is asked for); frames of videos and streams
are written as a video (source frame rate) or as numbered images. When a method returns depth, every output
also gets ``depth/<stem>.png`` (uint16 millimetres) and ``depth_preview/<stem>.jpg`` (fixed 0-15 m colour
range), and videos optionally a coloured depth video.

Reliability: unreadable or undecodable inputs are recorded in ``errors.jsonl`` in the output folder and
skipped (the run continues; callers exit non-zero); ``errors.jsonl`` is rewritten by every run (it lists the
failures of the latest run only); a broken video frame is recorded and replaced by the previous output frame
so the video keeps its length and timing; outputs inside the input folder are never read back as inputs, and
the input folder itself is refused as output (:func:`murk.io.paths.check_output_location`); inputs whose
outputs would share a name get distinct names (:func:`murk.io.paths.output_names`); rerunning skips images
whose output exists (``overwrite=True`` redoes them); video files are written atomically (complete or absent),
live recordings directly and flushed (see :mod:`murk.io.video`). A full disk stops the run with
:class:`murk.errors.OutputError` (``PATH: no space left on device``), never a truncated file under a final name.

Timing: :class:`EnhanceReport` accumulates read (decode + conversion), restore and write (encode + files)
seconds, reported as milliseconds per frame, and frames per second over the wall time.
"""

from murk.enhance.frame_job import enhance_frames
from murk.enhance.image_job import enhance_images
from murk.enhance.inputs import EnhanceInput, ImageFormat, ImageJob, InputKind, plan_images, resolve_input
from murk.enhance.job_common import (
    SIXTEEN_BIT_SUFFIXES,
    EnhanceReport,
    OutputOptions,
    ProgressFn,
    StopFn,
    VideoBackendChoice,
    restore_batch,
)

__all__ = [
    "SIXTEEN_BIT_SUFFIXES",
    "EnhanceInput",
    "EnhanceReport",
    "ImageFormat",
    "ImageJob",
    "InputKind",
    "OutputOptions",
    "ProgressFn",
    "StopFn",
    "VideoBackendChoice",
    "enhance_frames",
    "enhance_images",
    "plan_images",
    "resolve_input",
    "restore_batch",
]
