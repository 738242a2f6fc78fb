"""configs/README.md, the index of the run configurations: every file in configs/ is named there (shipped stage,
recipe or measured experiment), every name there is a file, and every file loads (a training config, or a study
whose arms load)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from murk._config import load_yaml
from murk.train.config import TrainConfig
from murk.train.study import load_study

CONFIGS = Path(__file__).resolve().parents[2] / "configs"
NAME = re.compile(r"`([A-Za-z0-9_.-]+\.yaml)`")


def named_in_index(text: str) -> set[str]:
    """The configuration files the index names (in backticks)."""
    return set(NAME.findall(text))


def test_the_index_names_every_config_and_only_configs_that_exist() -> None:
    named = named_in_index((CONFIGS / "README.md").read_text(encoding="utf-8"))
    files = {p.name for p in CONFIGS.glob("*.yaml")}
    assert files, "no configs found"
    assert not files - named, f"configs/README.md does not name: {sorted(files - named)}"
    assert not named - files, f"configs/README.md names files that do not exist: {sorted(named - files)}"


def test_the_index_pattern_reads_backticked_names_only() -> None:
    """The pattern the index check reads names with: backticked config names count, a bare mention does not (so the
    check above cannot pass by matching nothing, or by a name merely mentioned in prose)."""
    text = "| `train-a-cpu.yaml` | x |\n| `study-b.yaml` | y |\nplain train-c.yaml is not a listing"
    assert named_in_index(text) == {"train-a-cpu.yaml", "study-b.yaml"}


@pytest.mark.parametrize("path", sorted(CONFIGS.glob("*.yaml")), ids=lambda p: p.name)
def test_every_config_loads(path: Path) -> None:
    if path.name.startswith("study-"):
        study, base = load_study(path)
        assert study.arms and base.model.kind in ("jointid", "lite")
    else:
        cfg = load_yaml(TrainConfig, path)
        assert cfg.model.kind in ("jointid", "lite")
