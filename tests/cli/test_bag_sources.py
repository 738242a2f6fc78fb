"""ROS bags as the image source of ``murk snow extract``, ``murk eval`` and ``murk compare`` (issue 17)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

pytest.importorskip("rosbags", reason="ROS bag support needs the optional 'ros' extra: pip install 'murk[ros]'")

from murk.cli.main import app
from murk.snow.bank import load_bank

from .._rosbags import BagBuilder, frames

runner = CliRunner()


def _specks(n: int) -> list[np.ndarray]:
    """Dark frames with two bright 4x4 specks (one moves with the index)."""
    out = []
    for i in range(n):
        f = np.full((48, 64, 3), 20, np.uint8)
        f[10 + i : 14 + i, 20:24] = 230
        f[30:34, 40:44] = 230
        out.append(f)
    return out


def test_snow_extract_from_a_bag_every_nth_frame(tmp_path: Path) -> None:
    bag = BagBuilder(tmp_path / "dive", "ros2", "mcap").compressed("/cam/c", _specks(5), fmt="png", broken=[2]).close()
    args = ["snow", "extract", str(bag), "--out", str(tmp_path / "b.npz"), "--open-px", "0", "--close-px", "0"]
    r = runner.invoke(app, [*args, "--topic", "/cam/c", "--every", "2"])
    assert r.exit_code == 1, r.output  # frame 2 does not decode: recorded, the bank is written
    b = load_bank(tmp_path / "b.npz")
    assert [s["frame"] for s in b.meta["sources"]] == [0, 4] and len(b) == 4
    assert "frame 1: compressed image data could not be decoded" in " ".join(r.output.split())
    assert sorted(p.name for p in (tmp_path / "b_preview").iterdir()) == ["dive_f000000.jpg", "dive_f000004.jpg"]
    r = runner.invoke(app, args)
    assert r.exit_code == 2 and "choose an image topic with --topic; image topics: /cam/c" in r.output


def test_eval_scores_bag_frames(tmp_path: Path) -> None:
    bag = BagBuilder(tmp_path / "dive.bag", "ros1").image("/cam", frames(4), "bgr8").close()
    r = runner.invoke(app, ["eval", str(bag), "--topic", "/cam", "--every", "2", "--json", str(tmp_path / "m.json")])
    assert r.exit_code == 0, r.output
    rows = json.loads((tmp_path / "m.json").read_text())["images"]
    assert [row["file"] for row in rows] == ["dive_000000.png", "dive_000001.png"]
    assert all(np.isfinite(row["uiqm"]) for row in rows)
    r = runner.invoke(app, ["eval", str(bag), "--topic", "/nope"])
    assert r.exit_code == 2 and "topic '/nope' not found; image topics: /cam" in r.output


def test_compare_runs_on_bag_frames(tmp_path: Path) -> None:
    bag = BagBuilder(tmp_path / "dive.bag", "ros1").compressed("/cam/compressed", frames(3)).close()
    out = tmp_path / "rep"
    r = runner.invoke(
        app,
        ["compare", str(bag), "--topic", "/cam/compressed", "--method", "raw", "--method", "post", "--out", str(out)],
    )
    assert r.exit_code == 0, r.output
    doc = json.loads((out / "metrics.json").read_text())
    assert {(row["method"], row["image"]) for row in doc["rows"]} >= {("post", "dive_000002.png")}
    assert len(doc["rows"]) == 6
