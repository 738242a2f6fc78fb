"""``murk export --model udaformer|ursct``: fixed-size ONNX graphs of the full-size baselines (one RGB input in
[0, 1], the restored RGB frame out, as the restorers' native policy), verified with ONNX Runtime at batch 1 and 2;
the untrusted official UDAformer file is refused."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from murk.cli.main import app
from murk.enhance.baseline import BaselineRestorer
from murk.enhance.udaformer_restorer import UDAFORMER
from murk.enhance.ursct_restorer import URSCT_SESR
from murk.models.baseline_onnx import export_baseline_onnx
from murk.models.udaformer import UDAformer
from murk.models.ursct_sesr import URSCT, URSCTConfig

ort = pytest.importorskip("onnxruntime")
runner = CliRunner()


def test_export_udaformer_fixed_size(tmp_path):
    torch.manual_seed(0)
    model = UDAformer().eval()
    torch.save({"model": model.state_dict(), "optimizer": torch.optim.Adam(model.parameters())}, tmp_path / "u.pkl")
    args = ["export", "-c", str(tmp_path / "u.pkl"), "-o", str(tmp_path / "u.onnx"), "--model", "udaformer"]
    refused = runner.invoke(app, [*args, "--size", "40x24"])
    assert refused.exit_code == 2 and "--trust-checkpoint" in refused.output
    res = runner.invoke(app, [*args, "--size", "37x21", "--trust-checkpoint"])
    assert res.exit_code == 0, res.output
    assert "fixed 37x21" in res.output and "verified batch 2" in res.output
    session = ort.InferenceSession(str(tmp_path / "u.onnx"), providers=["CPUExecutionProvider"])
    x = torch.rand(3, 3, 21, 37, generator=torch.Generator().manual_seed(1))
    (y,) = session.run(None, {"image": x.numpy()})  # RGB in; padded to 40x24 and BGR inside the graph
    ref = BaselineRestorer(UDAFORMER, model).restore_tensor(x).images
    np.testing.assert_allclose(y, ref.numpy(), rtol=0, atol=1e-4)


@pytest.mark.slow
def test_export_full_size_ursct_fixed_size(tmp_path):
    torch.save({"state_dict": URSCT().state_dict()}, tmp_path / "s.pth")
    args = ["export", "-c", str(tmp_path / "s.pth"), "-o", str(tmp_path / "s.onnx"), "--model", "ursct"]
    res = runner.invoke(app, [*args, "--size", "128x128"])
    assert res.exit_code == 0, res.output
    assert "fixed 128x128" in res.output and (tmp_path / "s.onnx").is_file()


def test_export_reduced_ursct_and_bad_sizes(tmp_path):
    torch.manual_seed(0)
    small = URSCT(URSCTConfig(img_size=128, embed_dim=8, depths=(2, 1, 1, 1))).eval()
    done = export_baseline_onnx(small, tmp_path / "small.onnx", size_hw=(128, 128))
    assert done.size_hw == (128, 128) and set(done.max_abs_diff) == {1, 2}
    assert max(done.max_abs_diff.values()) < 1e-4
    session = ort.InferenceSession(str(done.path), providers=["CPUExecutionProvider"])
    x = torch.rand(1, 3, 128, 128, generator=torch.Generator().manual_seed(2))
    (y,) = session.run(None, {"image": x.numpy()})
    ref = BaselineRestorer(URSCT_SESR, small, tile=128).restore_tensor(x).images  # one tile: the whole frame
    np.testing.assert_allclose(y, ref.numpy(), rtol=0, atol=1e-4)
    with pytest.raises(ValueError, match="square size that is a multiple of 128"):
        export_baseline_onnx(small, tmp_path / "x.onnx", size_hw=(128, 256))
    with pytest.raises(TypeError, match="UDAformer or a URSCT"):
        export_baseline_onnx(torch.nn.Identity(), tmp_path / "x.onnx")
    torch.save({"state_dict": small.state_dict()}, tmp_path / "s.pth")
    args = ["export", "-c", str(tmp_path / "s.pth"), "-o", str(tmp_path / "s.onnx")]
    bad = runner.invoke(app, [*args, "--model", "ursct", "--size", "256x128"])
    assert bad.exit_code == 2 and "square size that is a multiple of 128" in bad.output
    bad = runner.invoke(app, [*args, "--model", "resnet"])
    assert bad.exit_code == 2 and "--model: expected auto, udaformer or ursct" in bad.output
