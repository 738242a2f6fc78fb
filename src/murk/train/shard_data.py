"""Training from tar shards (``murk synth --format webdataset``), streamed, split across ranks and workers.

``data.source`` names the shards as a brace pattern (``'out/shards/{000000..000199}.tar'``), an ``index.json``,
or the folder holding it. Keys come from the index (beside the shards or one folder up); without one, the tar
headers are listed once at start-up.

An epoch, for ``world`` ranks with ``W`` DataLoader workers each (``S = world * W`` streams, ``W = 1`` with
``data.workers: 0``):

1. the shard order is a permutation drawn from ``derive_seed(seed, "shards", epoch)``; the training samples of
   the shards in that order form one sequence, cut into ``S`` equal contiguous ranges of ``L`` samples
   (``L`` = a multiple of the batch; the remainder, fewer than ``S * batch`` samples, waits for the next epoch,
   whose permutation drops different ones). Each sample is therefore read by exactly one stream per epoch,
   and each stream reads its range sequentially (whole shards, except at most one at each end);
2. stream ``rank * W + w`` shuffles its range with a shuffle buffer of ``data.shuffle_buffer`` samples whose
   draws come from ``derive_seed(seed, "shuffle", epoch, stream)``. The emitted order is computed from the keys
   alone before any byte is read, so it is a pure function of (seed, epoch, stream);
3. DataLoader worker ``w`` yields whole batches of its stream and the loader takes them in turn
   (worker 0, 1, ..., W-1, 0, ...).

Exact resume (``murk train --resume``) at step ``s`` of an epoch: each stream skips the samples of the batches
it already gave, in the computed order, without reading shards that held only those; the workers' roles are
rotated so that the loader's first batch comes from the stream whose turn it is. The batches after a resume
equal those of an uninterrupted run (tested), given the same world size, ``data.workers`` and batch size (the
split of the data depends on them, as in every streaming loader).
"""

from __future__ import annotations

import contextlib
import json
import tarfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import torch
from torch.utils.data import DataLoader, Dataset, IterableDataset, get_worker_info

from murk.errors import InputFileError
from murk.io.listing import real_path
from murk.rng import derive_seed
from murk.train.augment import centre_crop
from murk.train.sources import INDEX_NAME, is_shard_source

DEPTH_SCALE = 1000.0
"""Depth members are uint16 millimetres (as ``murk synth`` writes them)."""


def _require_webdataset() -> Any:
    try:
        import webdataset
    except ImportError:
        raise ValueError("data.source: reading tar shards needs webdataset; pip install 'murk[webdataset]'") from None
    return webdataset


@dataclass(frozen=True)
class ShardSet:
    """Shard files and the sample keys of each, in tar order."""

    urls: tuple[str, ...]
    keys: tuple[tuple[str, ...], ...]

    @property
    def counts(self) -> list[int]:
        return [len(k) for k in self.keys]

    @property
    def offsets(self) -> list[int]:
        """Global id of the first sample of each shard (ids number the samples of all shards in order)."""
        return [0, *np.cumsum(self.counts)[:-1].tolist()] if self.keys else []


def _read_index(path: Path) -> dict[str, Any]:
    try:
        index = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputFileError(path, f"cannot read the shard index ({exc})") from None
    if not isinstance(index, dict) or index.get("format") != "webdataset" or "shards" not in index:
        raise InputFileError(path, "not a shard index written by 'murk synth --format webdataset'")
    return index


def _tar_keys(url: str) -> tuple[str, ...]:
    """Sample keys of a tar in order, from its headers (WebDataset's rule: the key ends at the first dot)."""
    from webdataset.tariterators import base_plus_ext

    try:
        with tarfile.open(url) as tf:
            names = tf.getnames()
    except (OSError, tarfile.TarError) as exc:
        raise InputFileError(url, f"cannot read tar shard ({exc})") from None
    keys: list[str] = []
    for n in names:
        key = base_plus_ext(n)[0]
        if key is not None and (not keys or keys[-1] != key):
            keys.append(key)
    return tuple(keys)


