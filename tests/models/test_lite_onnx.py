"""The one-input ONNX export of ``lite``: the graph takes the frame as it is (any size, RGB in [0, 1]) and returns
what the torch restorer returns, at even and odd sizes, small frames (padded inside the graph) and large ones
(downsampled inside the graph), with the shipped weights on real images and with random ones; its size arithmetic
equals the Python code's; plain ONNX Runtime runs it at 640x480 and 1280x720."""

from __future__ import annotations

import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch

from murk.data import sample_underwater_images, shipped_lite_weights
from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.models.lite.checkpoint import load_lite, save_lite_checkpoint
from murk.models.lite.graph import LiteImageGraph, restore_reference
from murk.models.lite.network import build_lite, work_size, work_size_tensor

ort = pytest.importorskip("onnxruntime")
onnx = pytest.importorskip("onnx")

TOLERANCE = 1e-4
"""The issue's bound on max |ONNX Runtime - torch| (enhanced, [0, 1] units)."""


@pytest.fixture(scope="module")
def shipped_onnx(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from murk.models.lite.onnx_export import export_lite_onnx

    return export_lite_onnx(load_lite(shipped_lite_weights()), tmp_path_factory.mktemp("lite") / "lite.onnx")


def _session(path: Path) -> ort.InferenceSession:
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 2
    return ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])


def _real_frames(h: int, w: int, n: int = 2) -> np.ndarray:
    """``n`` shipped underwater images resized to h x w (INTER_AREA), (n, 3, h, w) float32 in [0, 1]."""
    frames = [cv2.resize(read_rgb(p), (w, h), interpolation=cv2.INTER_AREA) for p in sample_underwater_images()[:n]]
    return np.ascontiguousarray(np.clip(np.stack(frames), 0, 1).transpose(0, 3, 1, 2), dtype=np.float32)


def test_the_graph_takes_one_image_and_says_what_it_is(shipped_onnx: Path) -> None:
    model = onnx.load(str(shipped_onnx))
    (inp,) = model.graph.input
    (out,) = model.graph.output
    dims = [d.dim_param or d.dim_value for d in inp.type.tensor_type.shape.dim]
    assert inp.name == "image" and dims == ["batch", 3, "height", "width"]
    assert inp.type.tensor_type.elem_type == onnx.TensorProto.FLOAT and out.name == "enhanced"
    meta = {p.key: p.value for p in model.metadata_props}
    assert meta == {"murk.format": "murk.lite.image", "murk.work_area_px": "20480", "murk.exposure": "input"}
    assert [n.op_type for n in model.graph.node][-1] == "If"  # the restorer's two paths, chosen by the frame's area


@pytest.mark.parametrize("hw", [(64, 48), (97, 131), (480, 640)])
def test_onnx_runtime_equals_the_torch_restorer_on_real_images(shipped_onnx: Path, hw: tuple[int, int]) -> None:
    # 64x48 and 97x131 are their own working image (padded to multiples of 16 inside the graph: 97x131 on every
    # side); 480x640 is downsampled to 128x160 inside the graph. Reference: what `murk enhance --method lite`
    # computes (the torch restorer on the CPU, OpenCV upsampling), before any post-processing.
    frames = _real_frames(*hw)
    (got,) = _session(shipped_onnx).run(["enhanced"], {"image": frames})
    ref = create("lite").restore_tensor(torch.from_numpy(frames)).images.numpy()
    assert got.shape == frames.shape and got.dtype == np.float32
    assert np.abs(ref - frames).mean() > 0.01  # the restorer changes the frames: the comparison means something
    assert np.abs(got - ref).max() <= TOLERANCE


def test_onnx_runtime_runs_720p_and_matches(shipped_onnx: Path) -> None:
    frame = _real_frames(720, 1280, n=1)
    (got,) = _session(shipped_onnx).run(["enhanced"], {"image": frame})
    ref = create("lite").restore_tensor(torch.from_numpy(frame)).images.numpy()
    assert got.shape == (1, 3, 720, 1280) and 0.0 <= got.min() and got.max() <= 1.0
    assert np.abs(got - ref).max() <= TOLERANCE


