"""What murk's small trainers share (``murk water train``, ``murk detail train``): the scenes they learn from, their
samples kept between runs, the log of their losses and what they report.

Their samples are procedural construction-site scenes rendered at :data:`SCENE_HW` with photographic targets (each
clean scene colour-balanced at 0.5 % / 0.5 %, as the held-out set of ``murk study`` and the benchmarks), made
:data:`CHUNK` at a time, never with the held-out seed.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from murk.io.atomic import write_text_atomic

SCENE_HW = (240, 320)
"""The rendering size of the scenes (the held-out set's)."""

CHUNK = 100
"""Scenes rendered, degraded and passed through a network at a time."""


@dataclass(frozen=True)
class TrainResult:
    """Where the weights went, how many samples they learned from, the last losses and the run's seconds."""

    weights: Path
    samples: int
    loss: float
    val_loss: float
    seconds: float

    def summary(self) -> str:
        """The line the command prints at the end."""
        return (
            f"wrote {self.weights} ({self.samples} samples, loss {self.loss:.6f}, validation {self.val_loss:.6f}, "
            f"{self.seconds:.0f} s)"
        )


def base_fingerprint(restorer: Any) -> dict[str, Any]:
    """What a base restorer's outputs depend on beyond its spec, for a samples key: murk's version (it changes only
    when the version is raised) and ``base_weights``, ``[file name, the first 16 hex digits of its SHA-256]`` of each
    weights file it loaded (:func:`murk.enhance.restorer.weights_used`, and the same inside a method that builds on a
    ``base`` restorer: ``water``'s Joint-ID and its blended ``lite``), so that samples made with other weights are made
    again, not read back. Named by content and file name, not by folder: the same weights elsewhere give the same
    key. ``exposure``: whether each network stage keeps its input's exposure (a default that changed on 2026-12-06
    without a change of weights or version, :mod:`murk.restore_ops.exposure`), in the order visited; ``depth_area``:
    the area of each Joint-ID stage's depth pass (another default of 2026-12-06, ``jointid?depth_area``)."""
    import hashlib

    from murk import __version__
    from murk.enhance.restorer import Restorer, weights_used

    files: list[Path] = []
    exposure: list[bool] = []
    depth_area: list[int] = []

    def walk(r: Any) -> None:
        used = weights_used(r)
        for stage in (used.first, *(s for s, _ in used.blended), *used.later):
            if stage is not None and stage.weights and Path(stage.weights) not in files:
                files.append(Path(stage.weights))
            if stage is not None and hasattr(stage, "keep_exposure"):
                exposure.append(bool(stage.keep_exposure))
            if stage is not None and hasattr(stage, "depth_area"):
                depth_area.append(int(stage.depth_area))
            if isinstance(getattr(stage, "base", None), Restorer):
                walk(stage.base)  # type: ignore[union-attr]

    walk(restorer)
    return {
        "murk": __version__,
        "base_weights": [[f.name, hashlib.sha256(f.read_bytes()).hexdigest()[:16]] for f in files if f.is_file()],
        "exposure": exposure,
        "depth_area": depth_area,
    }


def weights_path(out: Path, name: str, what: str) -> Path:
    """``out / name``, the run's weights file, with ``out`` made.

    Raises:
        ValueError: that file exists (a trained ``what`` is never overwritten).
        OSError: ``out`` cannot be made.
    """
    weights = out / name
    if weights.exists():
        raise ValueError(
            f"out: {weights} exists (a trained {what} is never overwritten); choose another --out, or remove that "
            "file to train again there (the cached samples.npz is reused when the settings match)"
        )
    out.mkdir(parents=True, exist_ok=True)
    return weights


class LossLog:
    """Receives the trainer's ``{"step", "loss", "val_loss"}`` rows: says each, keeps them for ``log.jsonl``."""

    def __init__(self, say: Callable[[str], None]) -> None:
        self.say = say
        self.rows: list[str] = []
        self.last: dict[str, float] = {}

    def __call__(self, row: dict[str, float]) -> None:
        self.last.update(row)
        self.rows.append(json.dumps(row))
        self.say(f"step {int(row['step'])}: loss {row['loss']:.6f}, validation {row['val_loss']:.6f}")

    def write(self, path: Path) -> None:
        write_text_atomic(path, "\n".join(self.rows) + "\n")


def cached_samples(
    cache: Path, key: str, make: Callable[[], dict[str, np.ndarray]], say: Callable[[str], None]
) -> dict[str, np.ndarray]:
    """The arrays stored in ``cache`` when its ``key`` (a text naming every setting that made them) is ``key``;
    otherwise ``make()``'s, written there (atomically) with ``key`` for the next run."""
    if cache.is_file():
        with np.load(cache, allow_pickle=False) as z:
            if "key" in z.files and str(z["key"]) == key:
                arrays = {k: z[k] for k in z.files if k != "key"}
                say(f"samples: {len(next(iter(arrays.values()), []))} read from {cache}")
                return arrays
    arrays = make()
    tmp = cache.with_name(f".{cache.stem}.tmp.npz")
    stored: dict[str, Any] = {"key": np.array(key), **arrays}
    np.savez(tmp, **stored)
    tmp.replace(cache)
    return arrays
