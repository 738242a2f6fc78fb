"""Training data sources.

- **files**: ``(input, target, depth)`` triplets from a ``murk synth`` output folder (its ``manifest.jsonl``)
  or from a Joint-ID list file (``<input> <enhanced_gt> <depth_gt> <depth_scale>`` per line).
- **online**: clean RGB-D (a folder with ``rgb/`` + ``depth/``, or procedural scenes) degraded on the training
  device every step with the batched torch twins of Eqs. (1)-(8); parameters are drawn afresh every epoch
  from ``derive_seed(seed, "online", epoch, sample)``, so runs are deterministic and no multi-gigabyte
  dataset is written to disk.

Samples are centre-cropped to the training size when loaded; random augmentation happens on the device
(:mod:`murk.train.augment`). Train/validation splits are made by clean image (stem), so variants of one
clean image never land on both sides.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from murk.errors import InputFileError
from murk.io.depth import read_depth
from murk.io.images import read_rgb
from murk.io.jobs import ErrorLog, ErrorRecord
from murk.io.jsonl import read_jsonl
from murk.io.pairs import DepthFrom, DepthOptions, RGBDSource, discover, load_pair
from murk.rng import derive_seed
from murk.train.augment import centre_crop


@dataclass(frozen=True)
class PairItem:
    """One training triplet on disk."""

    stem: str
    input_path: str
    target_path: str
    depth_path: str
    depth_scale: float = 1000.0


def items_from_synth_folder(folder: str | Path) -> list[PairItem]:
    """Triplets listed in a ``murk synth`` folder's manifest.jsonl (paths relative to the folder)."""
    folder = Path(folder)
    manifest = folder / "manifest.jsonl"
    if not manifest.is_file():
        raise InputFileError(
            folder,
            "no manifest.jsonl: not a 'murk synth' output folder (write one with 'murk synth', or set data.kind "
            "to what the folder holds)",
        )
    items = [  # depth from the layout prior (murk synth --depth-from layout) is no target: left out (all invalid)
        PairItem(
            r["stem"],
            str(folder / r["degraded"]),
            str(folder / r["clean"]),
            "" if r.get("depth_from") == "layout" else str(folder / r["depth"]),
            1000.0,
        )
        for r in read_jsonl(manifest)
    ]
    if not items:
        raise InputFileError(manifest, "lists no variants")
    return items


