"""``murk detail train`` as a library call: a base method restores murk's synthetic water, the detail network learns
to improve those restorations (:func:`murk.train.detail.fit_detail`) and is written.

Scenes: the small trainers' (:mod:`murk.workflows.small_train`), shared out evenly between the training configs, each
degraded with its config's ``data.synthesis``. With ``eq1_share`` that share of each config's scenes is degraded by
Eq. (1) alone (its stages less ``forward_scatter`` and ``marine_snow``), so that the network also sees water with no
blur or snow to take away and learns to leave it alone (docs/train.md: without such scenes it costs 0.4-0.6 dB there).
Each part (a config's water, then its Eq. (1)-only water) is seeded ``derive_seed(seed, "detail", part index,
chunk)``. The base method (``lite`` by default) restores every degraded scene; its restoration and the clean scene
are the sample, kept in ``OUT/samples.npz`` for a second run with the same settings. An ``eq1_share`` outside [0, 1] is
refused (ValueError).

With ``photos`` (a folder of clean in-air photographs, CC BY / CC0 or whatever their licence allows to ship) every
photograph is also a sample in every part's water: centre-cropped and resized to the scenes' size, balanced as they
are, given the layout prior's distance (:mod:`murk.io.distance_prior`), degraded with each part's synthesis (seeded
``derive_seed(seed, "detail-photos", part index)``) and restored by the base. Real content teaches the network that
the fine texture of a photograph is not snow (docs/train.md: +0.15 dB after the fit on held-out photographs).

``OUT`` receives ``detail.npz`` (the network; its ``meta`` holds the settings and counts), ``log.jsonl`` (both
losses every ``log_every`` steps) and ``samples.npz``.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from murk.models.detail.network import save_detail
from murk.train.detail import DetailSamples, DetailTrainSettings, fit_detail
from murk.workflows.small_train import (
    CHUNK,
    SCENE_HW,
    LossLog,
    TrainResult,
    base_fingerprint,
    cached_samples,
    weights_path,
)

EQ1_DROPS = ("forward_scatter", "marine_snow")
"""The stages an Eq. (1)-only part leaves out."""


def sample_parts(syntheses: Sequence[Any], scenes: int, eq1_share: float) -> list[tuple[Any, int]]:
    """``(synthesis, scene count)`` of every part, in seeding order: each config's ``scenes / len(syntheses)``, of
    which ``eq1_share`` (rounded half up) in its Eq. (1)-only water, that part second. Parts of no scene are left out
    before the parts are numbered for their seeds: with ``eq1_share`` 0 the configs are numbered 0, 1, ... as
    without the option; with a share strictly between 0 and 1 (and enough scenes), config ``c``'s parts are ``2c``
    and ``2c + 1``.

    Raises:
        ValueError: ``eq1_share`` outside [0, 1]; a config whose stages keep no stage once ``forward_scatter`` and
            ``marine_snow`` are taken out, when it has Eq. (1)-only scenes.
    """
    from murk._config import merge

    if not 0.0 <= eq1_share <= 1.0:
        raise ValueError(f"eq1_share: expected a share in [0, 1], got {eq1_share!r}")
    parts: list[tuple[Any, int]] = []
    for c, synthesis in enumerate(syntheses):
        share = scenes // len(syntheses) + (c < scenes % len(syntheses))
        eq1 = math.floor(share * eq1_share + 0.5)
        parts.append((synthesis, share - eq1))
        if eq1:
            kept = [s for s in synthesis.stages if s not in EQ1_DROPS]
            if not kept:
                raise ValueError(
                    f"eq1_share: the stages {', '.join(synthesis.stages)} keep none once forward_scatter and "
                    "marine_snow are taken out; give basic, or leave eq1_share at 0"
                )
            parts.append((merge(synthesis, {"stages": kept}, where="stages"), eq1))
    return [(synthesis, n) for synthesis, n in parts if n > 0]


def make_detail_samples(
    parts: Sequence[tuple[Any, int]],
    *,
    seed: int,
    restorer: Any,
    specks_per_mpx: float = 0.0,
    progress: Callable[[int], None] | None = None,
) -> DetailSamples:
    """The samples of ``parts`` (:func:`sample_parts`) as the module says, restored by ``restorer`` (the base
    method's), with ``specks_per_mpx`` specks on each clean scene (:func:`murk.report.heldout.make_heldout`),
    ``progress`` told the count after each chunk."""
    from murk.report.heldout import make_heldout
    from murk.rng import derive_seed

    restored: list[np.ndarray] = []
    clean: list[np.ndarray] = []
    for c, (synthesis, share) in enumerate(parts):
        for k in range(-(-share // CHUNK)):
            n = min(CHUNK, share - k * CHUNK)
            data = make_heldout(
                n,
                seed=derive_seed(seed, "detail", c, k),
                size_hw=SCENE_HW,
                synthesis=synthesis,
                balance_pct=0.5,
                specks_per_mpx=specks_per_mpx,
            )
            restored += [np.clip(restorer.restore(data.degraded[i : i + 8]).images, 0.0, 1.0) for i in range(0, n, 8)]
            clean.append(data.clean)
            if progress is not None:
                progress(sum(len(r) for r in restored))
    return DetailSamples(
        np.concatenate(restored).astype(np.float32, copy=False), np.concatenate(clean).astype(np.float32, copy=False)
    )


def load_photos(folder: Path, *, seed: int) -> tuple[np.ndarray, np.ndarray, list[Path]]:
    """``(clean (N, H, W, 3), distance_m (N, H, W), files)`` of the photographs in ``folder`` at the scenes'
    size, balanced at 0.5 % / 0.5 % as the scenes are, with the layout prior's distance (seeded per photograph).

    Raises:
        ValueError: no photograph in ``folder``, or one that cannot be read (named, with its problem).
        InputFileError: ``folder`` does not exist, or two of its files share a stem (as ``murk train --photos``).
    """
    from murk.io.pairs import DepthOptions, load_pair
    from murk.restore_ops.balance import color_balance
    from murk.rng import derive_seed
    from murk.synth.common import fit_size
    from murk.train.data import rgbd_sources

    sources = rgbd_sources(folder, "layout")
    if not sources:
        raise ValueError(f"photos: no photograph in {folder}")
    cleans, dists, names = [], [], []
    for k, src in enumerate(sources):
        try:
            rgb, dist, valid = load_pair(
                src, DepthOptions(depth_from="layout", layout_seed=derive_seed(seed, "photo", k))
            )
        except (OSError, ValueError) as exc:
            raise ValueError(f"photos: {src.rgb_path}: {exc}") from None
        rgb, dist, _ = fit_size(rgb, dist, valid, (SCENE_HW[1], SCENE_HW[0]))
        cleans.append(color_balance(rgb, 0.5, 0.5))
        dists.append(dist)
        names.append(Path(src.rgb_path))
    return np.stack(cleans).astype(np.float32), np.stack(dists).astype(np.float32), names


def make_photo_samples(
    clean: np.ndarray, distance_m: np.ndarray, waters: Sequence[Any], *, seed: int, restorer: Any
) -> tuple[np.ndarray, np.ndarray]:
    """``(restored, clean)``: each photograph (:func:`load_photos`) degraded by each of ``waters`` (syntheses) and
    restored by ``restorer``, ``len(waters) x N`` of them, water by water."""
    import torch

    from murk.rng import derive_seed
    from murk.train.data import OnlineDegrader

    rgb, dist = torch.from_numpy(clean).permute(0, 3, 1, 2), torch.from_numpy(distance_m)[:, None]
    restored = []
    for w, synthesis in enumerate(waters):
        degraded = OnlineDegrader(synthesis, seed=derive_seed(seed, "detail-photos", w))(
            rgb, dist, 0, list(range(len(clean)))
        )
        degraded_np = degraded.clamp(0.0, 1.0).permute(0, 2, 3, 1).numpy().astype(np.float32)
        restored += [
            np.clip(restorer.restore(degraded_np[i : i + 8]).images, 0.0, 1.0) for i in range(0, len(clean), 8)
        ]
    return np.concatenate(restored).astype(np.float32), np.concatenate([clean] * len(waters))


def train_detail(
    out: Path,
    *,
    configs: Sequence[Path],
    stages: Sequence[str] | None = None,
    eq1_share: float = 0.0,
    photos: Path | None = None,
    specks_per_mpx: float = 0.0,
    base: str = "lite",
    scenes: int = 1000,
    settings: DetailTrainSettings | None = None,
    seed: int = 7,
    progress: Callable[[str], None] | None = None,
) -> TrainResult:
    """Make (or read back) the samples of the water of ``configs`` (their ``data.synthesis``, with ``stages`` instead
    of theirs when given; ``eq1_share`` of them by Eq. (1) alone; with ``photos``, the photographs in every part's
    water too; with ``specks_per_mpx``, small sharp details on every procedural scene, :mod:`murk.scenes.specks`),
    learn, write ``OUT/detail.npz`` and ``OUT/log.jsonl``; ``progress`` hears each step of it. Refuses (ValueError)
    fewer than 10 scenes, a negative ``specks_per_mpx``, no config, a bad config or stage, an ``eq1_share`` outside
    [0, 1], a ``detail.npz`` already in ``out``, a bad base method and a photograph that cannot be read; an ``out``
    that cannot be made raises OSError."""
    from murk._config import load_yaml, merge
    from murk.enhance.restorer import create
    from murk.train.config import TrainConfig

    if scenes < 10 or not configs:
        raise ValueError(f"scenes: expected at least 10 and at least one config, got {scenes} and {len(configs)}")
    if not math.isfinite(specks_per_mpx) or specks_per_mpx < 0:
        raise ValueError(f"specks: expected a count >= 0 per megapixel, got {specks_per_mpx!r}")
    syntheses = [load_yaml(TrainConfig, c).data.synthesis for c in configs]
    if stages is not None:
        syntheses = [merge(s, {"stages": list(stages)}, where="stages") for s in syntheses]
    parts = sample_parts(syntheses, scenes, eq1_share)
    weights = weights_path(out, "detail.npz", "network")
    settings = settings or DetailTrainSettings()
    say = progress or (lambda _msg: None)
    started = time.perf_counter()
    restorer = create(base)
    made_by = {"base": base, **base_fingerprint(restorer)}
    photo_set = None if photos is None else load_photos(photos, seed=seed)
    photo_files = [[f.name, f.stat().st_size] for f in ([] if photo_set is None else photo_set[2])]
    key = json.dumps(
        {"seed": seed, **made_by, "parts": [[repr(s), n] for s, n in parts], "photos": photo_files}
        | ({"specks_per_mpx": float(specks_per_mpx)} if specks_per_mpx else {})
    )

    def make() -> dict[str, np.ndarray]:
        made = make_detail_samples(
            parts,
            seed=seed,
            restorer=restorer,
            specks_per_mpx=specks_per_mpx,
            progress=lambda n: say(f"samples: {n} of {scenes}"),
        )
        if photo_set is None:
            return {"restored": made.restored, "clean": made.clean}
        shot, shot_clean = make_photo_samples(
            photo_set[0], photo_set[1], [w for w, _ in parts], seed=seed, restorer=restorer
        )
        say(f"samples: {len(shot)} from {len(photo_files)} photographs")
        return {
            "restored": np.concatenate([made.restored, shot]),
            "clean": np.concatenate([made.clean, shot_clean]),
        }

    arrays = cached_samples(out / "samples.npz", key, make, say)
    samples = DetailSamples(arrays["restored"], arrays["clean"])
    log = LossLog(say)
    net = fit_detail(samples, settings, log)
    log.write(out / "log.jsonl")
    meta = {
        "configs": [str(c) for c in configs],
        "stages": [list(s.stages) for s in syntheses],
        "eq1_share": eq1_share,
        "parts": [{"stages": list(s.stages), "scenes": n} for s, n in parts],
        "scenes": scenes,
        "photos": None if photos is None else {"folder": str(photos), "files": photo_files},
        "specks_per_mpx": float(specks_per_mpx),
        "seed": seed,
        **made_by,
        "settings": asdict(settings),
        "val_loss": log.last["val_loss"],
    }
    save_detail(net, weights, meta)
    n = int(samples.restored.shape[0])
    return TrainResult(weights, n, log.last["loss"], log.last["val_loss"], time.perf_counter() - started)
