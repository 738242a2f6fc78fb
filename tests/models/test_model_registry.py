"""The small model registry."""

from __future__ import annotations

import pytest

from murk.models import available_models, build_model, register_model
from murk.models.jointid import JointID


def test_jointid_is_registered_and_builds_by_name():
    assert "jointid" in available_models()
    model = build_model("jointid", variant="tiny")
    assert isinstance(model, JointID) and model.config.embed_dims == (16, 32, 64, 128)


def test_unknown_names_and_bad_builders_are_rejected():
    with pytest.raises(ValueError, match=r"unknown model 'nope'; available: .*jointid"):
        build_model("nope")
    with pytest.raises(ValueError, match=r"package\.module:function"):
        register_model("x", "no_colon")
    with pytest.raises(ValueError, match="non-empty"):
        register_model("", "a:b")
