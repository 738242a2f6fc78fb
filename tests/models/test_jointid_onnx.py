"""ONNX export (tiny variant): dynamic sizes, equal to torch under ONNX Runtime; the runner's checks."""

from __future__ import annotations

import pytest
import torch

pytest.importorskip("onnxruntime")

from murk.errors import InputFileError
from murk.models.jointid import JointID, build_jointid, normalize_input
from murk.models.jointid.onnx_export import OnnxJointID, compare_onnx, export_onnx


@pytest.fixture(scope="module")
def tiny() -> JointID:
    torch.manual_seed(0)
    return build_jointid("tiny").eval()


@pytest.fixture(scope="module")
def onnx_file(tmp_path_factory, tiny):
    return export_onnx(tiny, tmp_path_factory.mktemp("onnx") / "tiny.onnx")


@pytest.mark.parametrize("shape", [(1, 3, 64, 96), (2, 3, 96, 64), (1, 3, 32, 160)])
def test_onnx_runtime_matches_torch_on_dynamic_sizes(tiny, onnx_file, shape):
    runner = OnnxJointID(onnx_file, threads=1)
    x = normalize_input(torch.rand(shape, generator=torch.Generator().manual_seed(sum(shape))))
    diff = compare_onnx(tiny, runner, x)
    depth, enhanced = runner(x)
    assert depth.shape == (shape[0], 1, *shape[2:]) and enhanced.shape == shape
    assert diff["depth_m"] < 1e-4 and diff["enhanced"] < 1e-5


def test_export_writes_atomically_and_validates_arguments(tmp_path, tiny):
    with pytest.raises(ValueError, match="opset: expected >= 14"):
        export_onnx(tiny, tmp_path / "a.onnx", opset=13)
    with pytest.raises(ValueError, match="sample_size"):
        export_onnx(tiny, tmp_path / "a.onnx", sample_size=(48, 64))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.filterwarnings("ignore::DeprecationWarning")
def test_runner_rejects_missing_and_foreign_files(tmp_path):
    with pytest.raises(InputFileError, match="ONNX model not found"):
        OnnxJointID(tmp_path / "none.onnx")
    (tmp_path / "junk.onnx").write_bytes(b"junk")
    with pytest.raises(InputFileError, match="not a loadable ONNX model"):
        OnnxJointID(tmp_path / "junk.onnx")
    other = tmp_path / "conv.onnx"
    torch.onnx.export(torch.nn.Conv2d(3, 3, 1), (torch.zeros(1, 3, 8, 8),), str(other), dynamo=False)
    with pytest.raises(InputFileError, match="not a murk Joint-ID export"):
        OnnxJointID(other)


def test_export_leaves_a_training_model_untouched(tmp_path, tiny):
    tiny.train()
    try:
        export_onnx(tiny, tmp_path / "t.onnx")
        assert tiny.training  # exported from an eval-mode copy
    finally:
        tiny.eval()
    assert (tmp_path / "t.onnx").is_file()
