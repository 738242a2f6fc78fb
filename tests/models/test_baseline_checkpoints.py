"""Loading the baselines' official checkpoint layouts (fake files built here from the fixtures' names and shapes):
UDAformer's {'model', pickled Adam optimiser, 'epoch'} is refused without --trust-checkpoint and loads with it;
URSCT-SESR's {'state_dict' (+ 'module.' prefix, + size-dependent buffers), 'epoch', 'PSNR', 'SSIM'} loads
with weights_only=True; bare state dicts load; wrong files are reported with their path."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

from murk.errors import InputFileError
from murk.models.udaformer import load_udaformer, read_udaformer_state, save_weights_only
from murk.models.ursct_sesr import URSCTConfig, load_ursct, read_ursct_state
from murk.models.ursct_sesr.network import relative_position_index


def _entries(tests_data: Path, name: str) -> list[tuple[str, list[int], str]]:
    return [tuple(e) for e in json.loads((tests_data / name).read_text())["entries"]]


def _marked_state(entries, prefix: str = "") -> dict[str, torch.Tensor]:
    """Every fixture key with a tensor of its shape holding its index (a marker to check where it lands)."""
    return {prefix + k: torch.full(shape, float(i)) for i, (k, shape, _) in enumerate(entries)}


@pytest.fixture(scope="module")
def uda_entries(tests_data):
    return _entries(tests_data, "udaformer_state_dict.json")


@pytest.fixture(scope="module")
def ursct_entries(tests_data):
    return _entries(tests_data, "ursct_sesr_state_dict.json")


def _check_markers(model: torch.nn.Module, entries, skip=()) -> None:
    own = model.state_dict()
    for i, (k, _, _) in enumerate(entries):
        if not k.endswith(skip):
            assert float(own[k].flatten()[0]) == float(i), k


def test_official_udaformer_file_is_refused_then_loads_when_trusted(tmp_path, uda_entries):
    state = _marked_state(uda_entries)
    optimiser = torch.optim.Adam([torch.nn.Parameter(torch.zeros(2))], lr=1e-4)
    path = tmp_path / "checkpoint_489_epoch.pkl"
    torch.save({"model": state, "optimizer": optimiser, "epoch": 489}, path)
    with pytest.raises(
        InputFileError, match=r"checkpoint_489_epoch\.pkl.*torch\.optim\.adam\.Adam.*--trust-checkpoint"
    ):
        load_udaformer(path)
    with pytest.raises(InputFileError, match=r"pickles its Adam optimiser object"):
        read_udaformer_state(path)
    model = load_udaformer(path, trust=True)
    assert not model.training and next(model.parameters()).dtype == torch.float32
    _check_markers(model, uda_entries)
    # a weights-only copy loads without trust, with the same weights
    safe = save_weights_only(path, tmp_path / "uda_weights.pt", trust=True)
    assert torch.serialization.get_unsafe_globals_in_checkpoint(safe) == []
    _check_markers(load_udaformer(safe), uda_entries)


@pytest.mark.parametrize("layout", ["state_dict", "bare_module_prefix", "model_half"])
def test_other_udaformer_layouts_load_with_weights_only(tmp_path, uda_entries, layout):
    state = _marked_state(uda_entries, "module." if layout == "bare_module_prefix" else "")
    obj = {"state_dict": state, "epoch": 3} if layout == "state_dict" else state
    if layout == "model_half":
        obj = {"model": {k: v.half() for k, v in state.items()}}
    torch.save(obj, tmp_path / "w.pt")
    _check_markers(load_udaformer(tmp_path / "w.pt"), uda_entries)


def test_official_ursct_file_loads_with_weights_only(tmp_path, ursct_entries):
    """DataParallel prefix, the 84 buffers of IMG_SIZE 256 and the training metadata: all handled; the
    learnable tensors load strictly, into a model for another size too (buffers are rebuilt)."""
    state = _marked_state(ursct_entries, "module.")
    index = relative_position_index()
    for k in state:
        if k.endswith("relative_position_index"):
            state[k] = index.clone()
    path = tmp_path / "model_bestSSIM.pth"
    torch.save({"epoch": 700, "state_dict": state, "PSNR": 23.1, "SSIM": 0.91, "optimizer": {"lr": 5e-4}}, path)
    assert len(read_ursct_state(path)) == 899
    model = load_ursct(path)
    _check_markers(model, ursct_entries, skip=("relative_position_index", "attn_mask"))
    assert model.config == URSCTConfig() and not model.training
    other = load_ursct(path, img_size=512)
    assert other.layers[0].blocks[1].attn_mask.shape == (1024, 64, 64)
    _check_markers(other, ursct_entries, skip=("relative_position_index", "attn_mask"))


def test_wrong_files_are_reported_with_the_path(tmp_path, uda_entries, ursct_entries):
    uda = _marked_state(uda_entries)
    uda.pop("output.weight")
    torch.save({"model": uda}, tmp_path / "missing.pt")
    with pytest.raises(
        InputFileError, match=r"missing\.pt.*not a UDAformer checkpoint: 1 missing keys \(e\.g\. output"
    ):
        load_udaformer(tmp_path / "missing.pt")
    torch.save({"model": _marked_state(ursct_entries)}, tmp_path / "ursct_as_uda.pt")
    with pytest.raises(InputFileError, match="not a UDAformer checkpoint"):
        load_udaformer(tmp_path / "ursct_as_uda.pt")
    bad = _marked_state(ursct_entries)
    key = next(k for k in bad if k.endswith("relative_position_index"))
    torch.save({"state_dict": bad}, tmp_path / "bad_index.pth")
    with pytest.raises(InputFileError, match=rf"{key}: not the 8x8-window index"):
        load_ursct(tmp_path / "bad_index.pth")
    good = {k: v for k, v in _marked_state(ursct_entries).items() if not k.endswith("relative_position_index")}
    good["layers.0.blocks.0.mlp.fc1.weight"] = torch.zeros(3, 3)
    torch.save(good, tmp_path / "shape.pth")
    with pytest.raises(InputFileError, match=r"shape\.pth.*1 shape mismatches \(e\.g\. layers\.0\.blocks\.0\.mlp\.fc1"):
        load_ursct(tmp_path / "shape.pth")
    torch.save({"epoch": 1}, tmp_path / "empty.pth")
    with pytest.raises(InputFileError, match=r"expected a dict with 'state_dict' or 'model'"):
        load_ursct(tmp_path / "empty.pth")
    (tmp_path / "junk.pth").write_bytes(b"not a checkpoint")
    with pytest.raises(InputFileError, match="not a readable PyTorch checkpoint"):
        load_ursct(tmp_path / "junk.pth")
    with pytest.raises(InputFileError, match="checkpoint not found"):
        load_udaformer(tmp_path / "nope.pkl")
