"""Checkpoint I/O: murk's format, the official format (with its pickled numpy array), refusal of other pickles."""

from __future__ import annotations

import json
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from murk.errors import InputFileError
from murk.models.jointid import (
    JointID,
    build_jointid,
    load_checkpoint,
    normalize_input,
    read_checkpoint,
    save_checkpoint,
)


@pytest.fixture(scope="module")
def tiny() -> JointID:
    torch.manual_seed(0)
    return build_jointid("tiny").eval()


def _same_weights(a: torch.nn.Module, b: torch.nn.Module) -> bool:
    sa, sb = a.state_dict(), b.state_dict()
    return sa.keys() == sb.keys() and all(torch.equal(sa[k], sb[k]) for k in sa)


def _official_file(path: Path, model: JointID, **extra) -> Path:
    """The official layout: {'model': state dict with 'structure.' keys, ...} plus a pickled numpy array."""
    state = {f"structure.{k}": v for k, v in model.state_dict().items()}
    torch.save({"model": state, "best_metrics": np.array([0.25, 7.5]), "epoch": 4, **extra}, path)
    return path


class _Evil:
    def __reduce__(self):
        return (print, ("this must not run",))


def test_murk_checkpoint_round_trip(tmp_path, tiny):
    path = save_checkpoint(tiny, tmp_path / "sub" / "tiny.pt", epoch=3, loss=0.5, tags=["a", "b"])
    assert path.is_file()
    assert [p.name for p in path.parent.iterdir()] == ["tiny.pt"]  # no temporary file left
    model = load_checkpoint(path)
    assert _same_weights(model, tiny) and not model.training
    state, info = read_checkpoint(path)
    assert state.keys() == tiny.state_dict().keys()
    assert info.source == "murk" and info.variant == "tiny" and info.config == tiny.config
    assert info.meta == {"epoch": 3, "loss": 0.5, "tags": ["a", "b"]}
    raw = torch.load(path, weights_only=True)  # murk's own files need no allow-listing at all
    assert raw["format"] == "murk.jointid" and raw["variant"] == "tiny"


def test_save_unwraps_ddp_like_and_compiled_wrappers(tmp_path, tiny):
    class Wrapper(torch.nn.Module):
        def __init__(self, module):
            super().__init__()
            self.module = module

    save_checkpoint(Wrapper(tiny), tmp_path / "w.pt")
    assert _same_weights(load_checkpoint(tmp_path / "w.pt"), tiny)
    with pytest.raises(TypeError, match="expected a JointID"):
        save_checkpoint(torch.nn.Linear(2, 2), tmp_path / "x.pt")


def test_save_rejects_metadata_that_weights_only_cannot_load(tmp_path, tiny):
    with pytest.raises(TypeError, match=r"meta\['obj'\].*weights_only-safe"):
        save_checkpoint(tiny, tmp_path / "m.pt", obj=object())
    assert not (tmp_path / "m.pt").exists()


def test_official_format_with_numpy_array_loads_with_weights_only(tmp_path, tiny):
    path = _official_file(tmp_path / "joint_id_ckpt.pth", tiny)
    with pytest.raises(Exception, match="numpy"):  # plain weights_only refuses the numpy array ...
        torch.load(path, weights_only=True)
    model = load_checkpoint(path)  # ... load_checkpoint allows exactly the numpy array globals
    assert _same_weights(model, tiny)
    _, info = read_checkpoint(path)
    assert info.source == "official" and info.meta == {"epoch": 4}


def test_official_format_written_by_numpy_1_loads(tmp_path, tiny):
    # numpy 1.x pickles arrays as numpy.core.multiarray._reconstruct (numpy 2: numpy._core...): rewrite the
    # pickle's GLOBAL opcode (torch.save uses protocol 2, newline-terminated names) to that spelling.
    src = _official_file(tmp_path / "new.pth", tiny)
    dst = tmp_path / "old.pth"
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_STORED) as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename.endswith("data.pkl"):
                assert b"numpy._core.multiarray\n" in data
                data = data.replace(b"numpy._core.multiarray\n", b"numpy.core.multiarray\n")
            zout.writestr(item, data)
    assert "numpy.core.multiarray._reconstruct" in torch.serialization.get_unsafe_globals_in_checkpoint(dst)
    assert _same_weights(load_checkpoint(dst), tiny)


