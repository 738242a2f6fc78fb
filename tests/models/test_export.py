"""``murk.models.export.export_checkpoint``: the one entry point of ``murk export`` (Joint-ID, lite, baselines)."""

from __future__ import annotations

from pathlib import Path

import pytest
import torch

from murk.models import export as export_mod
from murk.models.export import ExportedModel, export_checkpoint
from murk.models.jointid import build_jointid, save_checkpoint

pytest.importorskip("onnxruntime")


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory: pytest.TempPathFactory) -> Path:
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("export") / "tiny.pt"
    save_checkpoint(build_jointid("tiny"), path, epoch=1)
    return path


def test_a_jointid_checkpoint_is_exported_and_verified_on_two_shapes(tiny_checkpoint: Path, tmp_path: Path) -> None:
    done = export_checkpoint(tiny_checkpoint, tmp_path / "tiny.onnx")
    assert isinstance(done, ExportedModel) and done.kind == "jointid" and done.fixed_size_hw is None
    assert done.path.is_file() and done.parameters == sum(p.numel() for p in build_jointid("tiny").parameters())
    assert [c.label for c in done.checks] == ["61x97", "96x64"]
    for check in done.checks:
        assert set(check.max_abs_diff) == {"depth_m", "enhanced"}
        assert max(check.max_abs_diff.values()) < export_mod.VERIFY_TOLERANCE
    assert export_checkpoint(tiny_checkpoint, tmp_path / "b.onnx", verify=False).checks == ()


def test_a_difference_above_the_tolerance_is_an_error_naming_the_file_and_shape(
    tiny_checkpoint: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import murk.models.jointid.onnx_export as jointid_onnx

    monkeypatch.setattr(jointid_onnx, "compare_onnx", lambda *a: {"depth_m": 0.5, "enhanced": 1e-7})
    out = tmp_path / "bad.onnx"
    with pytest.raises(ValueError, match=r"bad\.onnx: ONNX Runtime differs from torch by 0\.5 at 61x97"):
        export_checkpoint(tiny_checkpoint, out)


def test_bad_arguments_are_refused_before_anything_is_loaded(tmp_path: Path) -> None:
    missing = tmp_path / "none.pt"
    with pytest.raises(ValueError, match=r"expected a file name ending in \.onnx"):
        export_checkpoint(missing, tmp_path / "x.pt")
    with pytest.raises(ValueError, match="model: expected auto, udaformer, ursct"):
        export_checkpoint(missing, tmp_path / "x.onnx", model="unet")
    with pytest.raises(ValueError, match="exposure: applies to lite exports only, not to udaformer"):
        export_checkpoint(missing, tmp_path / "x.onnx", model="udaformer", exposure="network")
    top = export_mod.max_opset()
    assert 17 <= top < 1000  # the installed torch's exporter, read from torch (20 with torch 2.13)
    there = tmp_path / "there.pt"
    there.write_bytes(b"")  # not read: the opset is refused first
    with pytest.raises(ValueError, match=rf"opset: this torch exports opsets up to {top} .*, got {top + 1}$"):
        export_checkpoint(there, tmp_path / "x.onnx", opset=top + 1)  # was a traceback from inside torch


def test_exposure_is_refused_for_a_jointid_checkpoint(tiny_checkpoint: Path, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"exposure: applies to lite exports only, and .* is a Joint-ID checkpoint"):
        export_checkpoint(tiny_checkpoint, tmp_path / "x.onnx", exposure="network")
    assert not (tmp_path / "x.onnx").exists()
