"""``murk study``: train the arms (:mod:`murk.train.study`), then evaluate them and write the report."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from murk.train.study import ArmRun, load_study, train_arms


@dataclass
class StudyResult:
    """What a ``murk study`` invocation did."""

    out_dir: Path
    arms: list[ArmRun] = field(default_factory=list)
    report: dict[str, Any] = field(default_factory=dict)
    ok: bool = True
    message: str = ""


def run_study(
    config_file: str | Path,
    out_dir: str | Path,
    *,
    train_only: bool = False,
    on_event: Callable[[str], None] | None = None,
) -> StudyResult:
    """Train every unfinished arm, then (unless ``train_only``) evaluate all arms and write the report."""
    study, base = load_study(config_file)
    out = Path(out_dir)
    result = StudyResult(out)
    result.arms = train_arms(study, base, out, on_event=on_event)
    failed = [a.name for a in result.arms if a.status == "failed"]
    if failed:
        result.ok = False
        result.message = f"study: arm(s) {', '.join(failed)} failed; rerun the same command to retry"
        return result
    if train_only:
        result.message = f"study: {len(result.arms)} arm(s) trained -> {out / 'models'}"
        return result
    raise NotImplementedError("evaluation")
