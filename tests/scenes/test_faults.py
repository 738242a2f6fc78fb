"""``murk scenes`` under faults (issue 13): error records of an earlier run do not survive a clean rerun; a
full disk stops the run with one line."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

import murk.rng
import murk.scenes
from murk.cli.main import app
from murk.io import read_jsonl

from .._faults import assert_nothing_partial, fill_disk, one_line_error

runner = CliRunner()


def _run(out: Path):
    return runner.invoke(app, ["scenes", str(out), "--count", "2", "--size", "32x24", "-q"])


def test_errors_jsonl_lists_the_latest_run_only(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    real = murk.scenes.render_scene

    def flaky(params, size, **kw):
        if params == murk.scenes.sample_scene(murk.rng.derive_seed(0, 1)):
            raise ValueError("renderer failed")
        return real(params, size, **kw)

    monkeypatch.setattr(murk.scenes, "render_scene", flaky)
    out = tmp_path / "sc"
    assert _run(out).exit_code == 1
    assert [(r["index"], r["stage"], r["input"]) for r in read_jsonl(out / "errors.jsonl")] == [
        (1, "render", "rgb/scene_000001.png")
    ]
    monkeypatch.undo()
    res = _run(out)
    assert res.exit_code == 0, res.output
    assert "1 scene processed, 1 skipped (already done) in" in res.output and "failed" not in res.output
    assert not (out / "errors.jsonl").exists()


def test_full_disk_stops_with_one_line(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    out = tmp_path / "sc"
    fill_disk(monkeypatch, only=".png")
    line = one_line_error(_run(out))
    assert line == f"error: {out / 'rgb' / 'scene_000000.png'}: no space left on device"
    assert not (out / "errors.jsonl").exists()
    assert_nothing_partial(out)
