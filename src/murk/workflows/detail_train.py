"""``murk detail train`` as a library call: a base method restores murk's synthetic water, the detail network learns
to improve those restorations (:func:`murk.train.detail.fit_detail`) and is written.

Scenes: the small trainers' (:mod:`murk.workflows.small_train`), shared out evenly between the training configs, each
degraded with its config's ``data.synthesis`` and seeded ``derive_seed(seed, "detail", config index, chunk)``. The
base method (``lite`` by default) restores every degraded scene; its restoration and the clean scene are the sample,
kept in ``OUT/samples.npz`` for a second run with the same settings.

``OUT`` receives ``detail.npz`` (the network; its ``meta`` holds the settings and counts), ``log.jsonl`` (both
losses every ``log_every`` steps) and ``samples.npz``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np

from murk.models.detail.network import save_detail
from murk.train.detail import DetailSamples, DetailTrainSettings, fit_detail
from murk.workflows.small_train import CHUNK, SCENE_HW, LossLog, TrainResult, cached_samples, weights_path


def make_detail_samples(
    scenes: int, *, seed: int, syntheses: Sequence[object], base: str, progress: Callable[[int], None] | None = None
) -> DetailSamples:
    """``scenes`` samples as the module says, ``progress`` told the count after each chunk."""
    from murk.enhance.restorer import create
    from murk.report.heldout import make_heldout
    from murk.rng import derive_seed

    restorer = create(base)
    restored: list[np.ndarray] = []
    clean: list[np.ndarray] = []
    for c, synthesis in enumerate(syntheses):
        share = scenes // len(syntheses) + (c < scenes % len(syntheses))
        for k in range(-(-share // CHUNK)):
            n = min(CHUNK, share - k * CHUNK)
            data = make_heldout(
                n, seed=derive_seed(seed, "detail", c, k), size_hw=SCENE_HW, synthesis=synthesis, balance_pct=0.5
            )
            restored += [np.clip(restorer.restore(data.degraded[i : i + 8]).images, 0.0, 1.0) for i in range(0, n, 8)]
            clean.append(data.clean)
            if progress is not None:
                progress(sum(len(r) for r in restored))
    return DetailSamples(
        np.concatenate(restored).astype(np.float32, copy=False), np.concatenate(clean).astype(np.float32, copy=False)
    )


def train_detail(
    out: Path,
    *,
    configs: Sequence[Path],
    stages: Sequence[str] | None = None,
    base: str = "lite",
    scenes: int = 1000,
    settings: DetailTrainSettings | None = None,
    seed: int = 7,
    progress: Callable[[str], None] | None = None,
) -> TrainResult:
    """Make (or read back) the samples of the water of ``configs`` (their ``data.synthesis``, with ``stages`` instead
    of theirs when given), learn, write ``OUT/detail.npz`` and ``OUT/log.jsonl``; ``progress`` hears each step of it.
    Refuses (ValueError) fewer than 10 scenes, no config, a bad config or stage, a ``detail.npz`` already in ``out``
    and a bad base method; an ``out`` that cannot be made raises OSError."""
    from murk._config import load_yaml, merge
    from murk.train.config import TrainConfig

    if scenes < 10 or not configs:
        raise ValueError(f"scenes: expected at least 10 and at least one config, got {scenes} and {len(configs)}")
    syntheses = [load_yaml(TrainConfig, c).data.synthesis for c in configs]
    if stages is not None:
        syntheses = [merge(s, {"stages": list(stages)}, where="stages") for s in syntheses]
    weights = weights_path(out, "detail.npz", "network")
    settings = settings or DetailTrainSettings()
    say = progress or (lambda _msg: None)
    started = time.perf_counter()
    key = json.dumps({"scenes": scenes, "seed": seed, "base": base, "syntheses": [repr(s) for s in syntheses]})

    def make() -> dict[str, np.ndarray]:
        made = make_detail_samples(
            scenes, seed=seed, syntheses=syntheses, base=base, progress=lambda n: say(f"samples: {n} of {scenes}")
        )
        return {"restored": made.restored, "clean": made.clean}

    arrays = cached_samples(out / "samples.npz", key, make, say)
    samples = DetailSamples(arrays["restored"], arrays["clean"])
    log = LossLog(say)
    net = fit_detail(samples, settings, log)
    log.write(out / "log.jsonl")
    meta = {
        "configs": [str(c) for c in configs],
        "stages": [list(s.stages) for s in syntheses],
        "scenes": scenes,
        "seed": seed,
        "base": base,
        "settings": asdict(settings),
        "val_loss": log.last["val_loss"],
    }
    save_detail(net, weights, meta)
    n = int(samples.restored.shape[0])
    return TrainResult(weights, n, log.last["loss"], log.last["val_loss"], time.perf_counter() - started)
