"""The one summary printout and progress display of every batch command (murk.cli._jobs)."""

from __future__ import annotations

import io

from rich.console import Console

from murk.cli._jobs import JobProgress, print_summary
from murk.io.jobs import ErrorRecord, JobSummary


def _console() -> tuple[Console, io.StringIO]:
    buf = io.StringIO()
    return Console(file=buf, width=300, highlight=False), buf


def test_print_summary_prints_line_notes_failures_and_returns_the_exit_code(tmp_path):
    console, buf = _console()
    s = JobSummary("compare", processed=2, notes=["weights: x.pt"])
    s.add_failure(ErrorRecord("a.png", "read", "a.png: not an image"))
    s.add_failure(ErrorRecord("v.mp4", "restore", "nan", frame=3))
    s.errors_path = tmp_path / "errors.jsonl"
    code = print_summary(s, "image", console=console)
    text = buf.getvalue()
    assert code == 1 and text.startswith("compare: 2 images processed, 2 failed (see ")
    assert "note: weights: x.pt" in text and "failed (read): a.png: not an image" in text
    assert "failed (restore frame 3): v.mp4: nan" in text
    assert print_summary(JobSummary("x", processed=1), "item", console=console) == 0


def test_progress_without_a_terminal_prints_nothing_at_once():
    console, buf = _console()  # not a terminal: plain status lines at most every 10 s
    with JobProgress(console, "synth", total=4, unit="variants") as progress:
        progress.update(1)
        progress.advance(2)
    assert buf.getvalue() == ""
