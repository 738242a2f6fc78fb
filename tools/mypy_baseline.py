"""Run mypy (configured in pyproject.toml) against the committed baseline of known errors, mypy-baseline.txt.

The baseline may only shrink:

- an error that is not in the baseline fails the check (fix it; do not add it to the baseline);
- a baseline error that no longer occurs also fails the check, so that the fix is recorded: regenerate with
  ``python tools/mypy_baseline.py --update`` and commit the smaller file.

Errors are compared without line numbers (``path: error: message  [code]``, counted), so that editing a file
does not invalidate its entries. ``--update`` refuses to add errors unless ``--allow-new`` is given (for a mypy
or stub upgrade, reviewed by hand).

Usage: python tools/mypy_baseline.py [--update [--allow-new]]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BASELINE = ROOT / "mypy-baseline.txt"
_ERROR = re.compile(r"^(?P<path>[^:\n]+):(?P<line>\d+)(?::\d+)?: error: (?P<message>.*)$")
HEADER = (
    "# Known mypy errors, tolerated by `make check` (tools/mypy_baseline.py). This list may only shrink:\n"
    "# fix errors and regenerate it with `python tools/mypy_baseline.py --update`; never add to it.\n"
)


def normalise(output: str) -> Counter[str]:
    """The error lines of mypy's output as ``path: error: message`` (no line or column numbers), counted."""
    errors: Counter[str] = Counter()
    for line in output.splitlines():
        m = _ERROR.match(line.strip())
        if m:
            path = m["path"].replace("\\", "/")
            errors[f"{path}: error: {' '.join(m['message'].split())}"] += 1
    return errors


def read_baseline(path: Path | None = None) -> Counter[str]:
    """The baseline file's entries (default: mypy-baseline.txt), counted (comments and blank lines skipped)."""
    path = path or BASELINE
    if not path.is_file():
        return Counter()
    lines = path.read_text(encoding="utf-8").splitlines()
    return Counter(line for line in lines if line.strip() and not line.startswith("#"))


def write_baseline(errors: Counter[str], path: Path | None = None) -> None:
    """Write ``errors`` sorted, one per line, under the header (default: mypy-baseline.txt)."""
    (path or BASELINE).write_text(HEADER + "".join(f"{e}\n" for e in sorted(errors.elements())), encoding="utf-8")


def run_mypy() -> str:
    proc = subprocess.run([sys.executable, "-m", "mypy"], cwd=ROOT, capture_output=True, text=True, check=False)
    if proc.returncode not in (0, 1) or (proc.returncode == 1 and "error:" not in proc.stdout):
        sys.stderr.write(proc.stdout + proc.stderr)
        raise SystemExit(f"mypy itself failed (exit code {proc.returncode})")
    return proc.stdout


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--update", action="store_true", help="rewrite mypy-baseline.txt with the current errors")
    parser.add_argument("--allow-new", action="store_true", help="with --update: also record new errors")
    args = parser.parse_args(argv)

    current = normalise(run_mypy())
    baseline = read_baseline()
    new = current - baseline
    fixed = baseline - current
    if args.update:
        if new and not args.allow_new:
            print(f"mypy: {sum(new.values())} error(s) not in the baseline; fix them (the baseline may only shrink):")
            print("".join(f"  {e}\n" for e in sorted(new)), end="")
            return 1
        write_baseline(current)
        print(f"mypy-baseline.txt: {sum(current.values())} error(s) (was {sum(baseline.values())})")
        return 0
    if new:
        print(f"mypy: {sum(new.values())} new error(s), not in mypy-baseline.txt (run mypy to see the lines):")
        print("".join(f"  {e}\n" for e in sorted(new)), end="")
    if fixed:
        print(
            f"mypy: {sum(fixed.values())} error(s) of mypy-baseline.txt no longer occur; record the fix with "
            "`python tools/mypy_baseline.py --update` and commit the smaller baseline:"
        )
        print("".join(f"  {e}\n" for e in sorted(fixed)), end="")
    if new or fixed:
        return 1
    print(f"mypy: no new errors ({sum(current.values())} known, listed in mypy-baseline.txt)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
