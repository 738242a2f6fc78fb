"""``murk water train`` as a library call: make samples of murk's synthetic water with the depth network's
distance maps, learn the water estimator on them (:func:`murk.train.water.fit_water`) and write it.

The samples are the small trainers' scenes (:mod:`murk.workflows.small_train`), degraded with the training
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
from dataclasses import asdict
from pathlib import Path

import cv2
import numpy as np

from murk.restore_ops.water import FEATURE_HW
from murk.train.water import WaterSamples, WaterTrainSettings, fit_water
from murk.workflows.small_train import CHUNK, SCENE_HW, LossLog, TrainResult, cached_samples, weights_path


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
            n, seed=derive_seed(seed, "water", k), size_hw=SCENE_HW, synthesis=synthesis, balance_pct=0.5
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
) -> TrainResult:
    """Make (or reuse) the samples, train, write ``OUT/water.npz`` and ``OUT/log.jsonl``.

    Raises:
        ValueError: fewer than 10 scenes, ``out`` already holds a ``water.npz``, a depth method without depth.
        OutputError: ``out`` cannot be written.
    """
    if scenes < 10:
        raise ValueError(f"scenes: expected at least 10, got {scenes}")
    weights = weights_path(out, "water.npz", "estimator")
    settings = settings or WaterTrainSettings()
    say = progress or (lambda _msg: None)
    t0 = time.perf_counter()
    from murk.enhance.restorer import create
    from murk.workflows.small_train import base_fingerprint

    made_by = base_fingerprint(create(depth_method))  # the distance maps' network, by content
    key = json.dumps(
        {"scenes": scenes, "seed": seed, "depth_method": depth_method, **made_by, "synthesis": repr(synthesis)}
    )
    arrays = cached_samples(
        out / "samples.npz", key,
        lambda: dict(vars(make_water_samples(
            scenes, seed=seed, synthesis=synthesis, depth_method=depth_method,
            progress=lambda n: say(f"samples: {n} of {scenes}"),
        ))),
        say,
    )  # fmt: skip
    samples = WaterSamples(arrays["degraded"], arrays["distance_m"], arrays["clean"])
    log = LossLog(say)
    estimator = fit_water(samples, settings, log)
    log.write(out / "log.jsonl")
    last = log.last
    meta = {
        "scenes": scenes,
        "seed": seed,
        "depth_method": depth_method,
        **made_by,
        "settings": asdict(settings),
        "val_loss": last.get("val_loss"),
    }
    type(estimator)(estimator.arrays, meta=meta).save(weights)
    return TrainResult(weights, int(samples.degraded.shape[0]), last["loss"], last["val_loss"],
                       time.perf_counter() - t0)  # fmt: skip
