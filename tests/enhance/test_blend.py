"""Blends in the method grammar (``A|B@W``): the Blend restorer (lerp of two restorations, depth of the first that
gives one, numpy members blended without torch), the registry's routing of options into blends and presets, a
preset's weight of 0 leaving its member out, and which weights files an output came from (``weights_used``)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from collections.abc import Iterator

import numpy as np
import pytest

from murk.enhance.declare import Checked, Method, Preset, opt
from murk.enhance.restorer import (
    Blend,
    Chain,
    Restored,
    Restorer,
    available,
    check,
    create,
    options_of,
    register,
    unregister,
    weights_used,
)


class Gain(Restorer):
    """Multiplies by ``gain``; with ``depth``, returns a constant depth map of that many metres."""

    def __init__(self, gain: float, depth: float = 0.0, name: str = "gain") -> None:
        self.gain, self.depth, self.name = gain, depth, name

    def restore(self, images: np.ndarray) -> Restored:
        depth = np.full(images.shape[:3], self.depth, np.float32) if self.depth else None
        return Restored((images * np.float32(self.gain)).astype(np.float32), depth)


def make_gain(o: Checked) -> Gain:
    return Gain(o.gain, o.depth)


GAIN = Method(
    "gain",
    make_gain,
    (opt("gain", "float", 0.5, "a gain", low=0, high=2), opt("depth", "float", 0.0, "metres of depth", low=0)),
    help="a gain (a toy method)",
)
MIX = Preset(
    "mix",
    "gain|colorbalance@share",
    (opt("share", "float", 0.25, "colorbalance's share", low=0, high=1),),
    help="a gain with the colour balance blended in (a toy preset)",
)


@pytest.fixture
def toys() -> Iterator[None]:
    register(GAIN)
    register(MIX)
    try:
        yield
    finally:
        unregister("gain")
        unregister("mix")


@pytest.fixture
def images() -> np.ndarray:
    return np.random.default_rng(0).uniform(0.1, 0.9, (2, 6, 7, 3)).astype(np.float32)


def test_a_blend_lerps_two_restorations_of_the_same_input(images: np.ndarray) -> None:
    a, b = Gain(0.5, name="a"), Gain(1.5, name="b")
    for w in (0.0, 0.25, 0.5, 0.75, 1.0):
        out = Blend(a, b, w).restore(images).images
        np.testing.assert_allclose(out, (1 - w) * 0.5 * images + w * 1.5 * images, rtol=1e-6)
    assert np.array_equal(Blend(a, b, 0.0).restore(images).images, a.restore(images).images)  # exact at both ends
    assert np.array_equal(Blend(a, b, 1.0).restore(images).images, b.restore(images).images)
    assert Blend(a, Chain([a, b]), 0.5).name == "a|(a+b)@0.5"
    for bad in (-0.1, 1.5, float("nan")):
        with pytest.raises(ValueError, match=r"weight: expected a number in \[0.0, 1.0\]"):
            Blend(a, b, bad)


def test_a_blend_keeps_the_depth_of_the_first_member_that_gives_one(images: np.ndarray) -> None:
    plain, near, far = Gain(1.0), Gain(1.0, depth=2.0), Gain(1.0, depth=5.0)
    assert Blend(plain, plain, 0.5).restore(images).depth_m is None
    for blend, metres in ((Blend(near, far, 0.9), 2.0), (Blend(plain, far, 0.1), 5.0)):
        depth = blend.restore(images).depth_m
        assert depth is not None and np.all(depth == metres)


def test_the_toy_method_blends_and_chains_through_the_registry(toys: None, images: np.ndarray) -> None:
    restorer = create("gain|colorbalance@0.25+gain?gain=1.5")  # the options reach every method declaring them
    assert isinstance(restorer, Chain) and isinstance(restorer.stages[0], Blend)
    assert restorer.name == "gain|colorbalance@0.25+gain"
    balanced = create("colorbalance").restore(images).images
    want = ((0.75 * 1.5 * images + 0.25 * balanced) * 1.5).astype(np.float32)
    np.testing.assert_allclose(restorer.restore(images).images, want, rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match=r"method: unknown 'gian' \(did you mean 'gain'\?\); available: .*'A\|B@W'"):
        check("gian|colorbalance@0.5")
    with pytest.raises(ValueError, match=r"option gain: expected a number in \[0.0, 2.0\], got 3.0"):
        check("colorbalance|gain@0.5?gain=3")
    with pytest.raises(ValueError, match=r"method 'gain\|@2': expected a method name after '\|'"):
        check("gain|@2")


def test_a_preset_takes_its_first_methods_options_and_names_what_it_builds(toys: None, images: np.ndarray) -> None:
    assert "mix" in available() and list(options_of("mix")) == ["gain", "depth", "share"]
    mix = create("mix?gain=1.5,share=0.5")
    assert isinstance(mix, Blend) and mix.name == "mix" and mix.weight_label == "share" and mix.weight == 0.5
    assert isinstance(mix.left, Gain) and mix.left.gain == 1.5
    alone = create("mix", gain=1.5, share=0)  # a weight of 0 leaves its member out: the first method itself
    assert isinstance(alone, Gain) and alone.name == "mix"
    assert np.array_equal(alone.restore(images).images, create("gain?gain=1.5").restore(images).images)
    with pytest.raises(ValueError, match=r"method mix: option share: expected a number in \[0.0, 1.0\], got 2.0"):
        check("mix?share=2")
    with pytest.raises(ValueError, match=r"unknown option 'low'; options of mix: depth, gain, share"):
        check("mix?low=2")  # colorbalance's options are not the preset's (passes: none)
    with pytest.raises(ValueError, match=r"options: the options of the preset bad are the weights its spec names"):
        Preset("bad", "gain|colorbalance@0.5", (opt("share", "float", 0.5, "x"),))
    with pytest.raises(ValueError, match=r"name: expected a non-empty name without white space or any of"):
        Preset("a@b", "gain")


def test_weights_used_walks_chains_and_blends() -> None:
    class Net(Gain):
        def __init__(self, name: str, weights: str) -> None:
            super().__init__(1.0, name=name)
            self.weights = weights

    big, small, other = Net("big", "big.pt"), Net("small", "small.pt"), Net("other", "other.pt")
    assert weights_used(Gain(1.0)).weights is None and weights_used(None).first is None
    used = weights_used(Chain([Gain(1.0), Blend(big, small, 0.3), other]))
    assert used.first is big and used.weights == "big.pt" and used.blended_weights == "small.pt"
    assert [blend.weight for _, blend in used.blended] == [0.3]
    nested = weights_used(Blend(Blend(Gain(1.0), big, 0.5), Chain([small, other]), 0.2))
    assert nested.weights == "big.pt" and nested.blended_weights == "small.pt; other.pt"


def test_a_blend_of_classical_methods_never_imports_torch() -> None:
    code = textwrap.dedent(
        """
        import sys
        import numpy as np
        from murk.enhance.restorer import create
        out = create("colorbalance|clahe@0.3+greyworld").restore(np.full((1, 8, 8, 3), 0.4, np.float32))
        assert out.images.shape == (1, 8, 8, 3) and out.images.dtype == np.float32
        print("torch" in sys.modules)
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
