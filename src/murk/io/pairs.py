"""Finding RGB-D pairs: a folder (``rgb/`` or ``color/`` beside ``depth/``), a list file, or a NYU ``.mat``; or
clean photographs without depth, given the distance of the ground-plane layout prior (``depth_from="layout"``,
:mod:`murk.io.distance_prior`).

A pair is described by an :class:`RGBDSource` (paths only, cheap to pickle to worker processes) and loaded
by :func:`load_pair`, which applies the depth options and checks that sizes agree.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from murk.errors import InputFileError
from murk.io.depth import DepthEncoding, InvalidDepthMode, nyu_mat_count, read_depth, read_nyu_mat, resolve_invalid
from murk.io.distance_prior import layout_distance, sample_layout
from murk.io.images import IMAGE_SUFFIXES, read_image, to_float
from murk.io.jobs import ErrorRecord
from murk.io.listing import describe_unusable, walk_files
from murk.rng import derive_seed

DEPTH_SUFFIXES = (*IMAGE_SUFFIXES, ".pgm", ".npy")
DepthFrom = Literal["file", "layout"]
DEPTH_FROM: tuple[str, ...] = ("file", "layout")


@dataclass(frozen=True)
class RGBDSource:
    """Where one clean RGB-D pair comes from. ``mat_index`` is set for frames of a NYU ``.mat`` file;
    ``depth_path`` is empty for a photograph whose distance comes from the layout prior."""

    stem: str
    rgb_path: str
    depth_path: str
    mat_index: int | None = None


@dataclass(frozen=True)
class DepthOptions:
    """How to interpret depth files (see :mod:`murk.io.depth`)."""

    depth_scale: float = 1000.0
    relative: bool = False
    invalid: InvalidDepthMode = "fill"
    crop_px: int = 0
    encoding: DepthEncoding = "linear"
    depth_from: DepthFrom = "file"
    """``file``: the pair's depth file; ``layout``: the ground-plane prior of :mod:`murk.io.distance_prior`, drawn
    per photograph from ``layout_seed`` and its stem (the same photograph always gets the same distance)."""
    layout_seed: int = 0


def discover(path: str | Path, depth_from: DepthFrom = "file") -> tuple[list[RGBDSource], list[ErrorRecord]]:
    """Find pairs in a folder with ``rgb/`` (or ``color/``) and ``depth/`` matched by file stem, or in a NYU-v2
    ``.mat`` file (with ``depth_from="layout"``: photographs alone, :func:`discover_photos`). Unmatched files are
    returned as error records (stage ``"pair"``), not raised, and so is a stem shared by several files of one
    folder (``rgb/x.png`` + ``rgb/x.jpg``, ``depth/x.npy`` + ``depth/x.png``): that pair is left out and the
    record names every file, the other pairs go on.

    Raises:
        InputFileError: the path does not exist or has neither layout.
    """
    if depth_from == "layout":
        return discover_photos(path)
    if depth_from != "file":
        raise ValueError(f"depth_from: expected one of {', '.join(DEPTH_FROM)}, got {depth_from!r}")
    path = Path(path)
    if path.is_file() and path.suffix.lower() == ".mat":
        return [RGBDSource(f"{path.stem}_{i:05d}", str(path), str(path), i) for i in range(nyu_mat_count(path))], []
    if not path.exists():
        raise InputFileError(path, "not found")
    if not path.is_dir():
        raise InputFileError(path, "expected a folder with rgb/ and depth/, a --list file, or a NYU .mat file")
    rgb_dir = next((path / n for n in ("rgb", "color") if (path / n).is_dir()), None)
    depth_dir = path / "depth"
    if rgb_dir is None or not depth_dir.is_dir():
        raise InputFileError(path, "expected subfolders rgb/ (or color/) and depth/ with files matched by stem")
    rgbs, rgb_clash = _by_stem(rgb_dir, IMAGE_SUFFIXES)
    depths, depth_clash = _by_stem(depth_dir, DEPTH_SUFFIXES)
    if not rgbs and not rgb_clash:
        raise InputFileError(rgb_dir, f"no images found (recognised suffixes: {', '.join(IMAGE_SUFFIXES)})")
    sources, problems = [], []
    for stem in sorted(set(rgbs) | set(rgb_clash)):
        clash = [*rgb_clash.get(stem, []), *depth_clash.get(stem, [])]
        if clash:  # several files claim this pair: using one silently could pair the wrong data
            names = ", ".join(str(p) for p in clash)
            problems.append(
                ErrorRecord(
                    str(clash[0]), "pair", f"ambiguous stem '{stem}': {names} share it; rename or remove all but one"
                )
            )
        elif stem in depths:
            sources.append(RGBDSource(stem, str(rgbs[stem]), str(depths[stem])))
        else:
            problems.append(_unpaired(rgbs[stem], f"no depth file with stem '{stem}' in {depth_dir}"))
    for stem in sorted((set(depths) | set(depth_clash)) - set(rgbs) - set(rgb_clash)):
        path = depths[stem] if stem in depths else depth_clash[stem][0]
        problems.append(_unpaired(path, f"no RGB image with stem '{stem}' in {rgb_dir}"))
    return sources, problems


def discover_photos(path: str | Path) -> tuple[list[RGBDSource], list[ErrorRecord]]:
    """Clean photographs without depth: the images of ``rgb/`` (or ``color/``) when the folder has one, else the
    folder's own image files (not its subfolders); a ``depth/`` folder beside them is not read. A stem shared by
    several files is left out and recorded (stage ``"pair"``), as in :func:`discover`.

    Raises:
        InputFileError: the path is not a folder, or holds no image.
    """
    path = Path(path)
    if not path.is_dir():
        raise InputFileError(path, "not found" if not path.exists() else "expected a folder of photographs")
    folder = next((path / n for n in ("rgb", "color") if (path / n).is_dir()), path)
    photos, clash = _by_stem(folder, IMAGE_SUFFIXES)
    if not photos and not clash:
        raise InputFileError(folder, f"no images found (recognised suffixes: {', '.join(IMAGE_SUFFIXES)})")
    problems = [
        ErrorRecord(str(files[0]), "pair", f"ambiguous stem '{stem}': {', '.join(map(str, files))} share it")
        for stem, files in sorted(clash.items())
    ]
    return [RGBDSource(stem, str(photos[stem]), "") for stem in sorted(photos)], problems


def _unpaired(path: Path, missing: str) -> ErrorRecord:
    """The record of a file without its other half; an entry that is no file (a broken link, a symlink loop, a
    FIFO) is recorded as what it is, since that, not the missing half, is what the user has to fix."""
    why = describe_unusable(path)
    return ErrorRecord(str(path), "read", why) if why else ErrorRecord(str(path), "pair", missing)


def read_list(list_file: str | Path) -> list[RGBDSource]:
    """Read a pair list: one ``rgb_path depth_path`` per line (``#`` comments; relative paths are resolved
    against the list file's folder). Stems come from the RGB file names; duplicates get a numeric suffix.

    Raises:
        InputFileError: missing file, or a line without exactly two fields (the line number is named).
    """
    list_file = Path(list_file)
    if not list_file.is_file():
        raise InputFileError(list_file, "list file not found")
    sources: list[RGBDSource] = []
    seen: dict[str, int] = {}
    used: set[str] = set()
    for n, line in enumerate(list_file.read_text(encoding="utf-8").splitlines(), start=1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        fields = line.split()
        if len(fields) != 2:
            raise InputFileError(list_file, f"line {n}: expected 'rgb_path depth_path', got {len(fields)} fields")
        rgb, depth = (Path(f) if Path(f).is_absolute() else list_file.parent / f for f in fields)
        stem = base = rgb.stem
        while stem in used:  # x, x, x_1 -> x, x_1, x_1_1: every output name distinct
            seen[base] = seen.get(base, 0) + 1
            stem = f"{base}_{seen[base]}"
        used.add(stem)
        sources.append(RGBDSource(stem, str(rgb), str(depth)))
    if not sources:
        raise InputFileError(list_file, "no pairs listed (expected one 'rgb_path depth_path' per line)")
    return sources


def load_pair(source: RGBDSource, options: DepthOptions) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Load a pair as (clean float32 RGB in [0, 1], depth float32 metres with invalid pixels resolved,
    validity mask). ``crop_px`` trims that many pixels from every border of both.

    Raises:
        InputFileError: unreadable files, a size mismatch (both files named), a crop larger than the image,
            or invalid depth under ``invalid="fail"``.
    """
    if source.mat_index is not None:
        rgb_u, depth = read_nyu_mat(source.rgb_path, source.mat_index)
        where = f"{source.rgb_path}[{source.mat_index}]"
    elif options.depth_from == "layout" or not source.depth_path:
        rgb_u, _ = read_image(source.rgb_path)
        depth, where = layout_depth(source.stem, rgb_u.shape[0], rgb_u.shape[1], options.layout_seed), source.rgb_path
    else:
        rgb_u, _ = read_image(source.rgb_path)
        depth = read_depth(
            source.depth_path, depth_scale=options.depth_scale, relative=options.relative, encoding=options.encoding
        )
        where = source.depth_path
    if rgb_u.shape[:2] != depth.shape:
        raise InputFileError(
            source.rgb_path,
            f"size {rgb_u.shape[1]}x{rgb_u.shape[0]} does not match depth {source.depth_path} "
            f"({depth.shape[1]}x{depth.shape[0]})",
        )
    c = options.crop_px
    if c:
        h, w = depth.shape
        if 2 * c >= min(h, w):
            raise InputFileError(source.rgb_path, f"--crop {c} leaves nothing of a {w}x{h} image")
        rgb_u, depth = rgb_u[c : h - c, c : w - c], depth[c : h - c, c : w - c]
    depth, valid = resolve_invalid(depth, options.invalid, source=where)
    return to_float(np.ascontiguousarray(rgb_u)), np.ascontiguousarray(depth), np.ascontiguousarray(valid)


def layout_depth(stem: str, height: int, width: int, seed: int = 0) -> np.ndarray:
    """The layout prior's distance (metres) for the photograph ``stem``: its layout is drawn from
    ``derive_seed(seed, "layout", stem)``, so it does not depend on the order or number of photographs."""
    return layout_distance(height, width, sample_layout(derive_seed(seed, "layout", stem)))


def _by_stem(folder: Path, suffixes: tuple[str, ...]) -> tuple[dict[str, Path], dict[str, list[Path]]]:
    """Files of ``folder`` by stem: (stems with one file, stems shared by several files such as x.png + x.jpg).

    Entries that cannot be read as files (broken links, FIFOs, devices) are kept: the reader refuses each,
    so the pair is recorded as failed rather than reported as missing its other half."""
    groups: dict[str, list[Path]] = {}
    try:
        listed = walk_files(folder, unusable=True)
    except OSError as exc:
        raise InputFileError(folder, f"cannot list this input folder ({exc.strerror or exc})") from None
    for p in listed:
        if p.suffix.lower() in suffixes and not p.name.startswith("."):
            groups.setdefault(p.stem, []).append(p)
    unique = {stem: files[0] for stem, files in groups.items() if len(files) == 1}
    return unique, {stem: files for stem, files in groups.items() if len(files) > 1}
