"""ONNX export (tiny variant): one input (the frame in [0, 1], any size), equal to torch under ONNX Runtime; the
runner's checks."""

from __future__ import annotations

import warnings

import pytest
import torch

pytest.importorskip("onnxruntime")

from murk.errors import InputFileError
from murk.models.jointid import JointID, build_jointid
from murk.models.jointid.onnx_export import JointIDImageGraph, OnnxJointID, compare_onnx, export_onnx, restore_reference


@pytest.fixture(scope="module")
def tiny() -> JointID:
    torch.manual_seed(0)
    return build_jointid("tiny").eval()


@pytest.fixture(scope="module")
def onnx_file(tmp_path_factory, tiny):
    return export_onnx(tiny, tmp_path_factory.mktemp("onnx") / "tiny.onnx")


@pytest.mark.parametrize("shape", [(1, 3, 64, 96), (2, 3, 96, 64), (1, 3, 32, 160), (1, 3, 61, 97), (2, 3, 5, 7)])
def test_onnx_runtime_matches_torch_on_dynamic_sizes(tiny, onnx_file, shape):
    # Frames of any size: 61x97 and 5x7 are reflect-padded to multiples of 32 inside the graph (5x7: repeatedly).
    runner = OnnxJointID(onnx_file, threads=1)
    x = torch.rand(shape, generator=torch.Generator().manual_seed(sum(shape)))
    diff = compare_onnx(tiny, runner, x)
    depth, enhanced = runner(x)
    assert depth.shape == (shape[0], 1, *shape[2:]) and enhanced.shape == shape
    assert diff["depth_m"] < 1e-4 and diff["enhanced"] < 1e-5
    with torch.inference_mode():  # the traced module itself, eagerly, against the plain reference
        for got, ref in zip(JointIDImageGraph(tiny)(x), restore_reference(tiny, x), strict=True):
            assert (got - ref).abs().max().item() < 1e-5


def test_export_writes_atomically_and_validates_arguments(tmp_path, tiny):
    with pytest.raises(ValueError, match="opset: expected >= 14"):
        export_onnx(tiny, tmp_path / "a.onnx", opset=13)
    with pytest.raises(ValueError, match="sample_size"):
        export_onnx(tiny, tmp_path / "a.onnx", sample_size=(0, 64))
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


def test_an_export_of_an_earlier_murk_is_refused_with_what_to_do(tmp_path, tiny):
    class Plain(torch.nn.Module):  # the earlier graph: the network's forward on a normalised batch
        def __init__(self):
            super().__init__()
            self.net = tiny

        def forward(self, x):
            out = self.net(x)
            return out.depth_m, out.enhanced

    old = tmp_path / "old.onnx"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(Plain().eval(), (torch.zeros(1, 3, 64, 64),), str(old), dynamo=False, input_names=["image"],
                          output_names=["depth_m", "enhanced"])  # fmt: skip
    with pytest.raises(InputFileError, match=r"earlier murk \(a normalised input.*export it again"):
        OnnxJointID(old)


def test_export_leaves_a_training_model_untouched(tmp_path, tiny):
    tiny.train()
    try:
        export_onnx(tiny, tmp_path / "t.onnx")
        assert tiny.training  # exported from an eval-mode copy
    finally:
        tiny.eval()
    assert (tmp_path / "t.onnx").is_file()


def test_a_network_with_the_global_colour_head_exports_and_matches(tmp_path):
    from dataclasses import replace

    from murk.models.jointid import VARIANTS

    torch.manual_seed(1)
    model = build_jointid(replace(VARIANTS["tiny"], global_colour=True)).eval()
    head = model.global_colour_head
    assert head is not None
    with torch.no_grad():  # a head that is not the identity
        head.fc2.weight.normal_(0.0, 0.05)
        head.fc2.bias.copy_(torch.tensor([0.2, -0.1, 0.0, 0.3, 0.0, -0.2]))
    runner = OnnxJointID(export_onnx(model, tmp_path / "gc.onnx"), threads=1)
    for shape in [(1, 3, 64, 96), (1, 3, 61, 97)]:
        diff = compare_onnx(model, runner, torch.rand(shape, generator=torch.Generator().manual_seed(7)))
        assert diff["depth_m"] < 1e-4 and diff["enhanced"] < 1e-5, diff
