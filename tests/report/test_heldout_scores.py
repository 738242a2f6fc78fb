"""murk.report.heldout.score_heldout: the paired PSNR gain over the input, with its spread and 95 % interval."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from murk.metrics import psnr
from murk.report.heldout import HeldoutSet, score_heldout


class _Towards:
    """A stand-in restorer: moves each input a fixed fraction of the way to its reference."""

    def __init__(self, clean: np.ndarray, share: float) -> None:
        self.clean, self.share, self.seen = clean, share, 0

    def restore(self, batch: np.ndarray) -> SimpleNamespace:
        ref = self.clean[self.seen : self.seen + len(batch)]
        self.seen += len(batch)
        return SimpleNamespace(images=batch + self.share * (ref - batch), depth_m=None)


def test_the_paired_gain_is_the_mean_per_scene_difference_with_its_interval() -> None:
    rng = np.random.default_rng(11)
    clean = rng.random((12, 16, 20, 3)).astype(np.float32)
    noise = rng.normal(0.0, 1.0, clean.shape).astype(np.float32) * rng.uniform(0.02, 0.2, (12, 1, 1, 1))
    degraded = np.clip(clean + noise.astype(np.float32), 0.0, 1.0)
    data = HeldoutSet(degraded, clean, np.full(clean.shape[:3], np.nan, np.float32), seed=0)
    scores = score_heldout(data, {"half": _Towards(clean, 0.5)}, batch=5)
    before = np.array([psnr(a, b, data_range=1.0) for a, b in zip(degraded, clean, strict=True)])
    restored = degraded + 0.5 * (clean - degraded)
    after = np.array([psnr(a, b, data_range=1.0) for a, b in zip(restored, clean, strict=True)])
    gain = after - before
    row = scores["half"]
    assert abs(row["psnr_gain"] - gain.mean()) < 1e-9
    assert abs(row["psnr_gain"] - (row["psnr"] - scores["input"]["psnr"])) < 1e-9
    assert abs(row["psnr_gain_std"] - gain.std(ddof=1)) < 1e-9
    assert abs(row["psnr_gain_ci95"] - 1.96 * gain.std(ddof=1) / np.sqrt(12)) < 1e-9
    # halving the error everywhere gains 20 log10(2) = 6.02 dB wherever nothing was clipped
    assert 5.0 < row["psnr_gain"] < 6.1 and row["psnr_gain_ci95"] > 0
    assert "psnr_gain" not in scores["input"]


class _Global:
    """A stand-in restorer that only applies one gain and offset per channel (what the affine fit forgives)."""

    def restore(self, batch: np.ndarray) -> SimpleNamespace:
        return SimpleNamespace(images=batch * np.float32(0.8) + np.float32(0.05), depth_m=None)


def test_the_affine_fit_gain_credits_local_restoration_only() -> None:
    rng = np.random.default_rng(12)
    clean = (0.2 + 0.6 * rng.random((6, 16, 20, 3))).astype(np.float32)
    haze = np.linspace(0.1, 0.7, 20, dtype=np.float32)[None, None, :, None]  # grows across the frame
    degraded = (clean * (1 - haze) + 0.4 * haze).astype(np.float32)
    data = HeldoutSet(degraded, clean, np.full(clean.shape[:3], np.nan, np.float32), seed=0)
    scores = score_heldout(data, {"global": _Global(), "half": _Towards(clean, 0.5)}, batch=4)
    assert abs(scores["global"]["affine_psnr_gain"]) < 1e-4  # a global map changes nothing once fitted
    assert abs(scores["global"]["psnr_gain"]) > 0.1  # while the plain PSNR moves
    assert scores["half"]["affine_psnr_gain"] > 3.0  # halving the local error is credited
    assert scores["input"]["affine_psnr"] > scores["input"]["psnr"]
    assert "affine_psnr_gain" not in scores["input"]


def test_per_scene_scores_feed_paired_contrasts_between_methods() -> None:
    from murk.report.study import HELDOUT_CONTRAST_KEYS, contrasts_markdown, paired_contrasts

    rng = np.random.default_rng(5)
    clean = rng.random((10, 12, 16, 3)).astype(np.float32)
    degraded = np.clip(clean + rng.normal(0.0, 0.1, clean.shape).astype(np.float32), 0.0, 1.0)
    data = HeldoutSet(degraded, clean, np.full(clean.shape[:3], np.nan, np.float32), seed=0)
    per_scene: dict[str, dict[str, list[float]]] = {}
    scores = score_heldout(data, {"a": _Towards(clean, 0.5), "b": _Towards(clean, 0.25)}, batch=4, per_scene=per_scene)
    assert set(per_scene) == {"a", "b"} and len(per_scene["a"]["affine_psnr"]) == 10
    assert abs(np.mean(per_scene["a"]["psnr"]) - scores["a"]["psnr"]) < 1e-9
    assert abs(np.mean(per_scene["a"]["affine_psnr"]) - scores["a"]["affine_psnr"]) < 1e-9
    rows = [
        {"set": "heldout", "image": i, "method": m, **{k: v[i] for k, v in per_scene[m].items()}}
        for m in per_scene
        for i in range(10)
    ]
    (c,) = paired_contrasts(rows, [("a", "b")], HELDOUT_CONTRAST_KEYS)
    diff = np.array(per_scene["a"]["affine_psnr"]) - np.array(per_scene["b"]["affine_psnr"])
    assert abs(c["affine_psnr"]["mean"] - diff.mean()) < 1e-9 and c["affine_psnr"]["higher"] == 10
    text = "\n".join(contrasts_markdown([c], HELDOUT_CONTRAST_KEYS, "### held-out contrasts"))
    assert "### held-out contrasts" in text and "| a - b | 10 |" in text and "PSNR after affine fit" in text
