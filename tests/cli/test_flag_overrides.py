"""CLI overrides map flags to config paths declaratively (issue 14): the tables name real flags and fields."""

from __future__ import annotations

import dataclasses
import inspect

import pytest

from murk.cli import synth as cli_synth
from murk.cli import train as cli_train
from murk.cli._common import flag_overrides
from murk.synth.config import SynthConfig
from murk.train.config import TrainConfig


def test_flag_overrides_nests_dotted_paths_and_skips_unset_flags():
    table = {"fs_mode": "forward_scatter.mode", "seed": "seed", "crop": "input.crop_px", "size": "input.size"}
    got = flag_overrides(table, {"fs_mode": "exact", "seed": None, "crop": 8, "size": [64, 48], "other": 1})
    assert got == {"forward_scatter": {"mode": "exact"}, "input": {"crop_px": 8, "size": [64, 48]}}


@pytest.mark.parametrize(
    ("command", "table", "config"),
    [
        (cli_synth.synth, cli_synth.CONFIG_PATHS, SynthConfig()),
        (cli_train.train, cli_train.CONFIG_PATHS, TrainConfig()),
    ],
)
def test_every_table_entry_is_a_parameter_and_a_config_field(command, table, config):
    params = set(inspect.signature(command).parameters)
    for flag, path in table.items():
        assert flag in params, flag
        node = config
        for key in path.split("."):
            assert key in {f.name for f in dataclasses.fields(node)}, path
            node = getattr(node, key)
