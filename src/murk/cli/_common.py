"""Pieces shared by the command modules: options, console, error reporting and exit codes.

Exit codes: 0 = everything succeeded; 1 = the job ran but some inputs failed (see ``errors.jsonl``);
2 = bad usage or input (the message names the file and the problem).
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
from collections.abc import Iterator, Mapping
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.markup import escape
from typer.core import TyperGroup

EXIT_OK = 0
EXIT_PARTIAL = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="Print only errors and the final summary.")]
DeviceOpt = Annotated[str, typer.Option("--device", help="cpu, cuda or cuda:N.")]


def topic_option(inputs: str) -> Any:
    """The ``--topic`` option of a command reading ROS bags (``inputs`` names them in the help): the image topic,
    and the bag's topics are listed when it is left out."""
    return typer.Option("--topic", help=f"{inputs}: the image topic (omit it to list them).")


class MurkGroup(TyperGroup):
    """Turns ``ValueError``/``OSError`` raised by the library into a clean one-line error (exit code 2).

    Set ``MURK_DEBUG=1`` to see the full traceback instead.
    """

    def invoke(self, ctx: Any) -> Any:
        try:
            return super().invoke(ctx)
        except (ValueError, OSError) as exc:
            if os.environ.get("MURK_DEBUG"):
                raise
            print_error(error_text(exc))
            raise typer.Exit(EXIT_USAGE) from exc
        except KeyboardInterrupt:
            if os.environ.get("MURK_DEBUG"):
                raise
            Console(stderr=True, highlight=False).print(
                "interrupted: finished outputs are kept; rerun the same command to continue "
                "(murk train: with --resume)",
                soft_wrap=True,
            )
            raise typer.Exit(EXIT_INTERRUPTED) from None


def command_group(help: str) -> typer.Typer:
    """A ``murk <group> <command>`` sub-application (``murk snow``, ``murk water``) with murk's help style."""
    return typer.Typer(cls=MurkGroup, no_args_is_help=True, add_completion=False, rich_markup_mode="rich", help=help)


def error_text(exc: BaseException) -> str:
    """The one-line message of a library error. A bare ``OSError`` (``[Errno 13] Permission denied: 'x'``) is
    written as ``x: permission denied`` so that the path leads, as in every other murk error (murk's own
    ``OutputError`` already reads that way)."""
    from murk.errors import OutputError

    if isinstance(exc, OSError) and not isinstance(exc, OutputError) and exc.filename:
        other = f" -> {exc.filename2}" if exc.filename2 else ""
        reason = (exc.strerror or str(exc)).lower()
        return f"{exc.filename}{other}: {reason} (murk could not access this path)"
    return str(exc)


def print_error(message: str) -> None:
    """Print ``error: message`` on stderr (one line, no traceback)."""
    Console(stderr=True, highlight=False).print(f"[bold red]error:[/] {escape(message)}", soft_wrap=True)


def make_console(quiet: bool = False) -> Console:
    """Console for progress and summaries (stderr, so stdout stays clean for tables and data)."""
    return Console(stderr=True, quiet=quiet, highlight=False)


def parse_size(text: str, *, option: str = "--size") -> tuple[int, int]:
    """Parse ``WxH`` (e.g. ``640x480``) into (width, height), both >= 1; the error names ``option``."""
    from murk._checks import int_pair
    from murk._limits import max_pixels

    pair = int_pair(text.lower().strip().split("x"))
    if pair is None or min(pair) < 1:
        raise ValueError(f"{option}: expected WxH with integers >= 1 (e.g. 640x480), got {text!r}")
    w, h = pair
    if w * h > max_pixels():
        raise ValueError(
            f"{option}: {w}x{h} = {w * h:,} pixels is over the limit of {max_pixels():,} (murk --max-pixels N)"
        )
    return w, h


def resolve_device(device: str) -> str:
    """Validate a ``--device`` value; ``cuda`` without a GPU is an error that says so (only that asks torch, so
    ``cpu`` and a misspelt value answer without importing it)."""
    dev = device.strip().lower()
    if dev == "cpu":
        return "cpu"
    if dev.startswith("cuda"):
        import torch

        if not torch.cuda.is_available():
            raise ValueError(
                f"--device {device}: CUDA is not available on this machine (torch {torch.__version__}); leave "
                "--device out to run on the CPU, or install a CUDA build of torch (README, Install)"
            )
        return dev
    raise ValueError(f"--device: expected cpu, cuda or cuda:N, got {device!r}")


def flag_overrides(table: dict[str, str], values: dict[str, Any]) -> dict[str, Any]:
    """Nested config overrides from command-line flags: ``table`` maps a flag's parameter name to its dotted
    config path (``{"fs_mode": "forward_scatter.mode"}``); flags left at None are not overrides."""
    out: dict[str, Any] = {}
    for name, path in table.items():
        value = values.get(name)
        if value is None:
            continue
        *parents, leaf = path.split(".")
        node = out
        for key in parents:
            node = node.setdefault(key, {})
        node[leaf] = value
    return out


def flag_text(counts: Mapping[str, float] | None) -> str:
    """``flagged K/N (name count, ...)`` from :func:`murk.metrics.count_flags`'s counts; empty without counts."""
    if not counts or not counts.get("n"):
        return ""
    named = ", ".join(f"{k} {int(v)}" for k, v in counts.items() if k not in ("flagged", "n") and v)
    return f"flagged {int(counts.get('flagged', 0))}/{int(counts['n'])}" + (f" ({named})" if named else "")


def mean_std_text(stats: dict[str, Any], width: int = 9) -> str:
    """``mean +- std`` of a summary entry (``mean``, ``std``, ``n``); ``-`` when no value was finite (n = 0)."""
    if not stats.get("n"):
        return f"{'-':>{width}}" + " " * 9
    return f"{stats['mean']:>{width}.3f} +- {stats['std']:<5.3f}"


def merge_flags(config: Any, table: dict[str, str], values: dict[str, Any]) -> Any:
    """``config`` with the flags of :func:`flag_overrides` applied; a value the config refuses is reported under
    the flag's own name (``--water-types: unknown type 'XX'...``) instead of its config path."""
    from murk._config import merge

    where = "command line"
    try:
        return merge(config, flag_overrides(table, values), where=where)
    except ValueError as exc:
        text = str(exc)
        for name, path in table.items():
            parent, _, leaf = path.rpartition(".")
            prefixes = [f"{where}.{path}: ", f"{where}.{parent}: {leaf}: " if parent else f"{where}: {leaf}: "]
            for prefix in prefixes:
                if values.get(name) is not None and text.startswith(prefix):
                    raise ValueError(f"--{name.replace('_', '-')}: {text[len(prefix) :]}") from None
        raise


@contextlib.contextmanager
def stop_on_signals() -> Iterator[Any]:
    """Yield a ``should_stop`` callable set by SIGINT/SIGTERM, so outputs are closed cleanly; a second
    Ctrl+C raises KeyboardInterrupt at once. Outside the main thread no handler is installed."""
    flag = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield flag.is_set
        return

    def handler(signum: int, frame: Any) -> None:
        if flag.is_set() and signum == signal.SIGINT:
            raise KeyboardInterrupt
        flag.set()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield flag.is_set
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
