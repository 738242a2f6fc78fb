"""Every numpy/torch twin pair gives the same result within the one tolerance table of tests/twins.py."""

from __future__ import annotations

import numpy as np
import pytest

from .twins import TWINS


@pytest.mark.parametrize("name", sorted(TWINS))
def test_numpy_and_torch_twins_agree(name: str) -> None:
    twin = TWINS[name]
    inputs = twin.inputs(np.random.default_rng(20240531))
    want, got = twin.numpy(inputs), twin.torch(inputs)
    assert set(got) == set(want) and want
    for key in want:
        assert got[key].shape == want[key].shape, key
        np.testing.assert_allclose(got[key], want[key], atol=twin.atol, rtol=twin.rtol, err_msg=f"{name}: {key}")
