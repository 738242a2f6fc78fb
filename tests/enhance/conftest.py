"""Fixtures for the enhance tests: a fake depth-estimating method (the MJPEG camera is in tests/conftest.py)."""

from __future__ import annotations

import pytest

from murk.enhance import restorer as restorer_mod

from ._enhance_helpers import FakeDepth


@pytest.fixture
def fake_depth_method(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, object]]:
    """Registers ``fakedepth`` for the test; returns the list of option dicts its factory received."""
    calls: list[dict[str, object]] = []

    def factory(**options: object) -> FakeDepth:
        calls.append(options)
        return FakeDepth()

    restorer_mod._load_builtin()
    monkeypatch.setitem(restorer_mod._REGISTRY, "fakedepth", factory)
    return calls
