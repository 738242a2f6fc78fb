"""The ``murk`` application: registers one command per module."""

from __future__ import annotations

from typing import Annotated

import typer

from murk._version import __version__
from murk.cli import compare as _compare
from murk.cli import demo as _demo
from murk.cli import detail as _detail
from murk.cli import enhance as _enhance
from murk.cli import eval as _eval
from murk.cli import export as _export
from murk.cli import live as _live
from murk.cli import scenes as _scenes
from murk.cli import snow as _snow
from murk.cli import study as _study
from murk.cli import synth as _synth
from murk.cli import train as _train
from murk.cli import water as _water
from murk.cli._common import MurkGroup

app = typer.Typer(
    name="murk",
    cls=MurkGroup,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
    help="murk: realistic underwater data synthesis, restoration and metrics for underwater robots.",
)


def _show_version(value: bool) -> None:
    if value:
        typer.echo(f"murk {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool, typer.Option("--version", callback=_show_version, is_eager=True, help="Print the version and exit.")
    ] = False,
    max_pixels: Annotated[
        int | None,
        typer.Option(
            "--max-pixels",
            min=1,
            help="Refuse images whose header declares more pixels (default 100,000,000 or MURK_MAX_PIXELS).",
        ),
    ] = None,
) -> None:
    """murk: realistic underwater data synthesis, restoration and metrics for underwater robots."""
    from murk._limits import max_pixels as pixel_limit
    from murk._limits import set_max_pixels
    from murk._perf import tune_allocator

    tune_allocator()
    set_max_pixels(max_pixels)
    pixel_limit()  # a bad MURK_MAX_PIXELS is a usage error now, not a failure of every image later


app.command("synth")(_synth.synth)
app.add_typer(_snow.app, name="snow")
app.add_typer(_water.app, name="water")
app.add_typer(_detail.app, name="detail")
app.command("scenes")(_scenes.scenes)
app.command("train")(_train.train)
app.command("study")(_study.study)
app.command("enhance")(_enhance.enhance)
app.command("live")(_live.live)
app.command("eval")(_eval.evaluate)
app.command("export")(_export.export)
app.command("compare")(_compare.compare)
app.command("demo")(_demo.demo)


def main() -> None:
    """Console-script entry point: idle OpenMP threads sleep (murk/_perf.py) unless the user chose otherwise."""
    from murk._perf import prefer_passive_openmp

    prefer_passive_openmp()
    app(prog_name="murk")
