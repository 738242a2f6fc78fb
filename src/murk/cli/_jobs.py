"""The one progress display and the one summary printout of every batch command (the job contract of
:mod:`murk.io.jobs`, on the console).

Library jobs report progress through a callback (``on_progress(done, total)`` or a report object); the command
hands them :meth:`JobProgress.update` and, at the end, prints the job's :class:`~murk.io.jobs.JobSummary`
with :func:`print_summary` (even under ``--quiet``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.markup import escape

if TYPE_CHECKING:  # (murk.io pulls in numpy and OpenCV: not needed for --help or a usage error)
    from murk.io.jobs import JobSummary

STATUS_EVERY_S = 10.0
"""Headless logs (no terminal) get a plain status line at most this often."""
MAX_LISTED_FAILURES = 10


class JobProgress:
    """A progress bar (finite work on a terminal), a live status line (a live stream or unknown total on a
    terminal), or a plain status line every :data:`STATUS_EVERY_S` seconds (headless logs); nothing under
    ``--quiet``. Use as a context manager; call :meth:`update` with the work done so far.

    Args:
        console: the command's console (``make_console(quiet)``).
        title: what is being done (shown before the bar).
        total: the amount of work, when known.
        unit: what is counted (``"images"``, ``"variants"``, ...).
        live: a live source (no bar; a status line).
        status: builds the status text from the object given to :meth:`update` (default: ``done/total unit``).
        rate: builds the rate shown beside the bar from that object (e.g. ``"12.5 f/s"``).
    """

    def __init__(
        self,
        console: Console,
        title: str,
        *,
        total: int | None = None,
        unit: str = "items",
        live: bool = False,
        status: Callable[[Any], str] | None = None,
        rate: Callable[[Any], str] | None = None,
    ) -> None:
        self.console, self.title, self.total, self.unit, self.live = console, title, total, unit, live
        self.status, self.rate = status, rate
        self.interactive = console.is_terminal and not console.quiet
        self._last = time.monotonic()
        self._progress: Any = None
        self._live: Any = None
        self._task: Any = None
        self._count = 0

    def __enter__(self) -> JobProgress:
        if self.interactive and not self.live:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

            self._progress = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn(escape(self.unit)),
                TextColumn("{task.fields[rate]}"),
                TimeRemainingColumn(),
                console=self.console,
                transient=True,
            )
            self._progress.start()
            self._task = self._progress.add_task(escape(self.title), total=self.total, rate="")
        elif self.interactive:
            from rich.live import Live

            self._live = Live("", console=self.console, refresh_per_second=4, transient=True)
            self._live.start()
        return self

    def update(self, done: int | Any, total: int | None = None, *, rate: str = "") -> None:
        """Show progress: ``done`` items (or a report object given to ``status``) of ``total``."""
        if total is not None:
            self.total = total
        count = done if isinstance(done, int) else _done_of(done)
        if self.rate is not None and not isinstance(done, int):
            rate = self.rate(done)
        if self._progress is not None:
            self._progress.update(self._task, completed=count, total=self.total, rate=rate)
            return
        now = time.monotonic()
        if self._live is not None:
            if now - self._last >= 0.25:
                self._live.update(self._line(done, count))
                self._last = now
        elif not self.console.quiet and now - self._last >= STATUS_EVERY_S:
            self.console.print(self._line(done, count), soft_wrap=True, highlight=False)
            self._last = now

    def advance(self, n: int = 1) -> None:
        """Count ``n`` more items done."""
        self._count += n
        self.update(self._count)

    def _line(self, done: Any, count: int) -> str:
        if self.status is not None:
            return escape(f"{self.title}: {self.status(done)}")
        of = f"/{self.total}" if self.total else ""
        return escape(f"{self.title}: {count}{of} {self.unit}")

    def __exit__(self, *exc: object) -> None:
        if self._progress is not None:
            self._progress.stop()
        if self._live is not None:
            self._live.stop()


def _done_of(report: Any) -> int:
    return int(getattr(report, "processed", 0) + getattr(report, "skipped", 0) + getattr(report, "failed", 0))


def print_summary(summary: JobSummary, unit: str, *, detail: str = "", console: Console | None = None) -> int:
    """Print the job's summary line, its notes and its first failures (always, even under ``--quiet``);
    return its exit code (0, or 1 when inputs failed)."""
    from murk.io.jobs import summary_line

    out = console or Console(stderr=True, highlight=False)
    out.print(escape(summary_line(summary, unit, detail)), soft_wrap=True, highlight=False)
    for note in summary.notes:
        out.print(f"  [yellow]note:[/] {escape(note)}", soft_wrap=True, highlight=False)
    for rec in summary.failures[:MAX_LISTED_FAILURES]:
        where = "".join(f" {k} {v}" for k, v in rec.to_json().items() if k in ("frame", "variant", "index"))
        text = rec.error if rec.error.startswith(rec.input) else f"{rec.input}: {rec.error}"
        out.print(f"  [red]failed[/] ({rec.stage}{where}): {escape(text)}", soft_wrap=True, highlight=False)
    if len(summary.failures) > MAX_LISTED_FAILURES and summary.errors_path is not None:
        out.print(f"  all {summary.failed} failures: {escape(str(summary.errors_path))}", soft_wrap=True)
    return summary.exit_code