def resolve_shards(source: str) -> ShardSet:
    """The shards named by ``data.source`` with their keys (from the index when there is one).

    Raises:
        InputFileError: a missing shard or index, an unreadable tar, an index of an unfinished dataset.
        ValueError: the pattern matches no shard.
    """
    _require_webdataset()
    from braceexpand import braceexpand

    s = source.strip()
    if not s.endswith(".tar"):
        path = Path(s) / INDEX_NAME if Path(s).is_dir() else Path(s)
        index = _read_index(path)
        if not index.get("complete", False):
            raise InputFileError(
                path,
                f"lists {index.get('shards_finished')} of {index.get('shards_planned')} shards: the dataset is "
                "unfinished (rerun the 'murk synth' command to finish it, or name the finished shards by pattern)",
            )
        return ShardSet(
            tuple(str(path.parent / e["url"]) for e in index["shards"]),
            tuple(tuple(e["keys"]) for e in index["shards"]),
        )
    urls = list(braceexpand(s))
    if not urls:
        raise ValueError(f"data.source: {source!r} names no shard")
    for u in urls:
        if not Path(u).is_file():
            raise InputFileError(u, "shard not found")
    known: dict[str, tuple[str, ...]] = {}
    for folder in {real_path(u).parent for u in urls}:
        for cand in (folder / INDEX_NAME, folder.parent / INDEX_NAME):
            if cand.is_file():
                index = _read_index(cand)
                for e in index["shards"]:
                    known[str(real_path(cand.parent / e["url"]))] = tuple(e["keys"])
    keys = tuple(known.get(str(real_path(u))) or _tar_keys(u) for u in urls)
    return ShardSet(tuple(urls), keys)


def stem_of_key(key: str) -> str:
    """``<stem>_v<k>`` -> ``<stem>`` (the split keeps all variants of one clean image on one side)."""
    from murk.synth.shards import stem_of_key as _stem

    return _stem(key)


# ------------------------------------------------------------------------------------------ sample order


def shuffle_buffer_order(items: Sequence[int], buffer: int, rng: np.random.Generator) -> list[int]:
    """The order in which a shuffle buffer of ``buffer`` slots emits ``items`` read in order: once full, each
    new item replaces a uniformly drawn buffered one, which is emitted; the rest leave in a random order."""
    items = list(items)
    if buffer <= 1 or len(items) <= 1:
        return items
    buf = items[:buffer]
    rest = items[buffer:]
    draws = rng.integers(0, len(buf), size=len(rest)).tolist()
    out = []
    for item, j in zip(rest, draws, strict=True):
        out.append(buf[j])
        buf[j] = item
    tail = rng.permutation(len(buf)).tolist()
    out.extend(buf[j] for j in tail)
    return out


@dataclass(frozen=True)
class StreamPlan:
    """The per-epoch split of a shard set's training samples into streams (a pure function of its fields)."""

    shard_set: ShardSet
    train_ids: tuple[tuple[int, ...], ...]
    """Per shard, the global ids of its training samples (in tar order)."""
    seed: int
    streams: int
    batch: int
    buffer: int

    @property
    def per_stream(self) -> int:
        """L: samples per stream per epoch (a multiple of the batch)."""
        total = sum(len(t) for t in self.train_ids)
        return total // self.streams // self.batch * self.batch

    def shard_order(self, epoch: int) -> list[int]:
        """The order of the shards in ``epoch`` (the order in which streams read them)."""
        return np.random.default_rng(derive_seed(self.seed, "shards", epoch)).permutation(len(self.train_ids)).tolist()

    def order(self, epoch: int, stream: int) -> list[int]:
        """Global ids that ``stream`` yields in ``epoch``, in order."""
        perm = self.shard_order(epoch)
        L = self.per_stream
        seq: list[int] = []
        lo, hi = stream * L, (stream + 1) * L
        pos = 0
        for s in perm:
            ids = self.train_ids[s]
            if pos + len(ids) > lo and pos < hi:
                seq.extend(ids[max(0, lo - pos) : hi - pos])
            pos += len(ids)
            if pos >= hi:
                break
        rng = np.random.default_rng(derive_seed(self.seed, "shuffle", epoch, stream))
        return shuffle_buffer_order(seq, self.buffer, rng)


# ------------------------------------------------------------------------------------------ decoding


def _decode_rgb(data: bytes, where: str) -> np.ndarray:
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    if img is None:
        raise InputFileError(where, "cannot decode image")
    return img[:, :, ::-1].astype(np.float32) / np.float32(255.0)


