"""tools/mypy_baseline.py: the committed mypy baseline may only shrink (mypy itself is not run here)."""

from __future__ import annotations

import importlib.util
from collections import Counter
from pathlib import Path

import pytest

_PATH = Path(__file__).resolve().parents[2] / "tools" / "mypy_baseline.py"
_spec = importlib.util.spec_from_file_location("mypy_baseline", _PATH)
assert _spec is not None and _spec.loader is not None
mb = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mb)

OUTPUT = """\
src/murk/a.py:10: error: Incompatible types in assignment  [assignment]
src/murk/a.py:20:5: error: Incompatible types in assignment  [assignment]
src/murk/a.py:21: note: a note, not an error
src/murk/b.py:3: error: Name "x" is not defined  [name-defined]
Found 3 errors in 2 files (checked 2 source files)
"""


def test_errors_are_compared_without_line_numbers_and_counted() -> None:
    errors = mb.normalise(OUTPUT)
    assert errors == Counter(
        {
            "src/murk/a.py: error: Incompatible types in assignment [assignment]": 2,
            'src/murk/b.py: error: Name "x" is not defined [name-defined]': 1,
        }
    )


def _run(monkeypatch: pytest.MonkeyPatch, output: str, *args: str) -> int:
    monkeypatch.setattr(mb, "run_mypy", lambda: output)
    return int(mb.main(list(args)))


def test_new_errors_fail_fixed_ones_ask_for_a_smaller_baseline(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "mypy-baseline.txt"
    monkeypatch.setattr(mb, "BASELINE", path)

    assert _run(monkeypatch, OUTPUT, "--update") == 1  # an empty baseline may not grow
    assert "3 error(s) not in the baseline" in capsys.readouterr().out
    assert _run(monkeypatch, OUTPUT, "--update", "--allow-new") == 0
    assert sum(mb.read_baseline(path).values()) == 3
    assert _run(monkeypatch, OUTPUT) == 0

    worse = OUTPUT + "src/murk/c.py:1: error: Missing return statement  [return]\n"
    assert _run(monkeypatch, worse) == 1
    assert "1 new error(s)" in capsys.readouterr().out

    better = OUTPUT.replace('src/murk/b.py:3: error: Name "x" is not defined  [name-defined]\n', "")
    assert _run(monkeypatch, better) == 1
    assert "no longer occur; record the fix with `python tools/mypy_baseline.py --update`" in capsys.readouterr().out
    assert _run(monkeypatch, better, "--update") == 0
    assert sum(mb.read_baseline(path).values()) == 2 and _run(monkeypatch, better) == 0
