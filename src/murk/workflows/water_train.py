"""``murk water train`` as a library call: make samples of murk's synthetic water with the depth network's
distance maps, learn the water estimator on them (:func:`murk.train.water.fit_water`) and write it.

The samples are procedural construction-site scenes rendered at 320x240 (photographic targets: each clean scene
colour-balanced at 0.5 % / 0.5 %, as the held-out set of ``benchmarks/bench_model.py``), degraded with the training
config's synthesis (``data.synthesis``), seeded ``derive_seed(seed, "water", chunk)`` per chunk of
:data:`CHUNK` scenes (never the held-out seed). The depth method (``jointid_net`` by default: the shipped Joint-ID)
gives each a distance map; image, distance and clean scene are kept at the features' size. They are cached in
``OUT/samples.npz``, so that a second run with the same settings only trains.

Writes into ``OUT``: ``water.npz`` (the estimator, with the settings and counts in its ``meta``), ``log.jsonl``
(training and validation loss every ``log_every`` steps) and ``samples.npz``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import cv2
import numpy as np

from murk.io.atomic import write_text_atomic
from murk.restore_ops.water import FEATURE_HW
from murk.train.water import WaterSamples, WaterTrainSettings, fit_water

CHUNK = 100
"""Scenes rendered, degraded and passed through the depth network at a time."""

SIZE_HW = (240, 320)
"""The rendering size of the scenes (the held-out set's)."""


@dataclass(frozen=True)
class WaterTrainResult:
    """Where the estimator went, how many samples it learned from and its last losses."""

    weights: Path
    samples: int
    loss: float
    val_loss: float
    seconds: float


def _small(a: np.ndarray) -> np.ndarray:
    h, w = FEATURE_HW
    return cv2.resize(np.ascontiguousarray(a, np.float32), (w, h), interpolation=cv2.INTER_AREA)


def make_water_samples(
    scenes: int, *, seed: int, synthesis: object, depth_method: str, progress: Callable[[int], None] | None = None
) -> WaterSamples:
    """``scenes`` samples (a multiple of :data:`CHUNK`, or fewer than one chunk), as the module says."""
    from murk.enhance.restorer import create
    from murk.report.heldout import make_heldout
    from murk.rng import derive_seed

    depth_net = create(depth_method)
    degraded, distance, clean = [], [], []
    for k in range(max(1, -(-scenes // CHUNK))):
        n = min(CHUNK, scenes - k * CHUNK)
        data = make_heldout(
            n, seed=derive_seed(seed, "water", k), size_hw=SIZE_HW, synthesis=synthesis, balance_pct=0.5
        )
        for i in range(0, n, 8):
            out = depth_net.restore(data.degraded[i : i + 8])
            if out.depth_m is None:
                raise ValueError(f"depth_method: {depth_method!r} gives no distance map; use jointid_net")
            for j in range(out.depth_m.shape[0]):
                degraded.append(_small(data.degraded[i + j]))
                distance.append(_small(out.depth_m[j]))
                clean.append(_small(data.clean[i + j]))
        if progress is not None:
            progress(len(degraded))
    return WaterSamples(np.stack(degraded), np.stack(distance), np.stack(clean))


def train_water(
    out: Path,
    *,
    synthesis: object,
    scenes: int = 4000,
    seed: int = 7,
    depth_method: str = "jointid_net",
    settings: WaterTrainSettings | None = None,
    progress: Callable[[str], None] | None = None,
) -> WaterTrainResult:
    """Make (or reuse) the samples, train, write ``OUT/water.npz`` and ``OUT/log.jsonl``.

    Raises:
        ValueError: fewer than 10 scenes, ``out`` already holds a ``water.npz``, a depth method without depth.
        OutputError: ``out`` cannot be written.
    """
    if scenes < 10:
        raise ValueError(f"scenes: expected at least 10, got {scenes}")
    if (out / "water.npz").exists():
        raise ValueError(
            f"out: {out / 'water.npz'} exists (a trained estimator is never overwritten); choose another --out, or "
            "remove that file to train again there (the cached samples.npz is reused when the settings match)"
        )
    settings = settings or WaterTrainSettings()
    say = progress or (lambda _msg: None)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    key = json.dumps({"scenes": scenes, "seed": seed, "depth_method": depth_method, "synthesis": repr(synthesis)})
    cache = out / "samples.npz"
    samples = None
    if cache.is_file():
        with np.load(cache, allow_pickle=False) as z:
            if str(z["key"]) == key:
                samples = WaterSamples(z["degraded"], z["distance_m"], z["clean"])
                say(f"samples: {samples.degraded.shape[0]} read from {cache}")
    if samples is None:
        samples = make_water_samples(
            scenes, seed=seed, synthesis=synthesis, depth_method=depth_method,
            progress=lambda n: say(f"samples: {n} of {scenes}"),
        )  # fmt: skip
        tmp = cache.with_name(".samples.tmp.npz")
        np.savez(tmp, key=np.array(key), degraded=samples.degraded, distance_m=samples.distance_m, clean=samples.clean)
        tmp.replace(cache)
    lines: list[str] = []
    last: dict[str, float] = {}

    def log(row: dict[str, float]) -> None:
        last.update(row)
        lines.append(json.dumps(row))
        say(f"step {int(row['step'])}: loss {row['loss']:.5f}, validation {row['val_loss']:.5f}")

    estimator = fit_water(samples, settings, log)
    write_text_atomic(out / "log.jsonl", "\n".join(lines) + "\n")
    meta = {
        "scenes": scenes,
        "seed": seed,
        "depth_method": depth_method,
        "settings": asdict(settings),
        "val_loss": last.get("val_loss"),
    }
    weights = out / "water.npz"
    type(estimator)(estimator.arrays, meta=meta).save(weights)
    return WaterTrainResult(weights, int(samples.degraded.shape[0]), last["loss"], last["val_loss"],
                            time.perf_counter() - t0)  # fmt: skip