def decode_sample(sample: dict[str, bytes], size_hw: tuple[int, int], index: int, where: str) -> dict[str, Any]:
    """``input``/``target`` (3, H, W) in [0, 1] and ``depth`` (1, H, W) metres (0 = invalid), centre-cropped."""
    missing = [m for m in ("degraded.png", "clean.png", "depth.png") if m not in sample]
    if missing:
        raise InputFileError(where, f"sample {sample.get('__key__')!s} lacks {', '.join(missing)}")
    x = _decode_rgb(sample["degraded.png"], where)
    y = _decode_rgb(sample["clean.png"], where)
    raw = cv2.imdecode(np.frombuffer(sample["depth.png"], np.uint8), cv2.IMREAD_UNCHANGED)
    if raw is None or raw.ndim != 2:
        raise InputFileError(where, f"sample {sample.get('__key__')!s}: depth.png is not a single-channel image")
    d = raw.astype(np.float32) / np.float32(DEPTH_SCALE)
    x, y, d = centre_crop([x, y, d[:, :, None]], size_hw, source=f"{where}:{sample.get('__key__')!s}")

    def chw(a: np.ndarray) -> torch.Tensor:
        return torch.from_numpy(np.ascontiguousarray(a.transpose(2, 0, 1)))

    return {"input": chw(x), "target": chw(y), "depth": chw(d), "index": index}


def _iter_tar(url: str) -> Iterator[dict[str, Any]]:
    """The samples of one tar in order (WebDataset's tar iterator and grouping)."""
    from webdataset.tariterators import group_by_keys, tar_file_expander

    with open(url, "rb") as f:
        yield from group_by_keys(tar_file_expander([{"url": url, "stream": f}]))


# ------------------------------------------------------------------------------------------ datasets


