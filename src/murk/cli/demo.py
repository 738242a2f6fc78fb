"""``murk demo``: the embedded end-to-end run (what ``make demo`` does)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from murk.cli._common import EXIT_PARTIAL, QuietOpt, flag_text, make_console


def demo(
    out: Annotated[Path, typer.Option("--out", help="Output folder.")] = Path("murk-demo"),
    quick: Annotated[bool, typer.Option("--quick", help="The same pipeline at CI size (under two minutes).")] = False,
    seed: Annotated[int, typer.Option("--seed", help="Seed of every stage.")] = 0,
    quiet: QuietOpt = False,
) -> None:
    """Run the paper's whole pipeline on embedded data: procedural scenes -> synthesis (3 stages) -> a short
    illustration of murk train -> restoration of real underwater images with the SHIPPED murk-trained Joint-ID
    -> compare -> report.html.
    """
    from murk.workflows.demo import run_demo

    console = make_console(quiet)
    res = run_demo(out, quick=quick, seed=seed, log=lambda m: console.print(m, highlight=False, soft_wrap=True))
    summary = make_console()
    summary.print(
        "\nmean UIQM on the real images (higher = more colourful, sharper, more contrast; UIQM also rewards noise,"
        " so read it with the restoration flags of docs/metrics.md):",
        highlight=False,
    )
    for label, value in res.summary["uiqm"].items():
        flagged = flag_text(res.summary["flags"].get(label) or {"flagged": 0, "n": 0})
        summary.print(f"  {label:<20} {value:.3f}  {flagged}", highlight=False)
    total = sum(res.seconds.values())
    summary.print(
        "\n".join(
            [
                f"\ndemo finished in {total:.0f} s ("
                + ", ".join(f"{k} {v:.0f} s" for k, v in res.seconds.items())
                + ")",
                f"  clean RGB-D scenes : {res.paths['scenes']}",
                f"  synthetic dataset  : {res.paths['synth']}  (manifest.jsonl, train.txt, degraded/, snow_alpha/)",
                "  restoration        : jointid / jointid+post / lite = the shipped models (docs/models.md)",
                f"  train illustration : {res.paths['checkpoint']}",
                f"  report             : {res.paths['report']}",
            ]
        ),
        highlight=False,
        soft_wrap=True,
    )
    if res.summary.get("compare_errors"):
        raise typer.Exit(EXIT_PARTIAL)