@pytest.mark.parametrize(
    "hw",
    [(1, 1), (5, 7), (16, 16), (160, 128), (161, 128), (150, 211), (2, 12000), (12000, 2), (60, 768), (243, 960)],
    ids=lambda hw: f"{hw[0]}x{hw[1]}",
)
def test_edge_sizes_follow_the_restorer(shipped_onnx: Path, hw: tuple[int, int]) -> None:
    # 1x1 and 5x7: padding larger than the frame (repeated reflection, a replicated single row); 160x128 has
    # exactly the working area's pixels (native), 161x128 one row more (downsampled, windows of two sizes);
    # 2x12000: a working image taller than the frame (each row repeated); 60x768 and 243x960: exact ties of the
    # working size's rounding (TIES).
    x = _real_frames(*hw)
    (got,) = _session(shipped_onnx).run(["enhanced"], {"image": x})
    ref = create("lite").restore_tensor(torch.from_numpy(x)).images.numpy()
    assert np.abs(got - ref).max() <= TOLERANCE


def test_the_traced_module_equals_the_plain_reference_eagerly() -> None:
    net = load_lite(shipped_lite_weights())
    graph = LiteImageGraph(net).eval()
    for hw in ((37, 53), (161, 128), (333, 517)):
        x = torch.rand(1, 3, *hw, generator=torch.Generator().manual_seed(hw[1]))
        with torch.inference_mode():
            assert (graph(x) - restore_reference(net, x)).abs().max().item() <= 2e-5


TIES = [(60, 768), (70, 896), (120, 1536), (192, 1215), (243, 960), (1125, 1600), (1920, 486), (3968, 2790)]
"""Frame sizes whose working size is an exact tie before rounding (60x768: 60 * sqrt(20480 / 46080) / 16 = 2.5):
a graph that divided as 1 / x * a (torch's scalar / tensor) rounded 40 of the sizes up to 4096x4096 the other
way; with a true division all 16.6 M sizes up to 4096x4096 agree (checked once, 2026-12-03)."""


def test_the_graph_computes_the_working_size_as_python_does() -> None:
    # A grid of frame sizes, large ones and the exact ties: the float64 tensor arithmetic of the graph (sqrt,
    # round half to even) gives work_size's sizes (Python's ** 0.5 and round).
    area = 128 * 160
    sizes = [(h, w) for h in range(1, 1101, 3) for w in range(1, 1101, 7) if h * w > area]
    sizes += [(h, w) for h in (720, 1080, 2160, 4001) for w in range(1000, 8000, 13)] + TIES
    h = torch.tensor([s[0] for s in sizes])
    w = torch.tensor([s[1] for s in sizes])
    hw, ww = work_size_tensor(h, w, area)
    assert [(int(a), int(b)) for a, b in zip(hw, ww, strict=True)] == [work_size(*s, area) for s in sizes]


def test_a_network_without_working_area_exports_one_path(tmp_path: Path) -> None:
    from murk.models.lite.onnx_export import OnnxLite, export_lite_onnx

    torch.manual_seed(1)
    net = build_lite("tiny", work_area_px=0)
    with torch.no_grad():
        net.head.weight.normal_(std=0.3)
    ckpt = save_lite_checkpoint(net, tmp_path / "native.pt")
    path = export_lite_onnx(load_lite(ckpt), tmp_path / "native.onnx")
    assert "If" not in {n.op_type for n in onnx.load(str(path)).graph.node}
    runner = OnnxLite(path, threads=1)
    assert runner.work_area_px == 0
    restorer = create("lite", checkpoint=str(ckpt))
    for hw in ((37, 53), (200, 300)):
        x = torch.rand(1, 3, *hw, generator=torch.Generator().manual_seed(2))
        assert (runner(x) - restorer.restore_tensor(x).images).abs().max().item() <= TOLERANCE


def test_export_command_writes_the_one_input_graph(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from murk.cli.main import app

    out = tmp_path / "lite.onnx"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        result = CliRunner().invoke(app, ["export", "-c", str(shipped_lite_weights()), "-o", str(out)])
    assert result.exit_code == 0, result.output
    for label in ("64x48", "97x131", "192x320", "480x640"):
        assert f"verified {label}" in result.output
    frame = _real_frames(97, 131, n=1)
    (got,) = _session(out).run(None, {"image": frame})  # one input, nothing else to make
    assert got.shape == frame.shape


def test_export_command_records_the_exposure_asked_for(tmp_path: Path) -> None:
    from typer.testing import CliRunner

    from murk.cli.main import app

    out = tmp_path / "own.onnx"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        args = ["export", "-c", str(shipped_lite_weights()), "-o", str(out), "--exposure", "network", "--no-verify"]
        result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert {p.key: p.value for p in onnx.load(str(out)).metadata_props}["murk.exposure"] == "network"
    frame = _real_frames(97, 131, n=1).transpose(0, 2, 3, 1)
    got = create("lite", checkpoint=str(out)).restore(frame).images
    want = create("lite", exposure="network").restore(frame).images
    np.testing.assert_allclose(got, want, atol=1e-4)
