"""``murk compare`` and ``murk eval`` under faults (issue 13): an unreadable file in the folder is skipped and
recorded (exit 1) while the others are processed; stale error records; an output folder that is the input."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.io import images as images_mod
from murk.io import read_jsonl

from .._faults import one_line_error

runner = CliRunner()


@pytest.fixture
def real(tmp_path: Path, rng: np.random.Generator) -> Path:
    d = tmp_path / "real"
    d.mkdir()
    for stem in ("a", "b", "c"):
        assert cv2.imwrite(str(d / f"{stem}.png"), (rng.random((48, 64, 3)) * 200 + 20).astype(np.uint8))
    return d


@pytest.fixture
def unreadable(real: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """real/b.png cannot be read (permission denied; simulated: the tests may run as root, which reads anyway)."""
    bad = real / "b.png"
    fromfile = np.fromfile

    def guarded(file: object, *args: object, **kwargs: object) -> np.ndarray:
        if Path(str(file)) == bad:
            raise PermissionError(13, "Permission denied", str(file))
        return fromfile(file, *args, **kwargs)

    monkeypatch.setattr(images_mod.np, "fromfile", guarded)
    return bad


def test_compare_skips_and_records_an_unreadable_file(real: Path, unreadable: Path, tmp_path: Path) -> None:
    out = tmp_path / "rep"
    res = runner.invoke(app, ["compare", str(real), "--method", "raw", "--out", str(out)])
    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output
    (record,) = read_jsonl(out / "errors.jsonl")
    assert record == {
        "input": str(unreadable),
        "stage": "read",
        "error": f"{unreadable}: cannot read this input file (permission denied)",
    }
    assert sorted(p.name for p in (out / "grids").iterdir()) == ["a.jpg", "c.jpg"]  # the others are processed
    assert [r["image"] for r in json.loads((out / "metrics.json").read_text())["rows"]] == ["a.png", "c.png"]


def test_compare_where_no_image_can_be_read_lists_them_all_and_prints_no_nan(tmp_path: Path) -> None:
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "t.jpg").write_bytes(b"\xff\xd8\xff\xe0 truncated")
    (bad / "x.jpg").write_text("not an image")
    out = tmp_path / "rep"
    res = runner.invoke(app, ["compare", str(bad), "--method", "raw", "--method", "post", "--out", str(out)])
    assert res.exit_code == 1, res.output
    assert sorted(Path(r["input"]).name for r in read_jsonl(out / "errors.jsonl")) == ["t.jpg", "x.jpg"]
    assert "nan" not in res.output.lower()
    page = (out / "report.html").read_text()
    assert ">nan<" not in page and 'class="best"' not in page  # no best method when nothing was scored


def test_compare_prints_the_flag_counts_of_each_method(real: Path, tmp_path: Path) -> None:
    res = runner.invoke(app, ["compare", str(real), "--method", "raw", "--out", str(tmp_path / "rep")])
    assert res.exit_code == 0, res.output
    counts = json.loads((tmp_path / "rep" / "metrics.json").read_text())["summary"]["raw"]["flags"]
    assert f"flagged {counts['flagged']}/{counts['n']}" in res.output and counts["n"] == 3


def test_compare_errors_jsonl_lists_the_latest_run_only(real: Path, tmp_path: Path) -> None:
    out = tmp_path / "rep"
    (real / "bad.png").write_bytes(b"not a png")
    assert runner.invoke(app, ["compare", str(real), "--method", "raw", "--out", str(out)]).exit_code == 1
    assert len(read_jsonl(out / "errors.jsonl")) == 1
    (real / "bad.png").unlink()
    res = runner.invoke(app, ["compare", str(real), "--method", "raw", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert not (out / "errors.jsonl").exists()


def test_compare_refuses_the_input_folder_as_output(real: Path) -> None:
    line = one_line_error(runner.invoke(app, ["compare", str(real), "--method", "raw", "--out", str(real)]))
    assert f"--out {real}: this is the input folder {real}" in line
    assert sorted(p.name for p in real.iterdir()) == ["a.png", "b.png", "c.png"]


def test_eval_skips_and_records_an_unreadable_file(real: Path, unreadable: Path, tmp_path: Path) -> None:
    out = tmp_path / "ev" / "scores.json"
    res = runner.invoke(app, ["eval", str(real), "--json", str(out)])
    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output
    (record,) = read_jsonl(out.parent / "errors.jsonl")
    assert record == {
        "input": str(unreadable),
        "stage": "score",
        "error": "cannot read this input file (permission denied)",
    }
    assert [r["file"] for r in json.loads(out.read_text())["images"]] == ["a.png", "c.png"]


def test_eval_errors_jsonl_lists_the_latest_run_only(real: Path, tmp_path: Path) -> None:
    out = tmp_path / "ev" / "scores.json"
    (real / "bad.png").write_bytes(b"not a png")
    assert runner.invoke(app, ["eval", str(real), "--json", str(out)]).exit_code == 1
    assert len(read_jsonl(out.parent / "errors.jsonl")) == 1
    (real / "bad.png").unlink()
    res = runner.invoke(app, ["eval", str(real), "--json", str(out)])
    assert res.exit_code == 0, res.output
    assert not (out.parent / "errors.jsonl").exists()