def test_other_pickled_objects_are_refused_unless_trusted(tmp_path, tiny, capsys):
    path = _official_file(tmp_path / "evil.pth", tiny, payload=_Evil())
    with pytest.raises(InputFileError, match=r"evil\.pth: refusing.*builtins\.print.*--trust-checkpoint"):
        load_checkpoint(path)
    assert "this must not run" not in capsys.readouterr().out
    model = load_checkpoint(path, trust=True)  # the user's explicit opt-in
    assert _same_weights(model, tiny)
    assert "this must not run" in capsys.readouterr().out  # (proof that trust=True really unpickles)


def test_bare_state_dicts_load_with_and_without_prefix(tmp_path, tiny):
    torch.save(tiny.state_dict(), tmp_path / "plain.pth")
    torch.save({f"structure.{k}": v for k, v in tiny.state_dict().items()}, tmp_path / "prefixed.pth")
    assert _same_weights(load_checkpoint(tmp_path / "plain.pth"), tiny)
    assert _same_weights(load_checkpoint(tmp_path / "prefixed.pth"), tiny)


def test_mismatching_weights_are_reported_with_the_file(tmp_path, tiny):
    state = {f"structure.{k}": v for k, v in tiny.state_dict().items()}
    missing = dict(state)
    missing.pop("structure.depth_structure.decoder.linear_pred1.weight")
    torch.save({"model": missing}, tmp_path / "missing.pth")
    with pytest.raises(InputFileError, match=r"missing\.pth: not a Joint-ID \(tiny\) checkpoint: 1 missing keys"):
        load_checkpoint(tmp_path / "missing.pth")
    bad = dict(state)
    bad["structure.depth_structure.decoder.linear_pred1.bias"] = torch.zeros(2)
    bad["structure.extra.weight"] = torch.zeros(1)
    torch.save({"model": bad}, tmp_path / "bad.pth")
    with pytest.raises(InputFileError, match=r"1 unexpected keys.*1 shape mismatches"):
        load_checkpoint(tmp_path / "bad.pth")


def test_unreadable_files_are_reported(tmp_path):
    with pytest.raises(InputFileError, match=r"nope\.pt: checkpoint not found"):
        load_checkpoint(tmp_path / "nope.pt")
    (tmp_path / "junk.pt").write_bytes(b"definitely not a checkpoint")
    with pytest.raises(InputFileError, match=r"junk\.pt: not a"):
        load_checkpoint(tmp_path / "junk.pt")
    torch.save({"weights": [1, 2]}, tmp_path / "other.pt")
    with pytest.raises(InputFileError, match="not a Joint-ID checkpoint"):
        load_checkpoint(tmp_path / "other.pt")


def test_unknown_murk_format_version_is_refused(tmp_path, tiny):
    path = save_checkpoint(tiny, tmp_path / "v.pt")
    obj = torch.load(path, weights_only=True)
    obj["format_version"] = 99
    torch.save(obj, path)
    with pytest.raises(InputFileError, match="format_version 99"):
        load_checkpoint(path)


@pytest.mark.slow
def test_full_size_official_format_file_loads(tmp_path, tests_data):
    # The whole official layout at full size (600 MB on disk): fixture names and shapes, numpy array included.
    entries = json.loads((tests_data / "jointid_state_dict.json").read_text())["entries"]
    state = {k: torch.full(shape, float(i % 97)) for i, (k, shape, _) in enumerate(entries)}
    torch.save({"model": state, "best": np.zeros(3)}, tmp_path / "joint_id_ckpt.pth")
    model = load_checkpoint(tmp_path / "joint_id_ckpt.pth")
    assert sum(p.numel() for p in model.parameters()) == 150_248_900
    own = model.state_dict()
    assert all(
        float(own[k.removeprefix("structure.")].flatten()[0]) == float(i % 97) for i, (k, _, _) in enumerate(entries)
    )


def test_slim_checkpoint_halves_and_reloads(tmp_path: Path) -> None:
    """fp16 distribution copy: smaller, loads with weights_only, same outputs to fp16 precision, no optimiser."""
    from murk.models.jointid import slim_checkpoint

    torch.manual_seed(0)
    model = build_jointid("small").eval()
    opt = torch.optim.AdamW(model.parameters())
    full = save_checkpoint(model, tmp_path / "full.pt", step=3, optimizer=opt.state_dict())
    slim = slim_checkpoint(full, tmp_path / "slim.pt", trained_by="test", steps=3)
    assert slim.stat().st_size < 0.6 * full.stat().st_size
    obj = torch.load(slim, weights_only=True)
    assert obj["meta"] == {"trained_by": "test", "steps": 3}
    assert all(v.dtype == torch.float16 for v in obj["state_dict"].values() if v.is_floating_point())
    back = load_checkpoint(slim)
    assert next(back.parameters()).dtype == torch.float32
    x = normalize_input(torch.rand(1, 3, 64, 64, generator=torch.Generator().manual_seed(1)))
    with torch.no_grad():
        torch.testing.assert_close(back(x).enhanced, model(x).enhanced, atol=5e-3, rtol=0)


