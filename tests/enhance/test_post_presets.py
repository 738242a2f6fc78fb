"""post presets: 'real' (murk's default) and 'paper' (Eq. 9 exactly); explicit settings override a preset."""

from __future__ import annotations

import numpy as np
import pytest

from murk.enhance import restorer as restorer_mod
from murk.enhance.equalize import equalize
from murk.enhance.post import POST_PRESETS, PostParams, post_process


def _murky(rng: np.random.Generator) -> np.ndarray:
    return (0.3 + 0.3 * rng.random((32, 40, 3))).astype(np.float32)


def test_paper_preset_is_eq9_as_written() -> None:
    assert POST_PRESETS["paper"] == PostParams() == PostParams(lam=0.3, he="y", he_strength=1.0)
    img = _murky(np.random.default_rng(0))
    out = restorer_mod.create("post?preset=paper")(img[None]).images[0]
    np.testing.assert_array_equal(out, post_process(img))


def test_default_is_the_real_preset_and_overrides_win() -> None:
    assert restorer_mod.create("post").params == POST_PRESETS["real"] == PostParams(lam=0.1, he_strength=0.3)
    assert restorer_mod.create("post?lam=0.2").params == PostParams(lam=0.2, he_strength=0.3)
    assert restorer_mod.create("post?preset=paper,he=clahe").params == PostParams(he="clahe")


def test_he_strength_blends_the_equalisation() -> None:
    img = _murky(np.random.default_rng(1))
    full = equalize(img)
    out = post_process(img, lam=0.0, he_strength=0.3)
    np.testing.assert_allclose(out, 0.3 * full + 0.7 * img, atol=1e-6)
    np.testing.assert_array_equal(post_process(img, lam=0.0, he_strength=0.0), np.clip(img, 0, 1))


def test_unknown_preset_and_bad_strength_are_refused() -> None:
    with pytest.raises(ValueError, match="preset"):
        restorer_mod.create("post?preset=vivid")
    with pytest.raises(ValueError, match="he_strength"):
        PostParams(he_strength=1.5)
