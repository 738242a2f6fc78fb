"""The ``murk`` application: registers one command per module."""

from __future__ import annotations

from typing import Annotated

import typer

from murk._version import __version__
from murk.cli import scenes as scenes_cmd
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
) -> None:
    """murk: realistic underwater data synthesis, restoration and metrics for underwater robots."""


app.command("scenes")(scenes_cmd.scenes)


def main() -> None:
    """Console-script entry point."""
    app(prog_name="murk")
