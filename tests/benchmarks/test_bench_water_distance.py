"""benchmarks/bench_water_distance.py: the true distance is the one Eq. (1) degraded the scene with, the oracle finds
the water of a pure Eq. (1) image, and the table is printed end to end."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from murk._config import load_yaml, merge
from murk.physics.medium import apply_medium
from murk.report.heldout import make_heldout
from murk.restore_ops.water import invert_eq1
from murk.rng import derive_seed
from murk.scenes import sample_scene
from murk.train.config import TrainConfig
from tests.benchmarks.bench_arms_run import ROOT, load_file

BENCH = ROOT / "benchmarks" / "bench_water_distance.py"


def test_the_true_distance_and_water_rebuild_the_degraded_input() -> None:
    bench = load_file(BENCH)
    for config in ("train-lite-mild-scratch-cpu.yaml", "train-small-cpu.yaml"):
        synthesis = merge(load_yaml(TrainConfig, ROOT / "configs" / config).data.synthesis, {"stages": ["basic"]})
        data = make_heldout(3, seed=5, size_hw=(48, 64), synthesis=synthesis, balance_pct=0.5)
        assert np.isnan(data.dist_m).any()  # open water in view: its distance comes from the far plane
        dists, media, peaks = bench.true_distances(data, synthesis)
        for i, (peak, d) in enumerate(zip(peaks, data.dist_m, strict=True)):  # the farthest depth, open water's too
            far_plane = sample_scene(derive_seed(5, "heldout", i)).far_m
            assert peak == pytest.approx(far_plane if np.isnan(d).any() else float(np.nanmax(d)), rel=1e-6)
        for clean, degraded, d, m in zip(data.clean, data.degraded, dists, media, strict=True):
            lit = clean if m.illuminant_rgb is None else clean * np.asarray(m.illuminant_rgb, np.float32)
            image, _ = apply_medium(lit, d, np.asarray(m.beta_per_m), np.asarray(m.b_inf))
            np.testing.assert_allclose(np.clip(image, 0.0, 1.0), degraded, atol=1e-5)


def test_the_oracle_finds_the_water_of_a_pure_eq1_image() -> None:
    bench = load_file(BENCH)
    rng = np.random.default_rng(3)
    clean = rng.uniform(0.1, 0.9, (40, 50, 3)).astype(np.float32)
    dist = np.tile(np.linspace(0.5, 6.0, 50, dtype=np.float32), (40, 1))
    att = bench.ATTENUATION_GRID_PER_M[[8, 14, 20]]  # t stays above the floor (0.1) out to 6 m
    veil = bench.VEIL_GRID[[5, 10, 15]]
    image, _ = apply_medium(clean, dist, att, veil)
    image = np.clip(image, 0.0, 1.0).astype(np.float32)
    found_veil, found_att = bench.oracle_water(image, dist, clean)
    np.testing.assert_allclose(found_att, att, rtol=1e-6)
    np.testing.assert_allclose(found_veil, veil, atol=1e-6)
    restored = invert_eq1(image, dist, found_veil, found_att, bench.T_MIN)
    assert np.abs(restored - clean).max() < 1e-3
    # one part held: it is kept, and the other is the best given it
    held_veil, att_given_veil = bench.oracle_water(image, dist, clean, veil=veil)
    np.testing.assert_array_equal(held_veil, veil)
    np.testing.assert_allclose(att_given_veil, att, rtol=1e-6)
    wrong_att = att * 2.0
    veil_given_att, held_att = bench.oracle_water(image, dist, clean, attenuation_per_m=wrong_att)
    np.testing.assert_array_equal(held_att, wrong_att)
    assert not np.allclose(veil_given_att, veil)  # a wrong attenuation is made up for by another veil


def test_median_scaled_takes_the_true_median() -> None:
    bench = load_file(BENCH)
    pred = np.array([[1.0, 2.0, 4.0]], np.float32)
    true = np.array([[3.0, 6.0, np.nan]], np.float32)
    np.testing.assert_allclose(bench.median_scaled(pred, true), pred * 3.0)


def test_the_estimate_is_scored_against_the_synthesis_water() -> None:
    from types import SimpleNamespace

    from murk.restore_ops.water import visibility_m

    bench = load_file(BENCH)
    medium = SimpleNamespace(
        b_inf=(0.1, 0.4, 0.5), beta_per_m=(0.6, 0.1, 0.2), distance_mode="metric", near_m=0.3, far_m=15.0
    )
    seen = visibility_m(np.array([0.6, 0.1, 0.2]))
    exact = SimpleNamespace(veil=(0.1, 0.4, 0.5), visibility_m=seen)
    perfect = {"veil_abs_error": 0.0, "veil_ciede2000": 0.0, "visibility_ratio": 1.0, "visibility_ratio_scene": 1.0}
    assert bench.estimate_error(exact, medium, 4.0) == perfect
    off = SimpleNamespace(veil=(0.1, 0.4, 0.8), visibility_m=seen * 2.0)
    errors = bench.estimate_error(off, medium, 4.0)
    assert abs(errors["veil_abs_error"] - 0.1) < 1e-12
    assert errors["veil_ciede2000"] > 1.0
    assert abs(errors["visibility_ratio"] - 2.0) < 1e-12
    # normalized: the scene (farthest 4 m) was stretched to 0.3-15.3 m, so the scene's metres are 15 / 4 times fewer
    stretched = SimpleNamespace(**{**vars(medium), "distance_mode": "normalized", "far_m": 15.3})
    errors = bench.estimate_error(exact, stretched, 4.0)
    assert abs(errors["visibility_ratio"] - 1.0) < 1e-12
    assert abs(errors["visibility_ratio_scene"] - seen / ((seen - 0.3) * 4.0 / 15.0)) < 1e-9


def test_the_table_is_printed() -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"), OMP_NUM_THREADS="1")
    cmd = [sys.executable, str(BENCH), "--heldout-scenes", "2", "--strengths", "0.5", "--threads", "1"]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    gains, estimates = proc.stdout.split("The estimate against the synthesis's water")
    rows = [line.split(" | ")[0].lstrip("| ") for line in gains.splitlines() if line.startswith("| ")][1:]
    assert rows[0] == "jointid (the base)"
    assert "true distance, synthesis water, strength 0.5" in rows
    assert "median-scaled distance, oracle water, strength 0.5" in rows
    assert "jointid distance, estimated veil and oracle attenuation water, strength 0.5" in rows
    # the base, three distances with two waters each, the synthesis water, the two half-oracles
    assert len(rows) == 1 + 3 * 2 + 1 + 2
    below = [line.split(" | ")[0].lstrip("| ") for line in estimates.splitlines() if line.startswith("| ")][1:]
    assert below == ["jointid", "true"]
