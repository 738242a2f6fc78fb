"""The job contract: one errors.jsonl schema and one summary for every batch command."""

from __future__ import annotations

import json

import pytest

from murk.io.jobs import ErrorLog, ErrorRecord, JobSummary, read_errors, summary_line, write_errors


def test_record_json_has_required_fields_and_only_the_optional_ones_set():
    rec = ErrorRecord(input="a.png", stage="read", error="a.png: not an image")
    assert rec.to_json() == {"input": "a.png", "stage": "read", "error": "a.png: not an image"}
    rec2 = ErrorRecord(input="v.mp4", stage="decode", error="bad", frame=7)
    assert rec2.to_json() == {"input": "v.mp4", "stage": "decode", "error": "bad", "frame": 7}
    assert ErrorRecord.from_json(rec2.to_json()) == rec2


def test_unknown_or_missing_fields_are_rejected():
    with pytest.raises(ValueError, match="unknown field"):
        ErrorRecord.from_json({"input": "a", "stage": "s", "error": "e", "file": "a"})
    with pytest.raises(ValueError, match="lacks"):
        ErrorRecord.from_json({"input": "a", "error": "e"})


def test_error_log_appends_and_start_clears_an_earlier_run(tmp_path):
    (tmp_path / "errors.jsonl").write_text('{"input":"old","stage":"read","error":"x"}\n')
    log = ErrorLog(tmp_path).start()
    assert not (tmp_path / "errors.jsonl").exists() and log.written is None
    log.add(ErrorRecord("a.png", "read", "boom"))
    log.add(ErrorRecord("b.mp4", "decode", "bad frame", frame=3))
    lines = (tmp_path / "errors.jsonl").read_text().splitlines()
    assert [json.loads(s)["input"] for s in lines] == ["a.png", "b.mp4"]
    assert log.count == 2 and log.written == tmp_path / "errors.jsonl"
    assert read_errors(tmp_path / "errors.jsonl")[1].frame == 3


def test_write_errors_replaces_or_removes(tmp_path):
    path = write_errors(tmp_path, [ErrorRecord("a", "score", "nan", index=2)])
    assert path is not None and read_errors(path) == [ErrorRecord("a", "score", "nan", index=2)]
    assert write_errors(tmp_path, []) is None and not path.exists()


def test_summary_exit_code_and_line():
    s = JobSummary("enhance", processed=3, skipped=1)
    assert s.exit_code == 0
    s.failed = 2
    s.errors_path = None
    assert s.exit_code == 1
    s.note("x")
    s.note("x")
    assert s.notes == ["x"]
    line = summary_line(s, "image")
    assert line.startswith("enhance: 3 images processed, 1 skipped") and "2 failed" in line
    assert s.to_json()["failed"] == 2


def test_summary_collects_failures_and_writes_them_once(tmp_path):
    s = JobSummary("synth")
    s.add_failure(ErrorRecord("a.png", "read", "broken"))
    s.add_failure(ErrorRecord("b.png", "render", "nan", variant=2))
    assert s.failed == 2 and s.write_errors(tmp_path) == tmp_path / "errors.jsonl"
    assert read_errors(tmp_path / "errors.jsonl")[1].variant == 2 and s.errors_path == tmp_path / "errors.jsonl"
    s.failures.clear()
    assert s.write_errors(tmp_path) is None and s.failed == 0 and not (tmp_path / "errors.jsonl").exists()


def test_error_log_counts_into_a_summary(tmp_path):
    s = JobSummary("enhance")
    log = ErrorLog(tmp_path, summary=s).start()
    log.add(ErrorRecord("v.mp4", "read", "bad frame", frame=4))
    assert s.failed == 1 and s.failures[0].frame == 4 and s.errors_path == tmp_path / "errors.jsonl"


def test_summary_line_singular_and_detail():
    s = JobSummary("scenes", processed=1, wall_s=2.0)
    assert summary_line(s, "scenes", "5.0 scenes/s") == "scenes: 1 scene processed in 2.0 s; 5.0 scenes/s"
