"""Run ``murk train`` through the command line on a config dict (the tests' small runs)."""

from __future__ import annotations

from pathlib import Path

import yaml
from typer.testing import CliRunner

from murk.cli.main import app


def train_cli(tmp_path: Path, config: dict) -> Path:
    """Write ``config`` to ``tmp_path/t.yaml``, run ``murk train`` into ``tmp_path/run`` (asserting exit 0) and
    return the run folder."""
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(config))
    r = CliRunner().invoke(
        app, ["train", "--config", str(tmp_path / "t.yaml"), "--out", str(tmp_path / "run"), "--quiet"]
    )
    assert r.exit_code == 0, r.output
    return tmp_path / "run"
