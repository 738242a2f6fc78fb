from __future__ import annotations

from pathlib import Path

import pytest

from murk._config import dump_yaml, load_yaml, merge
from murk.physics.jerlov import WATER_TYPES
from murk.synth.config import SynthConfig, parse_stages


def test_defaults_are_the_papers() -> None:
    c = SynthConfig()
    assert c.variants == 8 and c.medium.water_types == WATER_TYPES
    assert (c.forward_scatter.sigma0_px, c.forward_scatter.k_px_per_m, c.forward_scatter.gamma_per_m) == (
        0.5,
        0.15,
        0.2,
    )
    assert c.medium.near_m == 0.3 and c.medium.max_range_m == 15.0 and c.medium.vertical_depth_m == (3.0, 5.0)
    assert c.marine_snow.n_particles == (1000, 1600) and c.marine_snow.scale == (0.3, 0.6)
    assert c.marine_snow.rho_px == (0.2, 1.0)


def test_yaml_round_trip(tmp_path: Path) -> None:
    c = merge(SynthConfig(), {"variants": 3, "medium": {"water_types": ["I", "9C"]}, "input": {"size": [320, 240]}})
    p = tmp_path / "c.yaml"
    p.write_text(dump_yaml(c, murk_version="x").replace("murk_version: x\n", ""))
    assert load_yaml(SynthConfig, p) == c
    assert c.medium.water_types == ("I", "9C") and c.input.size == (320, 240)


def test_yaml_errors_name_file_and_key(tmp_path: Path) -> None:
    p = tmp_path / "bad.yaml"
    p.write_text("medium:\n  water_type: [I]\n")
    with pytest.raises(
        ValueError, match=r"bad\.yaml\.medium: unknown key\(s\) water_type \(did you mean 'water_types'\?\); allowed: "
    ):
        load_yaml(SynthConfig, p)
    p.write_text("variants: many\n")
    with pytest.raises(ValueError, match=r"bad\.yaml\.variants: expected an integer, got 'many'"):
        load_yaml(SynthConfig, p)
    p.write_text("forward_scatter:\n  mode: magic\n")
    with pytest.raises(ValueError, match=r"forward_scatter\.mode: expected one of 'approx', 'exact'"):
        load_yaml(SynthConfig, p)
    p.write_text("variants: [1\n")
    with pytest.raises(ValueError, match="invalid YAML"):
        load_yaml(SynthConfig, p)
    with pytest.raises(ValueError, match="config file not found"):
        load_yaml(SynthConfig, tmp_path / "none.yaml")
    p.write_text("- a list\n")
    with pytest.raises(ValueError, match=r"bad\.yaml: expected a mapping of SynthConfig fields, got a list of 1"):
        load_yaml(SynthConfig, p)


def test_the_resume_check_names_a_corrupt_earlier_config(tmp_path: Path) -> None:
    from murk.synth.common import check_config_compatible

    (tmp_path / "config.yaml").write_text("variants: [1\n")
    with pytest.raises(ValueError, match=r"config\.yaml: invalid YAML"):
        check_config_compatible(tmp_path, SynthConfig())
    (tmp_path / "config.yaml").write_text("just text\n")
    with pytest.raises(ValueError, match=r"config\.yaml: expected a mapping of the configuration of an earlier run"):
        check_config_compatible(tmp_path, SynthConfig())


def test_validation_errors() -> None:
    with pytest.raises(ValueError, match="variants: expected >= 1"):
        SynthConfig(variants=0)
    with pytest.raises(ValueError, match="relative depth has no metric scale"):
        merge(SynthConfig(), {"input": {"depth_relative": True}, "medium": {"distance_mode": "metric"}})
    with pytest.raises(ValueError, match="stages: unknown stage\\(s\\) 'haze'; expected a comma list"):
        parse_stages("basic,haze")
    with pytest.raises(ValueError, match="stages: no stage in ' , '"):
        parse_stages(" , ")
    assert parse_stages("forward_scatter,basic") == ("basic", "forward_scatter")
    with pytest.raises(ValueError, match="vertical_depth_m: expected min <= max"):
        merge(SynthConfig(), {"medium": {"vertical_depth_m": [5, 3]}})


def test_config_written_by_murk_loads_back(tmp_path: Path) -> None:
    """`murk synth --config OUT/config.yaml` reproduces a run: the provenance keys murk writes are ignored."""
    cfg = SynthConfig(variants=3, seed=7)
    path = tmp_path / "config.yaml"
    path.write_text(dump_yaml(cfg, murk_version="0.1.0"))
    assert load_yaml(SynthConfig, path) == cfg
    path.write_text(dump_yaml(cfg, murk_version="0.1.0", surprise=1))
    with pytest.raises(ValueError, match="unknown key"):
        load_yaml(SynthConfig, path)


def test_hostile_yaml_gives_one_line_errors_naming_the_file(tmp_path: Path) -> None:
    """Anchor bombs, deep nesting and non-UTF-8 files: a short ValueError naming the file, never a hang or a
    traceback (issue 13)."""
    bomb = ["a: &a [x, x, x, x, x, x, x, x, x]"]
    for i in range(1, 9):  # 9^9 elements if expanded
        prev = chr(ord("a") + i - 1)
        cur = chr(ord("a") + i)
        bomb.append(f"{cur}: &{cur} [" + ", ".join([f"*{prev}"] * 9) + "]")
    bomb.append("variants: *i")
    path = tmp_path / "bomb.yaml"
    path.write_text("\n".join(bomb) + "\n")
    with pytest.raises(ValueError) as err:
        load_yaml(SynthConfig, path)
    assert str(path) in str(err.value) and len(str(err.value)) < 400
    deep = tmp_path / "deep.yaml"
    deep.write_text("variants: " + "[" * 20000 + "]" * 20000 + "\n")
    with pytest.raises(ValueError, match=r"deep\.yaml"):
        load_yaml(SynthConfig, deep)
    latin = tmp_path / "latin.yaml"
    latin.write_bytes("variants: 2 # caf\xe9\n".encode("latin-1"))
    with pytest.raises(ValueError, match=r"latin\.yaml: not UTF-8"):
        load_yaml(SynthConfig, latin)
