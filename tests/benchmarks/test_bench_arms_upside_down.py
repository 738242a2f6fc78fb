"""benchmarks/bench_arms.py ``--upside-down``: the held-out frames scored a second time turned upside down (input,
truth and distance alike); a method that looks at no position (``greyworld``) scores the same, ``lite`` does not."""

from __future__ import annotations

import numpy as np

from murk.report.heldout import HeldoutSet

from .bench_arms_run import BENCH_ARMS, load_file, run_bench_arms


def test_upside_down_turns_input_truth_and_distance_over() -> None:
    module = load_file(BENCH_ARMS)
    rng = np.random.default_rng(0)
    data = HeldoutSet(rng.random((2, 4, 5, 3)), rng.random((2, 4, 5, 3)), rng.random((2, 4, 5)), seed=7)
    turned = module.upside_down(data)
    np.testing.assert_array_equal(turned.degraded, data.degraded[:, ::-1])
    np.testing.assert_array_equal(turned.clean, data.clean[:, ::-1])
    np.testing.assert_array_equal(turned.dist_m, data.dist_m[:, ::-1])
    assert turned.seed == 7 and not np.array_equal(turned.degraded, data.degraded)


def test_held_out_scenes_upside_down_change_lite_and_not_greyworld() -> None:
    arms = ("g=greyworld", "l=lite", "--ref", "g")
    proc = run_bench_arms(*arms, "--heldout-scenes", "2", "--upside-down", "--threads", "1")
    assert proc.returncode == 0, proc.stderr
    sections = proc.stdout.split("\nheld-out scenes (2)")
    assert len(sections) == 3 and sections[2].startswith(", upside down:"), proc.stdout
    rows = [
        {line.split(":")[0].strip(): line for line in part.splitlines() if line.startswith("  ")}
        for part in sections[1:]
    ]
    assert rows[0]["g"] == rows[1]["g"]  # greyworld: per-channel means, whatever the orientation
    assert rows[0]["l"] != rows[1]["l"]  # lite reads the frame's layout
