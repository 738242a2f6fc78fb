"""A fixed held-out set of degraded procedural scenes with references, and the scores of restorers on it.

Scene ``i`` is ``sample_scene(derive_seed(seed, "heldout", i))``, rendered at ``size_hw``, and degraded with
``synthesis`` (parameters from ``derive_seed(seed, "online", 0, i)``, as in online training). Training uses
``derive_seed(train_seed, i)`` for its scenes, so a held-out seed never reproduces a training scene.

Scores per method: PSNR and SSIM of the enhanced image against the clean render (and of the degraded input,
the ``input`` row), the PSNR after the best per-channel gain and offset onto the clean render
(:mod:`murk.metrics.affine_psnr`: what a restorer removes beyond a global colour correction, against the same
oracle correction of the input), and depth errors (AbsRel in m/m, AbsRel after median scaling, RMSE, SILog,
delta < 1.25) against the exact distance on pixels that hit a surface (open-water background at the scene's far
limit has no meaningful depth and is skipped). The reference is always the clean scene itself.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from murk.restore_ops.balance import color_balance
from murk.rng import derive_seed


@dataclass(frozen=True)
class HeldoutSet:
    """Degraded inputs, clean references and exact distances: (N, H, W, 3) float32 and (N, H, W) metres
    (NaN where a ray hit nothing: no depth reference there)."""

    degraded: np.ndarray
    clean: np.ndarray
    dist_m: np.ndarray
    seed: int


def make_heldout(
    n: int,
    *,
    seed: int,
    size_hw: tuple[int, int],
    synthesis: Any,
    balance_pct: float | None = None,
    specks_per_mpx: float = 0.0,
) -> HeldoutSet:
    """Render and degrade ``n`` held-out scenes (deterministic in ``seed``). ``balance_pct``: each clean scene
    first goes through the simplest colour balance (:mod:`murk.restore_ops.balance`), as the training scenes of
    ``data.scene_balance_pct`` do (the "photographic" held-out set: targets that span the range in every channel,
    as photographs and the references of real pairs do); None: the procedural scenes as rendered.
    ``specks_per_mpx`` not 0: small sharp details (:mod:`murk.scenes.specks`, seeded ``derive_seed(seed, "specks",
    i)``) are painted on each clean scene before the balance and the water; 0 (the default) adds none and draws
    nothing."""
    from murk.scenes import render_scene, sample_scene
    from murk.scenes.specks import apply_specks, sample_specks
    from murk.train.augment import centre_crop
    from murk.train.data import OnlineDegrader
    from murk.train.scenes_source import render_size

    if n < 1:
        raise ValueError(f"n: expected at least one scene, got {n}")
    h, w = size_hw
    cleans, dists, fars = [], [], []
    for i in range(n):
        scene = sample_scene(derive_seed(seed, "heldout", i))
        rgb, dist = centre_crop(list(render_scene(scene, render_size((h, w)))), (h, w), source=f"scene {i}")
        if specks_per_mpx != 0:  # a negative or NaN count is refused by sample_specks
            rgb = apply_specks(rgb, sample_specks(derive_seed(seed, "specks", i), (h, w), specks_per_mpx))
        if balance_pct is not None:
            rgb = color_balance(rgb, balance_pct, balance_pct)
        cleans.append(rgb)
        dists.append(dist)
        fars.append(scene.far_m)
    clean = np.stack(cleans).astype(np.float32)
    dist = np.stack(dists).astype(np.float32)
    degrader = OnlineDegrader(synthesis, seed=seed)
    to_t = torch.from_numpy
    degraded = degrader(to_t(clean).permute(0, 3, 1, 2), to_t(dist)[:, None], 0, list(range(n)))
    degraded_np = degraded.clamp(0.0, 1.0).permute(0, 2, 3, 1).numpy().astype(np.float32)
    far = np.asarray(fars, np.float32)[:, None, None]
    dist_ref = np.where(dist < far - 1e-3, dist, np.nan).astype(np.float32)
    return HeldoutSet(degraded_np, clean, dist_ref, seed)


def score_heldout(
    data: HeldoutSet,
    restorers: Mapping[str, Any],
    *,
    batch: int = 8,
    on_method: Callable[[str], None] | None = None,
    per_scene: dict[str, dict[str, list[float]]] | None = None,
) -> dict[str, dict[str, float]]:
    """Mean PSNR/SSIM (and depth errors where the method estimates depth) per method, plus ``input``.

    ``restorers`` maps a label to a restorer (``restore(numpy batch) -> Restored``) or None (the input).
    ``per_scene``: a dict that receives, per label, each scene's ``psnr`` and ``affine_psnr`` (for paired
    comparisons between methods).
    """
    from murk.metrics import affine_fit_psnr, depth_errors, psnr, ssim

    base = [psnr(a, b, data_range=1.0) for a, b in zip(data.degraded, data.clean, strict=True)]
    base_fit = [affine_fit_psnr(a, b, data_range=1.0) for a, b in zip(data.degraded, data.clean, strict=True)]
    out: dict[str, dict[str, float]] = {"input": _image_scores(data.degraded, data.clean, psnr, ssim)}
    for label, rest in restorers.items():
        if on_method:
            on_method(label)
        if rest is None:
            continue
        images, depths = [], []
        for i in range(0, len(data.degraded), batch):
            r = rest.restore(data.degraded[i : i + batch])
            images.append(np.clip(r.images, 0.0, 1.0))
            depths.append(r.depth_m)
        enhanced = np.concatenate(images)
        row = _image_scores(enhanced, data.clean, psnr, ssim, base=base, base_fit=base_fit)
        if per_scene is not None:
            per_scene[label] = {
                "psnr": [psnr(a, b, data_range=1.0) for a, b in zip(enhanced, data.clean, strict=True)],
                "affine_psnr": [
                    affine_fit_psnr(a, b, data_range=1.0) for a, b in zip(enhanced, data.clean, strict=True)
                ],
            }
        if all(d is not None for d in depths):
            pred = np.concatenate(depths)
            errs = [
                depth_errors(p, np.nan_to_num(g, nan=0.0))
                for p, g in zip(pred, data.dist_m, strict=True)
                if np.isfinite(g).any()
            ]
            for name in ("abs_rel", "abs_rel_median", "rmse", "silog", "d1"):
                row[name] = float(np.mean([getattr(e, name) for e in errs]))
        out[label] = row
    return out


def _image_scores(
    images: np.ndarray,
    refs: np.ndarray,
    psnr: Any,
    ssim: Any,
    *,
    base: Sequence[float] | None = None,
    base_fit: Sequence[float] | None = None,
) -> dict[str, float]:
    """Means and standard deviations over the images (PSNR, SSIM and the affine-fit PSNR); with ``base`` and
    ``base_fit`` (the input's PSNR and affine-fit PSNR per image) also the paired gains of both: mean, standard
    deviation and the half-width of the 95 % confidence interval (normal approximation, ``1.96 * std / sqrt(n)``,
    with the sample standard deviation)."""
    from murk.metrics import affine_fit_psnr

    ps = [psnr(a, b, data_range=1.0) for a, b in zip(images, refs, strict=True)]
    ss = [ssim(a, b, data_range=1.0) for a, b in zip(images, refs, strict=True)]
    fs = [affine_fit_psnr(a, b, data_range=1.0) for a, b in zip(images, refs, strict=True)]
    row = {
        "psnr": float(np.mean(ps)),
        "psnr_std": float(np.std(ps)),
        "ssim": float(np.mean(ss)),
        "ssim_std": float(np.std(ss)),
        "affine_psnr": float(np.mean(fs)),
        "affine_psnr_std": float(np.std(fs)),
        "n": float(len(ps)),
    }
    for key, mine, theirs in (("psnr_gain", ps, base), ("affine_psnr_gain", fs, base_fit)):
        if theirs is None:
            continue
        gain = np.asarray(mine, np.float64) - np.asarray(theirs, np.float64)
        spread = float(np.std(gain, ddof=1)) if gain.size > 1 else 0.0
        row.update({key: float(gain.mean()), f"{key}_std": spread, f"{key}_ci95": 1.96 * spread / np.sqrt(gain.size)})
    return row


def heldout_table(scores: Mapping[str, Mapping[str, float]], order: Sequence[str] | None = None) -> str:
    """A Markdown table of :func:`score_heldout` results."""
    lines = [
        "| method | PSNR dB | SSIM | PSNR after affine fit dB | its gain over the input dB (95 % CI) "
        "| depth AbsRel m/m | AbsRel median-scaled | depth RMSE m | delta<1.25 |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label in order or list(scores):
        r = scores[label]

        def f(k: str, fmt: str = "{:.3f}", r: Mapping[str, float] = r) -> str:
            return fmt.format(r[k]) if k in r else "-"

        fit_gain = (
            f"{r['affine_psnr_gain']:+.2f} ({r['affine_psnr_gain'] - r['affine_psnr_gain_ci95']:+.2f} to "
            f"{r['affine_psnr_gain'] + r['affine_psnr_gain_ci95']:+.2f})"
            if "affine_psnr_gain" in r
            else "-"
        )
        lines.append(
            f"| {label} | {r['psnr']:.2f} +- {r['psnr_std']:.2f} | {r['ssim']:.3f} +- {r['ssim_std']:.3f} | "
            f"{f('affine_psnr', '{:.2f}')} | {fit_gain} | "
            f"{f('abs_rel')} | {f('abs_rel_median')} | {f('rmse', '{:.2f}')} | {f('d1')} |"
        )
    return "\n".join(lines)
