"""Writing procedural scenes to disk in the ``murk synth`` input layout (what ``murk scenes`` runs).

Output folder::

    OUT_DIR/rgb/scene_000000.png      clean RGB (8-bit PNG, or JPEG with rgb_format="jpg")
    OUT_DIR/depth/scene_000000.png    uint16 millimetres: line-of-sight distance along each pixel's ray
    OUT_DIR/scenes.jsonl              one line per scene: files, seed, camera intrinsics, the full scene
    OUT_DIR/scenes_config.yaml        the settings of the run (seed, size, sampler config, murk version)

Scene ``i`` is sampled from ``murk.rng.derive_seed(seed, i)``, so the output never depends on ``workers``.
Rerunning skips scenes whose RGB and depth files both exist and rewrites scenes.jsonl; ``errors.jsonl`` lists the
scenes that failed in the latest run (rewritten by every run, absent when none). Workers die with the parent
(:mod:`murk._workers`); a full disk stops the run with ``OutputError`` naming the file.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from murk._workers import worker_pool
from murk.io.atomic import make_output_folder
from murk.io.jobs import ErrorRecord, FolderSummary

CONFIG_NAME = "scenes_config.yaml"
JSONL_NAME = "scenes.jsonl"
ERRORS_NAME = "errors.jsonl"
DEPTH_NOTE = (
    "depth/*.png: uint16, millimetres, line-of-sight distance from the camera centre along each pixel's ray "
    "(not z-depth; z = distance * cos(angle to the optical axis)); rays that hit nothing within far_m are far_m"
)

_TEXTURES: dict[str, Any] = {}


def stem_of(index: int) -> str:
    """File stem of scene ``index``."""
    return f"scene_{index:06d}"


def load_textures(folder: Path, problems: list[ErrorRecord] | None = None) -> dict[str, Any]:
    """Image textures of ``folder`` by file name, resized by :func:`murk.scenes.prepare_image_texture`.

    With ``problems``, a texture that cannot be read (corrupt, unreadable, a broken link, a FIFO) is appended
    to it as one error record (stage ``texture``) and the others are used; without it, it is an error.

    Raises:
        InputFileError: no image in ``folder``, none of them readable, or (without ``problems``) one unreadable.
    """
    from murk.errors import InputFileError
    from murk.io import list_images, read_rgb
    from murk.io.images import IMAGE_SUFFIXES
    from murk.scenes import prepare_image_texture

    paths = list_images(folder, unusable=problems is not None)
    if not paths:
        raise InputFileError(
            folder, f"no images found for --textures (suffixes {', '.join(IMAGE_SUFFIXES)}); give a folder of images"
        )
    textures: dict[str, Any] = {}
    for p in paths:
        try:
            textures[p.name] = prepare_image_texture(read_rgb(p))
        except InputFileError as exc:
            if problems is None:
                raise
            problems.append(ErrorRecord(str(p), "texture", f"{exc}; the scenes use the other textures"))
    if not textures:
        raise InputFileError(folder, f"no readable texture image ({problems[0].error if problems else ''})")
    return textures


def _init_worker(textures: dict[str, Any]) -> None:
    import cv2

    cv2.setNumThreads(1)
    _TEXTURES.clear()
    _TEXTURES.update(textures)


def _init_pool_worker(textures: dict[str, Any]) -> None:
    from murk._workers import die_with_parent

    die_with_parent()
    _init_worker(textures)


def scene_record(index: int, seed: int, size: tuple[int, int], cfg: Any, rgb_suffix: str) -> tuple[Any, dict]:
    """(params, scenes.jsonl record) of scene ``index`` (sampling only, no rendering)."""
    from murk.rng import derive_seed
    from murk.scenes import intrinsics, sample_scene

    scene_seed = derive_seed(seed, index)
    params = sample_scene(scene_seed, cfg)
    stem = stem_of(index)
    record = {
        "index": index,
        "stem": stem,
        "file_name": f"rgb/{stem}{rgb_suffix}",
        "depth_file": f"depth/{stem}.png",
        "seed": scene_seed,
        "size": list(size),
        "intrinsics": intrinsics(params, size),
        "depth": "line-of-sight distance in metres along each pixel's ray (not z-depth); stored as uint16 mm",
        "near_m": params.near_m,
        "far_m": params.far_m,
        "scene": params.to_dict(),
    }
    return params, record


def render_job(job: tuple[int, str, int, tuple[int, int], Any, str]) -> tuple[dict, str, str | None]:
    """Render and write one scene unless both its files exist; returns (record, status, error)."""
    from murk._workers import stop_if_orphaned
    from murk.errors import OutputError
    from murk.io import write_depth_png, write_rgb
    from murk.scenes import render_scene

    stop_if_orphaned()
    index, out_dir, seed, size, cfg, rgb_suffix = job
    params, record = scene_record(index, seed, size, cfg, rgb_suffix)
    out = Path(out_dir)
    rgb_path = out / record["file_name"]
    depth_path = out / record["depth_file"]
    if rgb_path.is_file() and depth_path.is_file():
        return record, "skipped", None
    try:
        rgb, dist_m = render_scene(params, size, textures=_TEXTURES or None)
        write_rgb(rgb_path, rgb)
        write_depth_png(depth_path, dist_m)
    except OutputError:  # a full disk ends the run
        raise
    except (ValueError, OSError) as exc:
        return record, "failed", str(exc)
    return record, "rendered", None


def _settings(seed: int, size: tuple[int, int], cfg: Any, rgb_format: str, texture_names: list[str]) -> dict:
    from murk._version import __version__
    from murk.scenes import SCENE_FORMAT_VERSION

    return {
        "command": "scenes",
        "murk_version": __version__,
        "scene_format_version": SCENE_FORMAT_VERSION,
        "seed": seed,
        "size": list(size),
        "rgb_format": rgb_format,
        "textures": texture_names,
        "scene_config": cfg.to_dict(),
        "depth": DEPTH_NOTE,
    }


def _check_resume(path: Path, settings: dict) -> None:
    from murk._config import read_yaml

    if not path.is_file():
        return
    old = read_yaml(path, what="the settings of an earlier run")
    keys = ("murk_version", "scene_format_version", "seed", "size", "rgb_format", "textures", "scene_config")
    diff = [k for k in keys if old.get(k) != settings[k]]
    if diff:
        raise ValueError(
            f"{path}: this folder was written with different settings ({', '.join(diff)}); "
            "use a new output folder (or delete this one) instead of mixing scenes"
        )


@dataclass
class ScenesSummary(FolderSummary):
    """What :func:`write_scenes` did (:class:`murk.io.jobs.JobSummary`; ``processed`` counts rendered scenes)."""

    command: str = "scenes"

    @property
    def rendered(self) -> int:
        return self.processed


def write_scenes(
    out_dir: str | Path,
    *,
    count: int,
    size: tuple[int, int] = (640, 480),
    seed: int = 0,
    workers: int = 1,
    config: Any = None,
    textures: dict[str, Any] | None = None,
    rgb_format: str = "png",
    on_progress: Callable[[int, int], None] | None = None,
    texture_problems: Sequence[ErrorRecord] = (),
) -> ScenesSummary:
    """Render ``count`` scenes into ``out_dir`` (see the module docstring); resumable.

    ``texture_problems``: the textures :func:`load_textures` could not read; recorded in ``errors.jsonl``
    (the run exits 1) while the scenes are made with the other textures.

    Raises:
        ValueError: bad ``rgb_format``, or a folder written with different settings.
    """
    import yaml

    from murk.io.atomic import atomic_path, remove_stale_temporaries, write_text_atomic
    from murk.io.jsonl import dumps
    from murk.scenes import SceneConfig

    out_dir = Path(out_dir)
    if len(size) != 2 or not all(8 <= v <= 16384 for v in size):
        raise ValueError(f"size: expected 8 <= width, height <= 16384, got {size[0]}x{size[1]}")
    cfg = SceneConfig() if config is None else config
    tex = dict(textures or {})
    fmt = rgb_format.lower()
    if fmt not in ("png", "jpg"):
        raise ValueError(f"rgb_format: expected png or jpg, got {rgb_format!r}")
    suffix = ".png" if fmt == "png" else ".jpg"
    make_output_folder(out_dir)
    remove_stale_temporaries(out_dir)
    settings = _settings(seed, size, cfg, fmt, sorted(tex))
    _check_resume(out_dir / CONFIG_NAME, settings)
    write_text_atomic(out_dir / CONFIG_NAME, yaml.safe_dump(settings, sort_keys=False))
    make_output_folder(out_dir / "rgb")
    make_output_folder(out_dir / "depth")
    jobs = [(i, str(out_dir), seed, size, cfg, suffix) for i in range(count)]
    summary = ScenesSummary(out=out_dir)
    for rec in texture_problems:
        summary.add_failure(rec)
    done = 0
    with contextlib.ExitStack() as stack:
        tmp = stack.enter_context(atomic_path(out_dir / JSONL_NAME))
        f = stack.enter_context(open(tmp, "w", encoding="utf-8"))
        if workers == 1:
            _init_worker(tex)
            results: Any = map(render_job, jobs)
        else:  # on an error (Ctrl+C, a full disk) the queued scenes are cancelled and the workers stopped at once
            pool = stack.enter_context(worker_pool(workers, initializer=_init_pool_worker, initargs=(tex,)))
            results = pool.map(render_job, jobs, chunksize=max(1, min(16, count // (4 * workers))))
        for record, status, error in results:
            f.write(dumps(record) + "\n")
            if error is not None:
                summary.add_failure(ErrorRecord(record["file_name"], "render", error, index=record["index"]))
            elif status == "rendered":
                summary.processed += 1
            else:
                summary.skipped += 1
            done += 1
            if on_progress:
                on_progress(done, count)
    extra = _scenes_beyond(out_dir / "rgb", count)
    if extra:  # an earlier run with a larger --count: its files stay (murk synth would read them as pairs)
        summary.note(
            f"{extra} scene(s) of an earlier run with a larger --count remain in rgb/ and depth/ (not listed in "
            f"{JSONL_NAME}); murk synth reads every pair in the folder: delete them, or rerun with that count"
        )
    summary.write_errors(out_dir, ERRORS_NAME)  # (removes the records of an earlier run when none failed)
    return summary.finish()


def _scenes_beyond(rgb_dir: Path, count: int) -> int:
    """How many ``scene_NNNNNN`` images in ``rgb_dir`` have an index of ``count`` or more."""
    n = 0
    for p in rgb_dir.glob("scene_*"):
        digits = p.stem.removeprefix("scene_")
        n += digits.isdigit() and int(digits) >= count
    return n
