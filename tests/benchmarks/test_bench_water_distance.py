"""benchmarks/bench_water_distance.py: the true distances are the scene's and the one Eq. (1) degraded it with, the
oracle finds the water of a pure Eq. (1) image (also through a global colour change, and with one part held), the
estimate is scored in the right metres, the shipped row is the ``water`` method itself, the synthesis's water
restores a scene degraded by Eq. (1) alone, and the tables are printed end to end."""

from __future__ import annotations

import os
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from murk._config import load_yaml, merge
from murk.enhance.restorer import create
from murk.metrics import affine_fit_psnr
from murk.physics.medium import apply_medium
from murk.report.heldout import make_heldout
from murk.restore_ops.water import invert_eq1, visibility_m
from murk.rng import derive_seed
from murk.scenes import sample_scene
from murk.train.config import TrainConfig
from tests.benchmarks.bench_arms_run import ROOT, load_file

BENCH = ROOT / "benchmarks" / "bench_water_distance.py"


def _synthesis(config: str, stages: list[str]) -> object:
    return merge(load_yaml(TrainConfig, ROOT / "configs" / config).data.synthesis, {"stages": stages})


def test_the_true_distances_rebuild_the_degraded_input() -> None:
    bench = load_file(BENCH)
    for config in ("train-lite-mild-scratch-cpu.yaml", "train-small-cpu.yaml"):
        synthesis = _synthesis(config, ["basic"])
        data = make_heldout(3, seed=5, size_hw=(48, 64), synthesis=synthesis, balance_pct=0.5)
        assert np.isnan(data.dist_m).any()  # open water in view: its distance comes from the far plane
        truths = bench.true_waters(data, synthesis)
        for i, (clean, degraded, dist_m, truth) in enumerate(
            zip(data.clean, data.degraded, data.dist_m, truths, strict=True)
        ):
            far_plane_m = sample_scene(derive_seed(5, "heldout", i)).far_m
            hit = np.isfinite(dist_m)
            np.testing.assert_array_equal(truth.scene_dist_m[hit], dist_m[hit])
            assert np.all(truth.scene_dist_m[~hit] == np.float32(far_plane_m))
            m = truth.medium
            assert m.distance_mode == "normalized" and truth.eq1_dist_m.max() == pytest.approx(m.far_m, rel=1e-5)
            lit = clean if m.illuminant_rgb is None else clean * np.asarray(m.illuminant_rgb, np.float32)
            image, _ = apply_medium(lit, truth.eq1_dist_m, np.asarray(m.beta_per_m), np.asarray(m.b_inf))
            np.testing.assert_allclose(np.clip(image, 0.0, 1.0), degraded, atol=1e-5)


def _eq1_scene() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, object]:
    bench = load_file(BENCH)
    rng = np.random.default_rng(3)
    clean = rng.uniform(0.1, 0.9, (40, 50, 3)).astype(np.float32)
    dist_m = np.tile(np.linspace(0.5, 6.0, 50, dtype=np.float32), (40, 1))
    att = bench.ATTENUATION_GRID_PER_M[[8, 14, 20]]  # t stays above the floor (0.1) out to 6 m
    veil = bench.VEIL_GRID[[5, 10, 15]]
    image, _ = apply_medium(clean, dist_m, att, veil)
    return clean, dist_m, att, veil, np.clip(image, 0.0, 1.0).astype(np.float32), bench


def test_the_oracle_finds_the_water_of_a_pure_eq1_image() -> None:
    clean, dist_m, att, veil, image, bench = _eq1_scene()
    # the target in another global colour: the oracle scores after the best gain and offset, so it finds the same
    found_veil, found_att = bench.oracle_water(image, dist_m, 0.7 * clean + 0.1)
    np.testing.assert_allclose(found_att, att, rtol=1e-6)
    np.testing.assert_allclose(found_veil, veil, atol=1e-6)
    assert np.abs(invert_eq1(image, dist_m, found_veil, found_att, bench.T_MIN) - clean).max() < 1e-3


def test_the_oracle_with_one_part_held_is_the_best_of_the_other() -> None:
    clean, dist_m, att, veil, image, bench = _eq1_scene()
    wrong_att = att * 2.0
    veil_given_att, held_att = bench.oracle_water(image, dist_m, clean, attenuation_per_m=wrong_att)
    np.testing.assert_array_equal(held_att, wrong_att)
    for c in range(3):  # brute force over the veil grid: the after-fit error of each choice, per channel
        errors = []
        for b in bench.VEIL_GRID:
            trial_veil = veil_given_att.copy()
            trial_veil[c] = b
            out = invert_eq1(image, dist_m, trial_veil, wrong_att, bench.T_MIN)[..., c].ravel().astype(np.float64)
            design = np.stack([out, np.ones_like(out)], axis=1)
            target = clean[..., c].ravel().astype(np.float64)
            errors.append(np.sum((design @ np.linalg.lstsq(design, target, rcond=None)[0] - target) ** 2))
        assert bench.VEIL_GRID[int(np.argmin(errors))] == pytest.approx(veil_given_att[c])
    held_veil, att_given_veil = bench.oracle_water(image, dist_m, clean, veil=veil)
    np.testing.assert_array_equal(held_veil, veil)
    np.testing.assert_allclose(att_given_veil, att, rtol=1e-6)


