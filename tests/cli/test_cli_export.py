"""``murk export``: checkpoint -> verified ONNX file; refusal of untrusted pickles."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from murk.cli.main import app
from murk.models.jointid import build_jointid, save_checkpoint

pytest.importorskip("onnxruntime")


class _Evil:
    def __reduce__(self):
        return (print, ("this must not run",))


@pytest.fixture(scope="module")
def tiny_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("export")
    torch.manual_seed(0)
    model = build_jointid("tiny")
    save_checkpoint(model, root / "tiny.pt", epoch=1)
    state = {f"structure.{k}": v for k, v in model.state_dict().items()}
    torch.save({"model": state, "extra": np.zeros(2), "hook": _Evil()}, root / "evil.pth")
    return root


def test_export_writes_a_verified_onnx_file(tiny_files):
    out = tiny_files / "tiny.onnx"
    result = CliRunner().invoke(app, ["export", "--checkpoint", str(tiny_files / "tiny.pt"), "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert out.is_file() and out.stat().st_size > 1_000_000
    assert str(out) in result.stdout
    assert "verified 61x97" in result.output and "verified 96x64" in result.output


def test_untrusted_pickles_are_refused_until_the_user_opts_in(tiny_files):
    args = ["export", "-c", str(tiny_files / "evil.pth"), "-o", str(tiny_files / "evil.onnx"), "--no-verify"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    assert "builtins.print" in result.output and "--trust-checkpoint" in result.output
    assert not (tiny_files / "evil.onnx").exists()
    result = CliRunner().invoke(app, [*args, "--trust-checkpoint", "--quiet"])
    assert result.exit_code == 0, result.output
    assert (tiny_files / "evil.onnx").is_file()


def test_bad_arguments_exit_with_code_2(tiny_files):
    result = CliRunner().invoke(app, ["export", "-c", str(tiny_files / "tiny.pt"), "-o", str(tiny_files / "x.pt")])
    assert result.exit_code == 2 and "expected a file name ending in .onnx" in result.output
    result = CliRunner().invoke(app, ["export", "-c", str(tiny_files / "none.pt"), "-o", str(tiny_files / "x.onnx")])
    assert result.exit_code == 2 and "checkpoint not found" in result.output


def test_a_trusted_legacy_lite_file_exports_for_murk_live(tmp_path):
    """murk live has no --trust-checkpoint: the refusal sends the user to murk export, which must then tell a
    trusted legacy lite file from a Joint-ID one (it said 'not a Joint-ID checkpoint'; issue 49)."""
    from murk.data import shipped_lite_weights

    legacy = tmp_path / "legacy_lite.pt"
    obj = torch.load(shipped_lite_weights(), weights_only=True)
    torch.save({**obj, "hook": _Evil()}, legacy)
    args = ["export", "-c", str(legacy), "-o", str(tmp_path / "lite.onnx"), "--no-verify", "--quiet"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2
    text = " ".join(result.output.split())
    assert "--trust-checkpoint" in text and "murk live has no such flag" in text and "murk export" in text
    result = CliRunner().invoke(app, [*args, "--trust-checkpoint"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "lite.onnx").is_file()
