"""What both dataset writers of ``murk synth`` share: the loose-file runner (:mod:`murk.synth.runner`) and the
tar-shard writer (:mod:`murk.synth.shards`, also run by :mod:`murk.synth.ray_backend`'s tasks).

- :class:`Shard`: which part of the sorted inputs a process takes (``--shard i/N``, SLURM array variables);
- the per-variant pieces, so that both writers produce the same samples: :func:`load_source` (a pair as the run
  renders it) with :func:`fit_size` (``--size``),
  :func:`depth_range_note`, :func:`variant_info` and :func:`manifest_record` (one manifest line);
- the checks of the output folder: :func:`input_locations` with :data:`OVERLAP_WHY` (the output may not overlap
  the inputs) and :func:`check_config_compatible` (no mixing of two configurations in one folder);
- the particle bank: :func:`check_snow_bank` (before any output) and :func:`setup_worker` (each worker process).

Imports flow one way (pyproject's import-linter contract): runner -> shards -> ray_backend, and each of them ->
this module -> params -> config; nothing here imports a writer.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from murk._config import from_dict, read_yaml, to_dict
from murk.io.pairs import DepthOptions, RGBDSource, load_pair
from murk.synth.config import SynthConfig
from murk.synth.params import VariantParams, variant_to_dict

DEPTH_SCALE_OUT = 1000.0
"""depth/ PNGs (and the shards' depth members) are millimetres."""


@dataclass(frozen=True)
class Shard:
    """Shard ``index`` of ``count`` (0-based): the sorted inputs ``index, index + count, ...``."""

    index: int = 0
    count: int = 1

    def __post_init__(self) -> None:
        if not (self.count >= 1 and 0 <= self.index < self.count):
            raise ValueError(f"shard: expected 0 <= i < N, got {self.index}/{self.count}")

    @property
    def tag(self) -> str:
        return "all" if self.count == 1 else f"{self.index}-of-{self.count}"

    @staticmethod
    def parse(spec: str | None, env: dict[str, str] | None = None) -> Shard:
        """Parse ``"i/N"``; without a spec use SLURM array variables when set (index = TASK_ID - TASK_MIN)."""
        if spec:
            try:
                i, n = (int(v) for v in spec.split("/"))
            except ValueError:
                raise ValueError(f"--shard: expected i/N (e.g. 0/4), got {spec!r}") from None
            return Shard(i, n)
        env = dict(os.environ) if env is None else env
        if "SLURM_ARRAY_TASK_ID" in env and "SLURM_ARRAY_TASK_COUNT" in env:

            def var(name: str, default: str | None = None) -> int:
                value = env.get(name, default)
                try:
                    return int(value)  # type: ignore[arg-type]
                except (TypeError, ValueError):
                    raise ValueError(f"{name}: expected an integer (SLURM array variable), got {value!r}") from None

            task = var("SLURM_ARRAY_TASK_ID") - var("SLURM_ARRAY_TASK_MIN", "0")
            try:
                return Shard(task, var("SLURM_ARRAY_TASK_COUNT"))
            except ValueError as exc:
                raise ValueError(f"SLURM array variables: {exc}") from None
        return Shard()


def load_source(source: RGBDSource, config: SynthConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One RGB-D pair as the run renders it: (clean RGB, depth in metres, valid mask), cropped and resized as
    configured (see :func:`murk.io.pairs.load_pair`; its errors propagate)."""
    inp = config.input
    opts = DepthOptions(
        inp.depth_scale,
        inp.depth_relative,
        inp.invalid_depth,
        inp.crop_px,
        inp.depth_encoding,
        depth_from=inp.depth_from,
        layout_seed=config.seed,
    )
    rgb, depth, valid = load_pair(source, opts)
    return fit_size(rgb, depth, valid, inp.size)


def fit_size(
    rgb: np.ndarray, depth: np.ndarray, valid: np.ndarray, size: tuple[int, int] | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre-crop to the aspect ratio of ``size`` = (width, height), then resize (area/cubic for RGB,
    nearest for depth and validity so depth edges are never blended)."""
    if size is None:
        return rgb, depth, valid
    tw, th = size
    h, w = depth.shape
    if w * th > tw * h:  # too wide: crop columns
        cw = max(1, round(h * tw / th))
        x0 = (w - cw) // 2
        rgb, depth, valid = rgb[:, x0 : x0 + cw], depth[:, x0 : x0 + cw], valid[:, x0 : x0 + cw]
    elif w * th < tw * h:
        ch = max(1, round(w * th / tw))
        y0 = (h - ch) // 2
        rgb, depth, valid = rgb[y0 : y0 + ch], depth[y0 : y0 + ch], valid[y0 : y0 + ch]
    h, w = depth.shape
    if (w, h) == (tw, th):
        return np.ascontiguousarray(rgb), np.ascontiguousarray(depth), np.ascontiguousarray(valid)
    interp = cv2.INTER_AREA if tw < w else cv2.INTER_CUBIC
    rgb = np.clip(cv2.resize(np.ascontiguousarray(rgb), (tw, th), interpolation=interp), 0.0, 1.0)
    depth = cv2.resize(np.ascontiguousarray(depth), (tw, th), interpolation=cv2.INTER_NEAREST)
    valid = cv2.resize(valid.astype(np.uint8), (tw, th), interpolation=cv2.INTER_NEAREST).astype(bool)
    return rgb, depth, valid


def manifest_record(
    source: RGBDSource, k: int, seed: int, params: VariantParams, result_info: dict[str, Any], files: dict[str, str]
) -> dict[str, Any]:
    """One manifest line: flat fields named as in the synthesis spec, plus ``params`` (exact re-render input)."""
    m, fs, sn = params.medium, params.forward_scatter, params.snow
    rec: dict[str, Any] = {
        "stem": source.stem,
        "variant": k,
        "seed": seed,
        "source_rgb": source.rgb_path,
        "source_depth": source.depth_path,
        "stages": list(params.stages),
        **files,
        **result_info,
    }
    if source.mat_index is not None:
        rec["source_index"] = source.mat_index
    if not source.depth_path and source.mat_index is None:
        rec["depth_from"] = "layout"  # depth/ holds the layout prior (murk.io.distance_prior), not a measurement
    if m is not None:
        rec.update(
            water_type=m.water_type,
            beta=list(m.beta_per_m),
            B_inf=list(m.b_inf),
            D=m.vertical_depth_m,
            H=m.far_m,
            d_near=m.near_m,
            distance_mode=m.distance_mode,
        )
        if m.illuminant_rgb is not None:
            rec["illuminant"] = list(m.illuminant_rgb)
    if fs is not None:
        rec.update(fs_mode=fs.mode, sigma0=fs.sigma0_px, k=fs.k_px_per_m, gamma=fs.gamma_per_m)
    if sn is not None:
        rec.update(N_p=sn.n_particles, s=list(sn.scale_range), rho=sn.rho_px, bank_id=sn.bank_id)
    rec["params"] = variant_to_dict(params)
    return rec


def variant_info(res: Any, w: int, h: int, valid_fraction: float, note: str | None) -> dict[str, Any]:
    """The manifest's per-variant figures: size, distance range, largest blur, valid depth fraction and the
    depth warning (if any); the same for loose files and shards. ``valid_fraction``: the share of valid depth
    pixels, ``valid.mean()`` (the same for every variant of an image: computed once)."""
    lo, hi = res.dist_range_m or (float(res.dist_m.min()), float(res.dist_m.max()))
    info: dict[str, Any] = {
        "width": w,
        "height": h,
        "dist_min_m": lo,
        "dist_max_m": hi,
        "sigma_max": res.sigma_max_px,
        "valid_depth_fraction": float(valid_fraction),
    }
    if note:
        info["depth_warning"] = note
    return info


def depth_range_note(source: RGBDSource, valid_depth_m: np.ndarray) -> str | None:
    """A warning when a depth map's values are implausible in metres (a wrong --depth-scale/--depth-encoding)."""
    if valid_depth_m.size == 0 or source.mat_index is not None:
        return None
    med = _median(valid_depth_m)
    if 0.1 <= med <= 20.0:  # underwater scenes end at 15 m: a larger median means a wrong scale or encoding
        return None
    return (
        f"{source.depth_path}: median depth {med:.3g} m is implausible for a camera scene; check --depth-scale "
        "(1000 mm, 5000 TUM, 256 KITTI) and --depth-encoding (sun, kinect-disparity)"
    )


def _median(values: np.ndarray) -> float:
    """``numpy.median`` by a partial sort (equal): ``numpy.median`` imports ``numpy.ma`` (20 ms) on its first call,
    in every synthesis worker."""
    flat = values.ravel()
    k = flat.size // 2
    if flat.size % 2:
        return float(np.partition(flat, k)[k])
    part = np.partition(flat, (k - 1, k))
    return float((part[k - 1] + part[k]) / 2)


OVERLAP_WHY = "the outputs would overwrite or mix with the input files"
"""Why an output folder may not overlap the input folders (the reason :func:`murk.io.paths.check_output_location`
gives)."""


def input_locations(sources: Sequence[RGBDSource]) -> list[Path]:
    """The folders of the input files, each once: what the output folder may not be or lie inside, and what its
    output subfolders may not hold. (A NYU ``.mat`` file is left out: no output can replace it.)"""
    seen: dict[str, Path] = {}
    for s in sources:
        if s.mat_index is None:
            paths = (s.rgb_path, s.depth_path) if s.depth_path else (s.rgb_path,)  # a photograph: no depth file
            for folder in (os.path.dirname(p) for p in paths):
                seen.setdefault(folder, Path(folder or "."))
    return list(seen.values())


def check_config_compatible(out_dir: Path, config: SynthConfig) -> None:
    """Refuse to add to a folder made with a different configuration (the results would not be one dataset)."""
    path = out_dir / "config.yaml"
    if not path.exists():
        return
    old = read_yaml(path, what="the configuration of an earlier run")
    known = {f.name for f in dataclasses.fields(SynthConfig)}
    try:  # options added since that run take their defaults, which reproduce what it did
        old = {**old, **to_dict(from_dict(SynthConfig, {k: v for k, v in old.items() if k in known}, where=str(path)))}
    except (TypeError, ValueError):
        pass  # not a configuration this murk can read: compared as written, so it is refused below
    new = to_dict(config)
    diffs = [
        k
        for k in sorted(set(old) | set(new))
        if k not in ("workers", "murk_version") and old.get(k) != new.get(k) and k in new
    ]
    if diffs:
        raise ValueError(
            f"{out_dir}: this folder was generated with a different configuration (differs in: "
            f"{', '.join(diffs)}); use a new output folder, or delete this one to start over"
        )


def check_snow_bank(config: SynthConfig, bank_path: str | None) -> None:
    """Refuse the marine_snow stage without a particle bank, and read the bank once, so that a bad one fails here
    (an ``InputFileError`` naming it) before any output is written or any worker started.

    Raises:
        ValueError: marine_snow without a bank.
        InputFileError: the bank cannot be read.
    """
    if "marine_snow" in config.stages and not bank_path:
        raise ValueError("stages: marine_snow needs a particle bank (--snow-bank)")
    if bank_path:
        from murk.snow.bank import load_bank

        load_bank(bank_path)


def setup_worker(bank_path: str | None) -> Any:
    """Per-process set-up of a synthesis worker (or of the one process of a run without workers): the allocator
    tuned, one OpenCV thread; returns the particle bank at ``bank_path``, loaded once (None without one)."""
    from murk._perf import tune_allocator

    tune_allocator()
    cv2.setNumThreads(1)
    if not bank_path:
        return None
    from murk.snow.bank import load_bank

    return load_bank(bank_path)