def items_from_list(list_file: str | Path, root: str | Path | None = None) -> list[PairItem]:
    """Triplets of a Joint-ID list file; relative paths are resolved against ``root`` (default: its folder).

    Raises:
        InputFileError: missing file, or a line without 4 fields / with a bad depth scale (line number named).
    """
    list_file = Path(list_file)
    if not list_file.is_file():
        raise InputFileError(list_file, "list file not found")
    base = Path(root) if root is not None else list_file.parent
    items = []
    for n, line in enumerate(list_file.read_text(encoding="utf-8").splitlines(), start=1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        f = line.split()
        if len(f) != 4:
            raise InputFileError(
                list_file, f"line {n}: expected '<input> <enhanced_gt> <depth_gt> <depth_scale>', got {len(f)} fields"
            )
        try:
            scale = float(f[3])
        except ValueError:
            raise InputFileError(list_file, f"line {n}: depth_scale {f[3]!r} is not a number") from None
        if not scale > 0:
            raise InputFileError(list_file, f"line {n}: depth_scale must be > 0, got {scale}")
        p = [str(Path(x) if Path(x).is_absolute() else base / x) for x in f[:3]]
        items.append(PairItem(Path(p[1]).stem, p[0], p[1], p[2], scale))
    if not items:
        raise InputFileError(list_file, "lists no samples")
    return items


def split_by_stem(stems: Sequence[str], val_fraction: float, seed: int) -> tuple[list[int], list[int]]:
    """Indices of the training and validation parts; each stem goes wholly to one side (hash-based)."""
    if not 0 <= val_fraction < 1:
        raise ValueError(f"val_fraction: expected 0 <= f < 1, got {val_fraction}")
    unique = sorted(set(stems))
    if val_fraction == 0 or len(unique) < 2:
        return list(range(len(stems))), []
    ranked = sorted(unique, key=lambda s: derive_seed(seed, "split", s))
    n_val = max(1, round(val_fraction * len(unique)))
    val = set(ranked[:n_val])
    tr = [i for i, s in enumerate(stems) if s not in val]
    va = [i for i, s in enumerate(stems) if s in val]
    return tr, va


def _chw(a: np.ndarray) -> torch.Tensor:
    return torch.from_numpy(np.ascontiguousarray(a.transpose(2, 0, 1)))


MAX_SUBSTITUTES = 16
"""How many following samples a dataset tries in place of an unreadable one before the run stops."""


def first_readable(n: int, i: int, load: Callable[[int], dict[str, Any]]) -> dict[str, Any]:
    """``load(i)``, or, when sample ``i`` cannot be read (:class:`InputFileError`), the first readable of the
    next samples ``i+1, i+2, ...`` (wrapping; at most :data:`MAX_SUBSTITUTES` tries). The sample's ``failed``
    entry lists what could not be read, one ``path<TAB>problem`` per line ("" when nothing failed), so that the
    training loop records each in ``errors.jsonl`` and the run goes on (deterministically: the substitute
    depends on ``i`` only).

    Raises:
        InputFileError: none of the tried samples could be read (the last problem, and how many were tried).
    """
    failed: list[str] = []
    last: InputFileError | None = None
    for k in range(min(n, MAX_SUBSTITUTES + 1)):
        try:
            sample = load((i + k) % n)
        except InputFileError as exc:
            failed.append(f"{exc.path}\t{exc.problem}")
            last = exc
            continue
        sample["failed"] = "\n".join(failed)
        return sample
    assert last is not None
    raise InputFileError(last.path, f"{last.problem} (and the {len(failed) - 1} samples after it could not be read)")


def record_unreadable(batch: dict[str, Any], errors: ErrorLog | None) -> None:
    """Record in ``errors.jsonl`` each input a dataset could not read (the ``failed`` entries of ``batch``;
    each file once per run) and drop the entry from the batch."""
    failed = batch.pop("failed", None)
    if errors is None or not failed:
        return
    seen = {r.input for r in (errors.summary.failures if errors.summary else [])}
    for text in failed:
        for line in str(text).splitlines():
            path, _, problem = line.partition("\t")
            if path not in seen:
                seen.add(path)
                errors.add(ErrorRecord(path, "read", f"{path}: {problem}; a readable sample was used in its place"))


class FileDataset(Dataset):
    """A dataset read from files: sample ``i`` is ``self._load(i)``, and an unreadable one is replaced by the next
    readable sample and reported (:func:`first_readable`). A subclass fills ``entries`` (one per sample) and writes
    ``_load``."""

    entries: list[Any]

    def __len__(self) -> int:
        return len(self.entries)

    def __getitem__(self, i: int) -> dict[str, Any]:
        sample = first_readable(len(self), i, self._load)
        sample["index"] = self._index(i)  # a substitute keeps the requested index: its online water is i's own
        return sample

    def _index(self, i: int) -> int:
        return i

    def _load(self, i: int) -> dict[str, Any]:
        raise NotImplementedError


class PairDataset(FileDataset):
    """Triplets from files, centre-cropped to ``size_hw``: ``input``, ``target`` (3, H, W) in [0, 1],
    ``depth`` (1, H, W) metres with 0 = invalid, ``index``, and ``failed`` (see :func:`first_readable`: an
    unreadable sample is replaced by the next readable one and reported)."""

    def __init__(self, items: Sequence[PairItem], size_hw: tuple[int, int]) -> None:
        self.entries = list(items)
        self.size_hw = size_hw

    def _load(self, i: int) -> dict[str, Any]:
        it = self.entries[i]
        x = read_rgb(it.input_path)
        y = read_rgb(it.target_path)
        if it.depth_path:
            d = read_depth(it.depth_path, depth_scale=it.depth_scale)
            d = np.where(np.isfinite(d) & (d > 0), d, 0.0).astype(np.float32)
        else:  # no measured depth: every pixel invalid, so no depth loss
            d = np.zeros(x.shape[:2], np.float32)
        if x.shape != y.shape or x.shape[:2] != d.shape:
            raise InputFileError(it.input_path, f"input/target/depth sizes differ: {x.shape}, {y.shape}, {d.shape}")
        x, y, d = centre_crop([x, y, d[:, :, None]], self.size_hw, source=it.input_path)
        return {"input": _chw(x), "target": _chw(y), "depth": _chw(d), "index": i}


class CleanRGBDDataset(FileDataset):
    """Clean RGB-D for online synthesis, centre-cropped: ``clean`` (3, H, W), ``depth_filled`` (1, H, W)
    (holes filled, for the physics), ``depth`` (1, H, W) (0 = invalid, the training target), ``index``, and
    ``failed`` (see :func:`first_readable`)."""

    def __init__(self, sources: Sequence[RGBDSource], size_hw: tuple[int, int], options: DepthOptions) -> None:
        self.entries = list(sources)
        self.size_hw = size_hw
        self.options = options

    def _load(self, i: int) -> dict[str, Any]:
        src = self.entries[i]
        rgb, depth, valid = load_pair(src, self.options)
        rgb, depth, valid = centre_crop([rgb, depth[:, :, None], valid[:, :, None]], self.size_hw, source=src.rgb_path)
        gt = depth_target(depth, valid, self.options)
        return {"clean": _chw(rgb), "depth_filled": _chw(depth), "depth": _chw(gt), "index": i}


def depth_target(depth: np.ndarray, valid: np.ndarray, options: DepthOptions) -> np.ndarray:
    """The depth a network learns from: the valid measured depth (0 = invalid); all 0 when the distance is the
    layout prior's (``depth_from="layout"``), which drives the synthesis but is no measurement to learn."""
    if options.depth_from == "layout":
        return np.zeros(depth.shape, np.float32)
    return np.where(valid, depth, 0.0).astype(np.float32)


def rgbd_sources(folder: str | Path, depth_from: DepthFrom = "file") -> list[RGBDSource]:
    """The clean RGB-D pairs of a folder (``rgb/`` + ``depth/``; photographs alone with ``depth_from="layout"``);
    unpaired files are an error here."""
    sources, problems = discover(folder, depth_from)
    if problems:
        raise InputFileError(problems[0].input, problems[0].error)
    return sources


class OnlineDegrader:
    """Degrades clean batches on their device with the batched torch twins of Eqs. (1)-(8).

    Variant parameters of sample ``i`` in epoch ``e`` come from ``derive_seed(seed, "online", e, i)``:
    :meth:`params` gives them, so the numpy pipeline can reproduce any training input exactly.
    """

    def __init__(self, synth_config: Any, *, seed: int, bank: Any = None) -> None:
        from murk.synth.params import snow_sampler_for

        self.config = synth_config
        self.seed = seed
        self.bank = bank
        if "marine_snow" in synth_config.stages and bank is None:
            from murk.data import default_snow_bank
            from murk.snow.bank import load_bank

            self.bank = load_bank(synth_config.marine_snow.bank or default_snow_bank())
        self._sampler = snow_sampler_for(synth_config, self.bank) if "marine_snow" in synth_config.stages else None

    def params(self, epoch: int, indices: Sequence[int]) -> list[Any]:
        from murk.synth.params import sample_variant

        return [
            sample_variant(
                np.random.default_rng(derive_seed(self.seed, "online", epoch, int(i))),
                self.config,
                snow_sampler=self._sampler,
            )
            for i in indices
        ]

    def __call__(
        self, clean: torch.Tensor, depth_filled: torch.Tensor, epoch: int, indices: Sequence[int]
    ) -> torch.Tensor:
        return self.render(clean, depth_filled, epoch, indices).degraded

    def render(self, clean: torch.Tensor, depth_filled: torch.Tensor, epoch: int, indices: Sequence[int]) -> Any:
        """The whole rendered batch (:class:`murk.synth.render.BatchResult`: the degraded inputs and, with marine
        snow, each input's particle alpha, which ``loss.snow`` weights)."""
        from murk.synth.render import render_batch_torch

        return render_batch_torch(clean, depth_filled, self.params(epoch, indices), bank=self.bank)