class ShardStream(IterableDataset):
    """One epoch of one rank: DataLoader worker ``w`` yields the samples of stream ``rank * W + (w + start) % W``
    from ``start_batch`` on (see the module docstring)."""

    def __init__(
        self, plan: StreamPlan, epoch: int, rank: int, workers: int, start_batch: int, size_hw: tuple[int, int]
    ) -> None:
        self.plan, self.epoch, self.rank = plan, epoch, rank
        self.workers = max(1, workers)
        self.start_batch, self.size_hw = start_batch, size_hw

    def __iter__(self) -> Iterator[dict[str, Any]]:
        info = get_worker_info()
        w = info.id if info is not None else 0
        logical = (w + self.start_batch) % self.workers
        consumed = max(0, (self.start_batch - logical + self.workers - 1) // self.workers)
        stream = self.rank * self.workers + logical
        order = self.plan.order(self.epoch, stream)[consumed * self.plan.batch :]
        yield from self._read(order)

    def _read(self, order: list[int]) -> Iterator[dict[str, Any]]:
        ss = self.plan.shard_set
        offsets = ss.offsets
        starts = np.asarray(offsets, dtype=np.int64)
        shard_of = np.searchsorted(starts, np.asarray(order, dtype=np.int64), side="right") - 1
        holding = set(shard_of.tolist())
        needed_shards = [s for s in self.plan.shard_order(self.epoch) if s in holding]  # in the stream's read order
        wanted = set(order)
        pending: dict[int, dict[str, Any]] = {}
        readers = iter(needed_shards)
        current: Iterator[tuple[int, dict[str, Any]]] = iter(())

        def next_sample() -> tuple[int, dict[str, Any]] | None:
            nonlocal current
            while True:
                item = next(current, None)
                if item is not None:
                    return item
                s = next(readers, None)
                if s is None:
                    return None
                current = self._shard_samples(s, offsets[s], wanted)

        for gid, s in zip(order, shard_of.tolist(), strict=True):
            while gid not in pending:
                item = next_sample()
                if item is None:
                    raise InputFileError(ss.urls[s], f"sample id {gid} not found: the shard changed after indexing")
                pending[item[0]] = item[1]
            yield decode_sample(pending.pop(gid), self.size_hw, gid, ss.urls[s])

    def _shard_samples(self, s: int, offset: int, wanted: set[int]) -> Iterator[tuple[int, dict[str, Any]]]:
        url = self.plan.shard_set.urls[s]
        keys = self.plan.shard_set.keys[s]
        for pos, sample in enumerate(_iter_tar(url)):
            if pos >= len(keys) or sample["__key__"] != keys[pos]:
                raise InputFileError(
                    url, f"sample {pos} is {sample['__key__']!r}, the index says otherwise: stale index"
                )
            gid = offset + pos
            if gid in wanted:
                yield gid, {k: sample[k] for k in ("__key__", "degraded.png", "clean.png", "depth.png") if k in sample}


class ShardTrainSet:
    """The training side of a shard source: ``len`` is the samples used per epoch over all ranks, and
    :meth:`epoch_loader` gives one rank's DataLoader for an epoch (from a batch offset, for resume)."""

    def __init__(self, plan: StreamPlan, world: int, workers: int, size_hw: tuple[int, int]) -> None:
        self.plan, self.world, self.workers, self.size_hw = plan, world, workers, size_hw

    def __len__(self) -> int:
        return self.plan.per_stream * self.plan.streams

    def epoch_loader(self, epoch: int, start_batch: int, *, rank: int, pin_memory: bool = False) -> DataLoader:
        stream = ShardStream(self.plan, epoch, rank, self.workers, start_batch, self.size_hw)
        return DataLoader(
            stream, batch_size=self.plan.batch, num_workers=self.workers, drop_last=True, pin_memory=pin_memory
        )


class ShardSampleDataset(Dataset):
    """Random access to given samples of a shard set (the validation split): members read by name."""

    def __init__(self, shard_set: ShardSet, ids: Sequence[int], size_hw: tuple[int, int]) -> None:
        self.shard_set, self.ids, self.size_hw = shard_set, list(ids), size_hw
        self._offsets = np.asarray(shard_set.offsets)
        self._open: dict[str, tarfile.TarFile] = {}

    def __len__(self) -> int:
        return len(self.ids)

    def __getitem__(self, i: int) -> dict[str, Any]:
        gid = self.ids[i]
        s = int(np.searchsorted(self._offsets, gid, side="right") - 1)
        url, key = self.shard_set.urls[s], self.shard_set.keys[s][gid - int(self._offsets[s])]
        tf = self._open.get(url)
        if tf is None:
            tf = self._open[url] = tarfile.open(url)
        sample: dict[str, Any] = {"__key__": key}
        for m in ("degraded.png", "clean.png", "depth.png"):
            with contextlib.suppress(KeyError):
                f = tf.extractfile(f"{key}.{m}")
                if f is not None:
                    sample[m] = f.read()
        return decode_sample(sample, self.size_hw, gid, url)

    def __getstate__(self) -> dict[str, Any]:  # open tar files do not travel to DataLoader workers
        return {**self.__dict__, "_open": {}}


def build_shard_data(config: Any, world: int) -> tuple[ShardTrainSet, ShardSampleDataset | None]:
    """The training stream and validation set of ``config.data`` (a shard source) for ``world`` ranks.

    Raises:
        ValueError: too few training samples for world x workers streams of one batch.
    """
    from murk.train.data import split_by_stem

    d = config.data
    ss = resolve_shards(d.source)
    offsets = ss.offsets
    stems = [stem_of_key(k) for keys in ss.keys for k in keys]
    crop = tuple(d.crop_hw)
    if d.val_source:
        if not is_shard_source(d.val_source):
            raise ValueError(f"data.val_source: with shards, expected shards or an index.json, got {d.val_source!r}")
        vs = resolve_shards(d.val_source)
        val: ShardSampleDataset | None = ShardSampleDataset(vs, range(sum(vs.counts)), crop)
        train_idx = list(range(len(stems)))
    else:
        train_idx, val_idx = split_by_stem(stems, d.val_fraction, config.seed)
        val = ShardSampleDataset(ss, val_idx, crop) if val_idx else None
    train_set = set(train_idx)
    train_ids = tuple(
        tuple(g for g in range(off, off + n) if g in train_set) for off, n in zip(offsets, ss.counts, strict=True)
    )
    workers = max(1, d.workers)
    plan = StreamPlan(ss, train_ids, config.seed, world * workers, config.batch, d.shuffle_buffer)
    if plan.per_stream < 1:
        raise ValueError(
            f"data.source: {len(train_idx)} training samples in {len(ss.urls)} shard(s) cannot give "
            f"{world} rank(s) x {workers} worker(s) a batch of {config.batch} each; lower --batch or data.workers"
        )
    return ShardTrainSet(plan, world, d.workers, crop), val
