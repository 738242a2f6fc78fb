"""Adding a method is one declaration plus one implementation (docs/DESIGN.md, "How to add a method"): a toy method
registered so is listed with its options, checked like a built-in one, and runs through ``murk enhance`` and
``murk live``'s method switch."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.enhance.declare import Checked, Method, opt
from murk.enhance.restorer import Restored, Restorer, available, check, options_of, register, unregister
from murk.io import read_rgb, write_rgb

# ----------------------------------------------------------------------------------- the implementation


class Brighter(Restorer):
    """Multiplies the image by ``gain`` (clipped to [0, 1])."""

    name = "brighter"

    def __init__(self, gain: float) -> None:
        self.gain = gain

    def restore(self, images: np.ndarray) -> Restored:
        return Restored(np.clip(images * np.float32(self.gain), 0.0, 1.0).astype(np.float32))


def make_brighter(o: Checked) -> Brighter:
    return Brighter(o.gain)


# -------------------------------------------------------------------------------------- the declaration

BRIGHTER = Method(
    "brighter",
    "tests.enhance.test_add_a_method:make_brighter",
    (opt("gain", "float", 1.5, "brightness gain", low=0, high=4),),
    help="a brightness gain (a toy method)",
)


@pytest.fixture
def brighter() -> Iterator[Method]:
    register(BRIGHTER)
    try:
        yield BRIGHTER
    finally:
        unregister("brighter")


def test_the_declaration_is_all_the_registry_needs(brighter: Method) -> None:
    assert "brighter" in available()
    option = options_of("brighter")["gain"]
    assert (option.type, option.default, option.help, option.annotation) == ("float", 1.5, "brightness gain", float)
    with pytest.raises(ValueError, match=r"unknown option 'gian' \(did you mean 'gain'\?\)"):
        check("brighter?gian=2")
    with pytest.raises(ValueError, match=r"option gain: expected a number in \[0.0, 4.0\], got 5.0"):
        check("brighter+post?gain=5")
    with pytest.raises(ValueError, match=r"option gain: expected float, got 'x'"):
        check("brighter?gain=x")


def test_the_toy_method_runs_through_murk_enhance(brighter: Method, tmp_path: Path) -> None:
    image = np.full((8, 10, 3), 0.25, np.float32)
    image[:, :5] = 0.5
    write_rgb(tmp_path / "in.png", image)
    res = CliRunner().invoke(
        app, ["enhance", str(tmp_path / "in.png"), "-o", str(tmp_path / "out.png"), "-m", "brighter?gain=2", "-q"]
    )
    assert res.exit_code == 0, res.output
    out = read_rgb(tmp_path / "out.png")
    assert np.allclose(out[:, :5], 1.0) and np.allclose(out[:, 5:], 0.5, atol=1 / 255)
    res = CliRunner().invoke(app, ["enhance", str(tmp_path / "in.png"), "-o", str(tmp_path / "x.png"), "-m", "brightr"])
    assert res.exit_code != 0 and "did you mean 'brighter'" in res.output


def test_the_toy_method_blends_through_murk_enhance(brighter: Method, tmp_path: Path) -> None:
    """A blend needs no code: ``brighter|colorbalance@0.25`` averages the two restorations of the same input."""
    from murk.enhance.restorer import create

    image = np.random.default_rng(1).uniform(0.1, 0.6, (12, 10, 3)).astype(np.float32)
    write_rgb(tmp_path / "in.png", image)
    spec = "brighter|colorbalance@0.25?gain=1.5"  # gain: brighter's option, given to the method that declares it
    res = CliRunner().invoke(app, ["enhance", str(tmp_path / "in.png"), "-o", str(tmp_path / "out.png"), "-m", spec])
    assert res.exit_code == 0, res.output
    x = read_rgb(tmp_path / "in.png")[None]
    want = 0.75 * np.clip(x * 1.5, 0, 1) + 0.25 * create("colorbalance").restore(x).images
    assert np.abs(read_rgb(tmp_path / "out.png") - want[0]).max() <= 1 / 255 + 1e-6
    res = CliRunner().invoke(
        app, ["enhance", str(tmp_path / "in.png"), "-o", str(tmp_path / "x.png"), "-m", "brighter|@2"]
    )
    assert res.exit_code == 2 and "expected a method name after '|'" in res.output


def test_the_toy_method_runs_through_the_live_method_switch(brighter: Method, tmp_path: Path) -> None:
    from tests.live._live import WAIT_S, clip, pipeline

    p = pipeline(clip(tmp_path, n=20, fps=30.0), tmp_path / "out", "post", loop=True).start()
    try:
        first = p.wait_view(-1, WAIT_S)
        assert first is not None, p.status()
        with pytest.raises(ValueError, match="option gain: expected a number in"):
            p.set_method("brighter?gain=9")
        p.set_method("brighter?gain=2")
        view, after = None, first.index
        while view is None or view.method != "brighter?gain=2":
            view = p.wait_view(after, WAIT_S)
            assert view is not None, p.status()
            after = view.index
    finally:
        p.stop()
    expected = np.minimum(view.raw.astype(int) * 2, 255)
    assert np.abs(view.restored.astype(int) - expected).max() <= 1  # the toy method ran on the frame
