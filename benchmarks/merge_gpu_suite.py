"""Put the figures of a ``gpu_suite.py`` run into BENCHMARKS.md's GPU blocks.

Run: python3 benchmarks/merge_gpu_suite.py gpu-suite/gpu_suite.json [MORE.json ...] [--benchmarks BENCHMARKS.md]

Each section of BENCHMARKS.md that has GPU figures holds a block between ``<!-- gpu: NAME -->`` and
``<!-- /gpu: NAME -->``; the block is replaced by a table of the figures of the parts whose ``section`` is NAME
(part, figure, value, the baseline measured in the same run, ratio, target), a line with the run's date, GPU and
versions, and what was not measured and why. Nothing outside the blocks changes, and merging twice gives the same
file. Given several JSON files (a full run, then a rerun of some parts with ``--parts``), a later file's parts
replace the earlier ones. A CPU dry run is refused unless ``--allow-dry-run`` (its figures are not GPU figures).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from gpu_suite import ROOT, figure_row, machine_line  # noqa: E402

BLOCK = re.compile(r"(<!-- gpu: (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- /gpu: (?P=name) -->)", re.DOTALL)


def load_runs(paths: list[Path], allow_dry_run: bool) -> dict[str, tuple[dict[str, Any], dict[str, Any]]]:
    """Part name -> (part, its run), later files winning.

    Raises:
        ValueError: a file that is not a gpu_suite report, or a dry run without ``allow_dry_run``.
    """
    parts: dict[str, tuple[dict[str, Any], dict[str, Any]]] = {}
    for path in paths:
        run = json.loads(path.read_text(encoding="utf-8"))
        if not isinstance(run, dict) or "parts" not in run or "mode" not in run:
            raise ValueError(f"{path}: not a gpu_suite.json report (no 'parts'/'mode')")
        if run["mode"] != "gpu" and not allow_dry_run:
            raise ValueError(
                f"{path}: a {run['mode']} report holds no GPU figures (use --allow-dry-run to merge anyway)"
            )
        for part in run["parts"]:
            parts[part["name"]] = (part, run)
    return parts


def render_block(name: str, parts: list[tuple[dict[str, Any], dict[str, Any]]]) -> str:
    """The Markdown that replaces the body of block ``name``."""
    runs = {id(run): run for _, run in parts}.values()
    lines = []
    for run in runs:
        dry = " **CPU DRY RUN, not GPU figures**" if run["mode"] != "gpu" else ""
        lines.append(f"GPU figures from `benchmarks/gpu_suite.py`{dry} ({run['date']}): {machine_line(run)}.")
    lines.append("")
    if name == "gpu-suite":  # the run's summary: every part, its status and time
        lines += ["| part | status | wall / budget | figures |", "|---|---|---|---|"]
        for run in runs:
            for p in run["parts"]:
                wall = f"{p.get('wall_s', 0):.0f} / {p['budget_s']:.0f} s"
                lines.append(f"| {p['name']} | {p['status']} | {wall} | {len(p.get('figures', []))} |")
            lines.append(f"| total | | {run.get('wall_s', 0):.0f} / {run['limit_s']:.0f} s | |")
        lines.append("")
    rows = [f"| `{part['name']}` " + figure_row(f) for part, _ in parts for f in part.get("figures", [])]
    if rows:
        lines += [
            "| part | GPU figure | value | same-run baseline | ratio | target |",
            "|---|---|---|---|---|---|",
            *rows,
            "",
        ]
    missing = []
    for part, _ in parts:
        notes = [*part.get("notes", [])]
        if part["status"] != "ok":
            why = part.get("skipped") or part.get("error") or ""
            missing.append(f"- `{part['name']}`: **{part['status']}**" + (f" ({why[:300]})" if why else ""))
        missing += [f"- `{part['name']}`: {q['label']}: {q['kind']} ({q['why']})" for q in part.get("problems", [])]
        missing += [f"- `{part['name']}`: {n}" for n in notes]
    if missing:
        lines += ["Notes and what was not measured:", "", *missing, ""]
    return "\n".join(lines)


def merge(text: str, parts: dict[str, tuple[dict[str, Any], dict[str, Any]]]) -> tuple[str, list[str]]:
    """``text`` with every GPU block that has parts replaced; also the names of the blocks replaced."""
    done: list[str] = []

    def replace(m: re.Match[str]) -> str:
        name = m["name"]
        mine = [pr for pr in parts.values() if pr[0]["section"] == name]
        if not mine:
            return m.group(0)
        done.append(name)
        return m.group(1) + render_block(name, mine) + m.group(4)

    return BLOCK.sub(replace, text), done


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reports", nargs="+", type=Path, help="gpu_suite.json files (later ones win, part by part)")
    ap.add_argument("--benchmarks", type=Path, default=ROOT / "BENCHMARKS.md")
    ap.add_argument("--allow-dry-run", action="store_true", help="merge a CPU dry run too (for tests)")
    args = ap.parse_args(argv)
    try:
        parts = load_runs(args.reports, args.allow_dry_run)
    except (OSError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    text = args.benchmarks.read_text(encoding="utf-8")
    new, done = merge(text, parts)
    sections = {p["section"] for p, _ in parts.values()}
    unplaced = sorted(sections - set(done))
    if new != text:
        from murk.io.atomic import write_text_atomic

        write_text_atomic(args.benchmarks, new)
    print(f"{args.benchmarks}: GPU blocks updated: {', '.join(done) or 'none'}")
    if unplaced:
        print(f"no <!-- gpu: NAME --> block for: {', '.join(unplaced)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
