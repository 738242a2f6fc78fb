"""Fixtures for the enhance tests: a fake depth-estimating method (the MJPEG camera is in tests/conftest.py)."""

from __future__ import annotations

import pytest

from murk.enhance import restorer as restorer_mod

from ._enhance_helpers import FakeDepth


@pytest.fixture
def fake_depth_method(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, object]]:
    """Registers ``fakedepth`` for the test; returns the list of option dicts its factory received."""
    calls: list[dict[str, object]] = []

    def factory(
        *,
        device: str = "cpu",
        batch: int = 1,
        he: str = "y",
        sigma_px: float = 1.0,
        lam: float = 0.3,
        clahe_clip: float = 2.0,
        clahe_tiles: int = 8,
        checkpoint: str | None = None,
        precision: str = "fp32",
        tile: int | None = None,
        overlap: int = 64,
        trust_checkpoint: bool = False,
        compile: bool = False,
        policy: str = "native",
    ) -> FakeDepth:
        calls.append({k: v for k, v in locals().items() if k != "calls"})
        return FakeDepth()

    restorer_mod._load_builtin()
    monkeypatch.setitem(restorer_mod._REGISTRY, "fakedepth", factory)
    return calls
