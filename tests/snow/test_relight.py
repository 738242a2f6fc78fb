"""``murk snow relight``: a bank's particles relit once, shapes kept, provenance recorded; the default bank is
what the documented command makes of ``builtin:snow-real``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import default_snow_bank
from murk.errors import InputFileError
from murk.snow.bank import load_bank, save_bank
from murk.snow.composite import composite_snow, particle_lumas, sample_snow
from murk.snow.relight import relight_bank, relight_bank_file

from .conftest import make_bank


def test_each_particle_gets_its_drawn_mean_luma_and_keeps_its_shape() -> None:
    bank = make_bank(colour=(30, 20, 10), sizes=(1, 2, 3, 4, 5))
    lit = relight_bank(bank, (120.0, 200.0), seed=4)
    target = np.random.default_rng(4).uniform(120.0, 200.0, size=len(bank))
    np.testing.assert_allclose(particle_lumas(lit), target, atol=0.5)  # rounded to uint8 per pixel
    assert np.all(lit.pixel_rgb[:, 0] == lit.pixel_rgb[:, 1]) and np.all(lit.pixel_rgb[:, 1] == lit.pixel_rgb[:, 2])
    np.testing.assert_array_equal(lit.offsets, bank.offsets)
    np.testing.assert_array_equal(lit.pixel_yx, bank.pixel_yx)
    np.testing.assert_array_equal(lit.bbox_hw, bank.bbox_hw)
    assert lit.bank_id != bank.bank_id
    assert lit.meta["relight"] == {"luma": [120.0, 200.0], "seed": 4, "from_bank_id": bank.bank_id}
    assert lit.meta["sources"] == bank.meta["sources"]


def test_luma_patterns_are_kept_and_clipped_at_white() -> None:
    from murk.snow.bank import build_bank
    from murk.snow.extract import Particle

    rgb = np.zeros((1, 2, 3), np.uint8)
    rgb[0, 0], rgb[0, 1] = 10, 40  # a dim and a 4x brighter pixel
    bank = build_bank([({"path": "x"}, [Particle(rgb, np.ones((1, 2), bool), 0, 0)])])
    lit = relight_bank(bank, (100.0, 100.0))
    assert list(lit.pixel_rgb[:, 0]) == [40, 160]  # gain 100 / 25: the pattern scaled
    hot = relight_bank(bank, (250.0, 250.0))
    assert list(hot.pixel_rgb[:, 0]) == [100, 255]  # the brighter pixel clipped at white


def test_seed_decides_the_draws() -> None:
    bank = make_bank(sizes=(1, 2, 3, 4))
    a, b, c = (relight_bank(bank, (50.0, 250.0), seed=s) for s in (1, 1, 2))
    np.testing.assert_array_equal(a.pixel_rgb, b.pixel_rgb)
    assert not np.array_equal(a.pixel_rgb, c.pixel_rgb)


def test_relit_dim_particles_composite_bright() -> None:
    dim = make_bank(colour=(20, 25, 20), sizes=(3, 4, 5))
    lit = relight_bank(dim, (200.0, 220.0))
    img = np.full((48, 64, 3), 0.4, np.float32)
    outs = []
    for bank in (dim, lit):
        params = sample_snow(np.random.default_rng(0), bank, n_particles=(40, 40), scale=(1.0, 1.0))
        out, alpha = composite_snow(img, params, bank)
        on = (alpha[..., 0] if alpha.ndim == 3 else alpha) > 0.5
        outs.append(float(out[on].mean()))
    assert outs[0] < 0.4 < 0.7 < outs[1]  # dark blots before, bright specks after


def test_bad_input_is_refused(tmp_path: Path) -> None:
    bank = make_bank()
    with pytest.raises(ValueError, match="luma"):
        relight_bank(bank, (200.0, 100.0))
    with pytest.raises(ValueError, match="luma"):
        relight_bank(bank, (0.0, 100.0))
    with pytest.raises(InputFileError, match=r"missing\.npz"):
        relight_bank_file(tmp_path / "missing.npz", tmp_path / "out.npz", (120.0, 230.0))
    assert not (tmp_path / "out.npz").exists()


def test_cli_writes_the_shipped_default_bank_from_the_real_footage_bank(tmp_path: Path) -> None:
    out = tmp_path / "default.npz"
    r = CliRunner().invoke(app, ["snow", "relight", "builtin:snow-real", "--luma", "120,230", "--out", str(out)])
    assert r.exit_code == 0, r.output
    assert "17888 particles relit" in r.output
    made, shipped = load_bank(out), load_bank(default_snow_bank())  # the documented command (DATA_LICENSES.md)
    assert made.meta == shipped.meta and made.bank_id == shipped.bank_id
    np.testing.assert_array_equal(made.pixel_rgb, shipped.pixel_rgb)
    r = CliRunner().invoke(app, ["snow", "relight", "builtin:snow-real", "--luma", "9", "--out", str(out)])
    assert r.exit_code != 0 and "--luma" in r.output


def test_a_relit_bank_round_trips(tmp_path: Path) -> None:
    lit = relight_bank(make_bank(), (120.0, 130.0))
    back = load_bank(save_bank(lit, tmp_path / "lit.npz"))
    assert back.bank_id == lit.bank_id and back.meta["relight"] == lit.meta["relight"]


def test_relighting_a_bank_over_itself_is_refused_and_leaves_it_as_cut(tmp_path: Path) -> None:
    bank = save_bank(make_bank(), tmp_path / "cut.npz")
    before = bank.read_bytes()
    r = CliRunner().invoke(app, ["snow", "relight", str(bank), "--out", str(tmp_path / "." / "cut.npz")])
    assert r.exit_code == 2 and "this is the input" in " ".join(r.output.split())
    assert bank.read_bytes() == before
