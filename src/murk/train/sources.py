"""What a training run reads, told apart without importing torch: :func:`detect_kind` names the kind of a data
source, :func:`check_sources` checks a configuration's sources before the trainer (and torch) is loaded, so that
``murk train --data MISSING`` answers at once."""

from __future__ import annotations

from pathlib import Path

from murk.train.config import TrainConfig

INDEX_NAME = "index.json"
"""The index of a tar-shard dataset (``murk synth --format webdataset``)."""


def is_shard_source(source: str) -> bool:
    """True for a brace pattern or path of ``.tar`` shards, an ``index.json``, or a folder holding one."""
    s = source.strip()
    if s.endswith((".tar", ".json")):
        return True
    return Path(s).is_dir() and (Path(s) / INDEX_NAME).is_file() and not (Path(s) / "manifest.jsonl").exists()


def detect_kind(source: str, depth_from: str = "file") -> str:
    """``synth`` (folder with manifest.jsonl), ``list`` (a file), ``rgbd`` (rgb/ + depth/, or with
    ``depth_from="layout"`` any other folder: photographs without depth), ``scenes`` or ``shards`` (tar shards: a
    ``.tar`` pattern or an ``index.json``)."""
    p = Path(source)
    if source == "scenes" or source.startswith("scenes:"):
        return "scenes"
    if is_shard_source(source):
        return "shards"
    if p.is_file():
        return "list"
    if (p / "manifest.jsonl").is_file():
        return "synth"
    if p.is_dir() and ((p / "depth").is_dir() or depth_from == "layout"):
        return "rgbd"
    raise ValueError(
        f"data.source: {source or '(empty)'} is neither a 'murk synth' folder, a Joint-ID list file, a folder with "
        "rgb/ and depth/, 'scenes', nor tar shards (a .tar pattern or an index.json)"
    )


def check_sources(config: TrainConfig) -> None:
    """Raise what :func:`murk.train.setup.build_data` raises first about ``config``'s data sources: a training
    source (``data.kind: auto``) or, for a ``murk synth`` folder or a list, a validation source of no known kind
    (e.g. a path that does not exist). Cheap: it only looks at the file system.

    Raises:
        ValueError: the message names ``data.source`` and what was expected.
    """
    d = config.data
    kind = d.kind if d.kind != "auto" else detect_kind(d.source, d.depth_from)
    if kind in ("synth", "list") and d.val_source:
        detect_kind(d.val_source)
    if d.photos is not None:
        if kind != "scenes":
            raise ValueError(
                f"data.photos: needs data.source: scenes (the photographs are mixed into the procedural scenes), "
                f"got {d.source} ({kind})"
            )
        if not Path(d.photos).is_dir():
            raise ValueError(f"data.photos: {d.photos} is not a folder")