def test_median_scaled_takes_the_true_median() -> None:
    bench = load_file(BENCH)
    pred = np.array([[1.0, 2.0, 4.0]], np.float32)
    true = np.array([[3.0, 6.0, np.nan]], np.float32)
    np.testing.assert_allclose(bench.median_scaled(pred, true), pred * 3.0)


def test_the_estimate_is_scored_in_the_metres_it_was_given() -> None:
    bench = load_file(BENCH)
    beta = (0.6, 0.1, 0.2)
    seen_m = visibility_m(np.array(beta))
    medium = SimpleNamespace(b_inf=(0.1, 0.4, 0.5), beta_per_m=beta, distance_mode="metric", near_m=0.3, far_m=15.0)
    truth = SimpleNamespace(medium=medium, scene_peak_m=4.0)
    exact = SimpleNamespace(veil=(0.1, 0.4, 0.5), visibility_m=seen_m)
    perfect = {"veil_abs_error": 0.0, "veil_ciede2000": 0.0, "visibility_ratio": 1.0}
    assert bench.estimate_error(exact, truth, eq1_metres=False) == perfect
    off = SimpleNamespace(veil=(0.1, 0.4, 0.8), visibility_m=seen_m * 2.0)
    errors = bench.estimate_error(off, truth, eq1_metres=True)
    assert errors["veil_abs_error"] == pytest.approx(0.1)
    assert errors["veil_ciede2000"] > 1.0
    assert errors["visibility_ratio"] == pytest.approx(2.0)
    # normalized: the scene (farthest 4 m) was rescaled to 0.3-15.3 m, so a visibility of V there is (V - 0.3) * 4 / 15
    # of the scene's metres
    rescaled = SimpleNamespace(medium=SimpleNamespace(**{**vars(medium), "distance_mode": "normalized", "far_m": 15.3}))
    rescaled.scene_peak_m = 4.0
    assert bench.estimate_error(exact, rescaled, eq1_metres=True)["visibility_ratio"] == pytest.approx(1.0)
    in_scene = bench.estimate_error(exact, rescaled, eq1_metres=False)["visibility_ratio"]
    assert in_scene == pytest.approx(seen_m / ((seen_m - 0.3) * 4.0 / 15.0))


def test_the_shipped_row_is_the_water_method_and_the_synthesis_water_restores_eq1() -> None:
    bench = load_file(BENCH)
    synthesis = _synthesis("train-small-cpu.yaml", ["basic"])
    data = make_heldout(2, seed=7, size_hw=(60, 80), synthesis=synthesis, balance_pct=0.5)
    gains = bench.score(data, synthesis, [0.25, 1.0], oracle=False)
    method = create("water").restore(data.degraded)
    for i, (out, clean, image) in enumerate(zip(method.images, data.clean, data.degraded, strict=True)):
        expected = affine_fit_psnr(np.clip(out, 0, 1), clean, data_range=1.0) - affine_fit_psnr(
            image, clean, data_range=1.0
        )
        assert gains[f"{bench.SHIPPED}, strength 0.25"][i] == pytest.approx(expected, abs=1e-6)
    # Eq. (1) alone: the synthesis's own water and distance undo it (but for the floored transmission), far beyond
    # what the estimate does; swapping the veil and the attenuation would not
    exact = np.asarray(gains["Eq. (1)'s distance, synthesis water, strength 1"])
    assert np.all(exact > 5.0)
    assert np.all(exact > np.asarray(gains[f"{bench.SHIPPED}, strength 1"]) + 3.0)
    assert not any(label.startswith("jointid distance, oracle") for label in gains)  # oracle=False


def test_the_tables_are_printed() -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), OMP_NUM_THREADS="1")
    cmd = [sys.executable, str(BENCH), "--heldout-scenes", "2", "--strengths", "0.5", "--threads", "1"]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    gains, estimates = proc.stdout.split("The estimate against the synthesis's water")
    rows = [line.split(" | ") for line in gains.splitlines() if line.startswith("| ")][1:]
    labels = [r[0].lstrip("| ") for r in rows]
    assert labels[0] == "jointid (the base)"
    assert "true distance, oracle water, strength 0.5" in labels
    assert "Eq. (1)'s distance, synthesis water, strength 0.5" in labels
    assert "jointid distance, estimated veil and oracle attenuation water, strength 0.5" in labels
    # the base, three distances with two waters each, the two half-oracles, the synthesis's water
    assert len(labels) == 1 + 3 * 2 + 2 + 1
    shipped = labels.index(f"{load_file(BENCH).SHIPPED}, strength 0.5")
    assert rows[shipped][2].strip(" |") == ""  # no difference to itself
    assert all(r[2].strip(" |") for k, r in enumerate(rows) if k not in (0, shipped))
    below = [line.split(" | ")[0].lstrip("| ") for line in estimates.splitlines() if line.startswith("| ")][1:]
    assert below == ["jointid", "true", "Eq. (1)'s"]
