"""What ``murk enhance`` is asked to do: classify INPUT (images, a folder, a glob, a video file, a camera, a
stream URL) and plan the output path of every image (:func:`resolve_input`, :func:`plan_images`).

Outputs inside the input folder are never read back as inputs, and the input folder itself is refused as output
(:func:`murk.io.paths.check_output_location`); inputs whose outputs would share a name get distinct names
(:func:`murk.io.paths.output_names`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from murk.enhance.choices import ImageFormat
from murk.errors import InputFileError
from murk.io.images import IMAGE_SUFFIXES, glob_images, list_images
from murk.io.listing import real_path
from murk.io.paths import check_output_location, output_names
from murk.io.video import VIDEO_SUFFIXES, is_stream_url, redact_url

InputKind = Literal["images", "video", "stream", "bag"]
_GLOB_CHARS = set("*?[")


@dataclass(frozen=True)
class EnhanceInput:
    """What the INPUT argument designates. ``images`` and ``root`` (for relative output paths) are set for
    ``kind="images"``; ``target`` (a path, a camera index or a URL) for ``"video"``, ``"stream"`` and ``"bag"``
    (a ROS bag: its file or folder)."""

    kind: InputKind
    label: str
    images: tuple[Path, ...] = ()
    root: Path | None = None
    target: str | int | None = None


def resolve_input(spec: str, *, recursive: bool = False, exclude: Path | None = None) -> EnhanceInput:
    """Classify INPUT: an existing folder or image file, a video file (by suffix), a camera index (digits),
    a stream URL, or a glob of images. Images under ``exclude`` (the output folder) are left out.

    Raises:
        InputFileError: nothing exists at ``spec``, a glob or folder matches no image.
    """
    path = Path(spec)
    if path.is_dir():
        images = _exclude(list_images(path, recursive=recursive, unusable=True), exclude, path)
        if not images:
            videos = sorted(p.name for p in path.iterdir() if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES)
            if videos:
                hint = f" (videos are restored one at a time: murk enhance {path / videos[0]} --out ...)"
            else:
                hint = "" if recursive else " (use --recursive for subfolders)"
            raise InputFileError(path, f"no images found{hint}")
        return EnhanceInput("images", str(path), tuple(images), root=path)
    if path.is_file() or (os.path.lexists(path) and not _GLOB_CHARS & set(spec)):  # a FIFO: its reader says so
        if path.suffix.lower() in VIDEO_SUFFIXES:
            return EnhanceInput("video", str(path), target=str(path))
        return EnhanceInput("images", str(path), (path,), root=path.parent)
    if spec.strip().isdigit():
        return EnhanceInput("stream", f"camera {int(spec)}", target=int(spec))
    if is_stream_url(spec):
        return EnhanceInput("stream", redact_url(spec), target=spec.strip())
    if _GLOB_CHARS & set(spec):
        root = _glob_root(spec)
        images = _exclude(glob_images(spec, unusable=True), exclude, root)  # never follows a symlink loop
        if not images:
            raise InputFileError(
                spec,
                f"the pattern matches no image file (suffixes {', '.join(IMAGE_SUFFIXES)}); check the folder and the "
                "pattern ('**' matches any number of subfolders)",
            )
        return EnhanceInput("images", spec, tuple(images), root=root)
    raise InputFileError(
        spec,
        "not found (expected an image, a folder, a glob, a video file, a camera index or an rtsp:// / http:// URL)",
    )


def _exclude(images: list[Path], folder: Path | None, root: Path) -> list[Path]:
    """Drop images below ``folder`` (the output) when it lies inside the input ``root``; an output folder
    equal to the input, or above it with outputs landing inside it, is refused by :func:`plan_images`."""
    if folder is None:
        return images
    out = real_path(folder)
    if real_path(root).is_relative_to(out):
        return images
    return [p for p in images if not real_path(p).is_relative_to(out)]


def _glob_root(spec: str) -> Path:
    parts = Path(spec).parts
    root: list[str] = []
    for part in parts:
        if _GLOB_CHARS & set(part):
            break
        root.append(part)
    return Path(*root) if root else Path(".")


@dataclass(frozen=True)
class ImageJob:
    """One image to restore: ``src`` -> ``dst``; ``stem`` names its depth outputs (relative, no suffix)."""

    src: Path
    dst: Path
    stem: str


def plan_images(inp: EnhanceInput, out: Path, fmt: ImageFormat | None = None) -> tuple[list[ImageJob], Path]:
    """Output paths for the images of ``inp``; returns (jobs, output folder).

    ``out`` is a folder (outputs mirror the inputs' paths relative to the input folder or glob root), or, for
    a single image, a file path with an image suffix.

    Two inputs whose outputs would share a name (``x.jpg`` and ``x.png`` with ``fmt="png"``, or their depth
    maps ``depth/x.png``) get distinct names (``x_jpg``, ``x_png``; see :func:`murk.io.paths.output_names`).

    Raises:
        ValueError: the output folder is the input folder, an output would overwrite its input, or ``fmt``
            contradicts an output file's suffix.
    """
    if inp.kind != "images" or inp.root is None:
        raise ValueError(f"inp: expected an images input, got {inp.kind}")
    if out.suffix.lower() in VIDEO_SUFFIXES:
        raise ValueError(f"--out {out}: images are written to a folder or an image file, not a video; name a folder")
    if len(inp.images) == 1 and out.suffix.lower() in IMAGE_SUFFIXES and not out.is_dir():
        if fmt is not None and out.suffix.lower() not in _suffixes(fmt):
            raise ValueError(
                f"--format {fmt} contradicts the output file name {out.name}; leave --format out, or name the file "
                f"with {' or '.join(_suffixes(fmt))}"
            )
        jobs = [ImageJob(inp.images[0], out, out.stem)]
        out_dir = out.parent
    else:
        if out.suffix.lower() in IMAGE_SUFFIXES and not out.is_dir():
            raise ValueError(
                f"--out {out}: {len(inp.images)} images are written to a folder, not to one image file; give a "
                "folder name"
            )
        # an --out inside the input folder is fine: resolve_input leaves it out of the inputs
        check_output_location(out, [inp.root], inside="allow")
        names = output_names(list(inp.images), root=inp.root)
        jobs = []
        for src in inp.images:
            rel = src.relative_to(inp.root) if src.is_relative_to(inp.root) else Path(src.name)
            dst = out / (f"{names[src]}.{fmt}" if fmt else rel)  # without fmt the suffix keeps rel distinct
            jobs.append(ImageJob(src, dst, names[src]))
        out_dir = out
        root, out_real = real_path(inp.root), real_path(out)
        if not out_real.is_relative_to(root):  # (an --out inside the input folder is left out of the listing)
            for job in jobs:  # an --out above the input folder: outputs must not land inside the input folder
                if real_path(job.dst).is_relative_to(root):
                    raise ValueError(
                        f"--out {out}: the output {job.dst} would land inside the input folder {inp.root} (and be "
                        "read back as an input on a rerun); choose another folder"
                    )
    sources = {real_path(job.src): job.src for job in jobs}
    for job in jobs:
        hit = sources.get(real_path(job.dst))
        if hit is not None:
            what = "its input" if hit == job.src else f"the input {hit}"
            raise ValueError(f"--out {out}: the output {job.dst} would overwrite {what}; choose another --out")
    return jobs, out_dir


def _suffixes(fmt: str) -> tuple[str, ...]:
    return (".jpg", ".jpeg") if fmt == "jpg" else (f".{fmt}",)