def test_average_checkpoints_is_the_weighted_mean_of_the_weights(tmp_path: Path) -> None:
    """The model soup the shipped weights were made with: float32 weighted mean, saved slim, balance kept."""
    from murk.models.jointid import average_checkpoints

    nets = []
    for seed in (0, 1):
        torch.manual_seed(seed)
        net = build_jointid("tiny").eval()
        net.input_balance_pct = 1.0
        nets.append(net)
    a = save_checkpoint(nets[0], tmp_path / "a.pt", step=1)
    b = save_checkpoint(nets[1], tmp_path / "b.pt", step=2)
    out = average_checkpoints([a, b], tmp_path / "soup.pt", weights=[0.25, 0.75], dtype=torch.float32, made_by="test")
    soup = load_checkpoint(out)
    assert soup.input_balance_pct == 1.0
    assert torch.load(out, weights_only=True)["meta"]["made_by"] == "test"
    sa, sb, ss = nets[0].state_dict(), nets[1].state_dict(), soup.state_dict()
    for k, v in ss.items():
        if v.is_floating_point():
            torch.testing.assert_close(v, 0.25 * sa[k] + 0.75 * sb[k], atol=1e-7, rtol=1e-6)
        else:
            assert torch.equal(v, sa[k])
    half = load_checkpoint(average_checkpoints([a, b], tmp_path / "half.pt"))  # equal weights, fp16 on disk
    k = next(k for k, v in sa.items() if v.is_floating_point() and v.abs().max() > 0.01)
    torch.testing.assert_close(half.state_dict()[k], 0.5 * (sa[k] + sb[k]), atol=2e-3, rtol=1e-3)


def test_average_checkpoints_refuses_what_cannot_be_averaged(tmp_path: Path) -> None:
    from murk.models.jointid import average_checkpoints

    torch.manual_seed(0)
    tiny = save_checkpoint(build_jointid("tiny"), tmp_path / "tiny.pt")
    small = save_checkpoint(build_jointid("small"), tmp_path / "small.pt")
    balanced_net = build_jointid("tiny")
    balanced_net.input_balance_pct = 1.0
    balanced = save_checkpoint(balanced_net, tmp_path / "balanced.pt")
    with pytest.raises(ValueError, match="at least two"):
        average_checkpoints([tiny], tmp_path / "x.pt")
    with pytest.raises(ValueError, match="sum to 1"):
        average_checkpoints([tiny, tiny], tmp_path / "x.pt", weights=[0.5, 0.6])
    with pytest.raises(ValueError, match=r"small\.pt: another architecture"):
        average_checkpoints([tiny, small], tmp_path / "x.pt")
    with pytest.raises(ValueError, match=r"balanced\.pt: input_balance_pct"):
        average_checkpoints([tiny, balanced], tmp_path / "x.pt")
    assert not (tmp_path / "x.pt").exists()


def test_a_plain_pickle_is_refused_with_the_way_out_and_loads_when_trusted(tmp_path, tiny, capsys):
    """A legacy file written by pickle.dump (not torch.save): torch.load cannot read it at all, and the refusal
    said only 'not a readable PyTorch checkpoint (UnpicklingError: Unsupported operand 149)' (issue 49)."""
    import pickle

    path = tmp_path / "legacy.pkl"
    state = {f"structure.{k}": v for k, v in tiny.state_dict().items()}
    with open(path, "wb") as f:
        pickle.dump({"model": state, "hook": _Evil()}, f, protocol=4)
    with warnings.catch_warnings(record=True) as caught, pytest.raises(InputFileError) as info:
        warnings.simplefilter("always")
        load_checkpoint(path)
    assert not [w for w in caught if "pickle protocol" in str(w.message)]  # torch's warning is not shown
    text = str(info.value)
    assert text.startswith(f"{path}: refusing to load it: a plain Python pickle (written by pickle.dump")
    assert "builtins.print" in text and "--trust-checkpoint" in text and "murk export" in text
    assert "this must not run" not in capsys.readouterr().out
    assert _same_weights(load_checkpoint(path, trust=True), tiny)  # the user's explicit opt-in: pickle.load
    assert "this must not run" in capsys.readouterr().out
