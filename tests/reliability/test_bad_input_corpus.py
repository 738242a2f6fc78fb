"""The reliability contract on a corpus of bad inputs built at run time (issue 31; docs/failure-modes.md).

Every batch command, given a folder that holds one good input and one bad input of each kind robots and field
laptops produce, must: process the good input, write one error record naming the bad file (the
:mod:`murk.io.jobs` schema), exit 1, and print no traceback. Two inputs never write one output; a command's own
outputs inside its input folder are never read back; an output folder that cannot be written is named; a
refused checkpoint says how to allow it and why it is refused; and a payload in a pickled checkpoint never runs.

Permission errors are real (``chmod 000``) when the suite runs as an ordinary user; as root (CI containers),
where ``chmod`` does not stop reads, the same ``PermissionError`` is raised by the read or mkdir call itself.
"""

from __future__ import annotations

import errno
import json
import os
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from murk.cli.main import app
from murk.io.jobs import read_errors

runner = CliRunner()
ROOT = os.geteuid() == 0 if hasattr(os, "geteuid") else False
BAD_KINDS = ("fifo", "broken_link", "device", "empty", "not_an_image", "truncated", "permission")


def _frame(path: Path, seed: int = 0, size: tuple[int, int] = (96, 128)) -> Path:
    """A murky frame with a few bright particles (marine snow for ``murk snow extract``)."""
    rng = np.random.default_rng(seed)
    h, w = size
    img = np.zeros((h, w, 3), np.uint8)
    img[:] = (40, 90, 70)
    img = np.clip(img.astype(np.int16) + rng.integers(-4, 5, img.shape), 0, 255).astype(np.uint8)
    for y, x in ((10, 20), (40, 60), (30, 80), (70, 100)):
        img[y : y + 4, x : x + 4] = 230
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), img)
    return path


def _bad(folder: Path, kind: str, stem: str = "bad") -> Path:
    """Put one bad input of ``kind`` named ``stem`` into ``folder``; return its path."""
    path = folder / f"{stem}{'.jpg' if kind == 'truncated' else '.png'}"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "broken_link":
        path.symlink_to(folder / "gone.png")
    elif kind == "device":
        path.symlink_to("/dev/zero")
    elif kind == "empty":
        path.write_bytes(b"")
    elif kind == "not_an_image":
        path.write_text("this is not an image\n")
    elif kind == "truncated":
        ok, buf = cv2.imencode(".jpg", np.full((64, 64, 3), 128, np.uint8))
        assert ok
        path.write_bytes(buf.tobytes()[:200])
    elif kind == "permission":
        _frame(path, seed=1)
        path.chmod(0)
    return path


@pytest.fixture
def deny_reads(monkeypatch: pytest.MonkeyPatch) -> None:
    """As root, make reading a file that has no permission bits fail as it does for an ordinary user."""
    if not ROOT:
        return
    real = np.fromfile

    def fromfile(file, *args, **kwargs):  # type: ignore[no-untyped-def]
        if isinstance(file, (str, Path)) and os.path.exists(file) and (os.stat(file).st_mode & 0o777) == 0:
            raise PermissionError(errno.EACCES, "Permission denied", str(file))
        return real(file, *args, **kwargs)

    monkeypatch.setattr(np, "fromfile", fromfile)


def _no_traceback(res) -> None:  # type: ignore[no-untyped-def]
    assert "Traceback" not in res.output, res.output
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)


def _one_record_naming(errors_file: Path, bad: Path) -> None:
    records = read_errors(errors_file)
    assert [r.input for r in records] == [str(bad)], records
    assert records[0].error.strip()


COMMANDS: dict[str, Callable[[Path, Path], list[str]]] = {
    "enhance": lambda inp, out: ["enhance", str(inp), "--out", str(out), "--method", "post"],
    "compare": lambda inp, out: ["compare", str(inp), "--out", str(out), "--method", "post"],
    "snow extract": lambda inp, out: [
        "snow",
        "extract",
        str(inp),
        "--out",
        str(out / "bank.npz"),
        "--method",
        "tophat",
    ],
    "eval": lambda inp, out: ["eval", str(inp), "--json", str(out / "scores.json")],
}


@pytest.mark.parametrize("kind", BAD_KINDS)
@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.usefixtures("deny_reads")
def test_one_bad_input_never_sinks_a_batch(tmp_path: Path, command: str, kind: str) -> None:
    inp = tmp_path / "dive"
    _frame(inp / "good.png")
    bad = _bad(inp, kind)
    out = tmp_path / "out"
    res = runner.invoke(app, COMMANDS[command](inp, out))
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    assert str(bad) in res.output
    if command == "enhance":
        assert (out / "good.png").is_file()
        _one_record_naming(out / "errors.jsonl", bad)
    elif command == "compare":
        assert (out / "report.html").is_file()
        _one_record_naming(out / "errors.jsonl", bad)
        assert [r["image"] for r in json.loads((out / "metrics.json").read_text())["rows"]] == ["good.png"]
    elif command == "snow extract":
        assert (out / "bank.npz").is_file()
        _one_record_naming(out / "bank_errors.jsonl", bad)
    else:
        scores = json.loads((out / "scores.json").read_text())
        assert [row["file"] for row in scores["images"]] == ["good.png"]
        assert [r["input"] for r in scores["errors"]] == [str(bad)]


@pytest.mark.parametrize("kind", ["fifo", "broken_link", "permission", "not_an_image"])
@pytest.mark.usefixtures("deny_reads")
def test_synth_records_a_bad_depth_map_and_writes_the_rest(tmp_path: Path, kind: str) -> None:
    rgbd = tmp_path / "rgbd"
    rng = np.random.default_rng(0)
    for stem in ("a", "b"):
        _frame(rgbd / "rgb" / f"{stem}.png", seed=3, size=(48, 64))
        (rgbd / "depth").mkdir(parents=True, exist_ok=True)
        assert cv2.imwrite(str(rgbd / "depth" / f"{stem}.png"), rng.integers(500, 5000, (48, 64)).astype(np.uint16))
    (rgbd / "depth" / "b.png").unlink()
    bad = _bad(rgbd / "depth", kind, stem="b")  # b's depth map is bad; a's pair is good
    out = tmp_path / "out"
    res = runner.invoke(app, ["synth", str(rgbd), str(out), "--variants", "1", "--water-types", "I"])
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    assert (out / "degraded" / "a_v0.png").is_file() and not (out / "degraded" / "b_v0.png").exists()
    records = read_errors(out / "errors.jsonl")
    assert len(records) == 1 and str(bad) in records[0].error, records


@pytest.mark.parametrize("command", ["enhance", "compare", "eval"])
@pytest.mark.usefixtures("deny_reads")
def test_a_subfolder_that_cannot_be_listed_is_one_record(tmp_path: Path, command: str) -> None:
    """An unreadable subfolder of a recursive listing is reported, not silently left out."""
    inp = tmp_path / "dive"
    _frame(inp / "good.png")
    _frame(inp / "locked" / "x.png")
    locked = inp / "locked"
    if ROOT:  # root lists any folder: make the walk fail on it as it does for an ordinary user
        real_scandir = os.scandir

        def scandir(path="."):  # type: ignore[no-untyped-def]
            if os.fspath(path) == str(locked):
                raise PermissionError(errno.EACCES, "Permission denied", str(locked))
            return real_scandir(path)

        mp = pytest.MonkeyPatch()
        mp.setattr(os, "scandir", scandir)
        mp.setattr(os, "access", lambda p, mode, **kw: os.fspath(p) != str(locked))
    else:
        locked.chmod(0)
        mp = None
    try:
        res = runner.invoke(app, [*COMMANDS[command](inp, tmp_path / "out"), "--recursive"])
    finally:
        if mp is not None:
            mp.undo()
        locked.chmod(0o755)
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    assert f"{locked}: a folder that cannot be listed" in res.output


def test_two_inputs_never_write_one_output(tmp_path: Path) -> None:
    inp = tmp_path / "dive"
    _frame(inp / "a.png", seed=1)
    _frame(inp / "a.jpg", seed=2)
    out = tmp_path / "out"
    res = runner.invoke(app, ["enhance", str(inp), "--out", str(out), "--method", "post", "--format", "png"])
    _no_traceback(res)
    assert res.exit_code == 0, res.output
    written = sorted(p.name for p in out.glob("*.png"))
    assert written == ["a_jpg.png", "a_png.png"]
    a, b = (cv2.imread(str(out / n)) for n in written)
    assert not np.array_equal(a, b)  # two results, neither overwritten by the other


@pytest.mark.parametrize("command", ["enhance", "compare", "snow extract"])
def test_outputs_inside_the_input_folder_are_never_read_back(tmp_path: Path, command: str) -> None:
    inp = tmp_path / "dive"
    _frame(inp / "f1.png")
    out = inp / "murk-out"
    for run in range(2):  # the first run, then the rerun with the outputs in place
        args = COMMANDS[command](inp, out) + (["--recursive"] if command != "snow extract" else [])
        res = runner.invoke(app, args)
        _no_traceback(res)
        assert res.exit_code == 0, (run, res.output)
        assert "failed" not in res.output
        if command == "enhance":
            assert sorted(p.name for p in out.rglob("*.png")) == ["f1.png"]
        elif command == "compare":
            rows = json.loads((out / "metrics.json").read_text())["rows"]
            assert [r["image"] for r in rows] == ["f1.png"]
        else:
            from murk.snow.bank import load_bank

            assert [s["path"] for s in load_bank(out / "bank.npz").meta["sources"]] == [str(inp / "f1.png")]


@pytest.mark.parametrize("command", ["enhance", "compare", "snow extract", "scenes"])
def test_an_output_folder_that_cannot_be_created_is_named(
    tmp_path: Path, command: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    inp = tmp_path / "dive"
    _frame(inp / "f1.png")
    locked = tmp_path / "locked"
    locked.mkdir()
    out = locked / "out"
    real_mkdir = os.mkdir

    def mkdir(path, *args, **kwargs):  # type: ignore[no-untyped-def]
        if Path(path).is_relative_to(locked):
            raise PermissionError(errno.EACCES, "Permission denied", os.fspath(path))
        return real_mkdir(path, *args, **kwargs)

    monkeypatch.setattr(os, "mkdir", mkdir)
    args = (
        ["scenes", str(out), "--count", "1", "--size", "64x48"] if command == "scenes" else COMMANDS[command](inp, out)
    )
    res = runner.invoke(app, args)
    _no_traceback(res)
    assert res.exit_code == 2, res.output
    lines = [line for line in res.output.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, res.output
    assert "cannot create the" in lines[0] and "folder (permission denied" in lines[0]
    assert f"check that {locked} is writable" in lines[0]


def test_a_file_where_the_output_folder_should_be_is_named(tmp_path: Path) -> None:
    inp = tmp_path / "dive"
    _frame(inp / "f1.png")
    (tmp_path / "notes.txt").write_text("x")
    res = runner.invoke(app, ["enhance", str(inp), "--out", str(tmp_path / "notes.txt" / "out"), "--method", "post"])
    _no_traceback(res)
    assert res.exit_code == 2
    assert f"error: {tmp_path / 'notes.txt' / 'out'}: cannot create the output folder" in res.output


def test_an_unwritable_output_file_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from murk.io import atomic

    def denied(path: Path, data: bytes, fsync: bool) -> None:
        raise PermissionError(errno.EACCES, "Permission denied", str(path))

    monkeypatch.setattr(atomic, "_write_file", denied)
    _frame(tmp_path / "f1.png")
    res = runner.invoke(app, ["eval", str(tmp_path / "f1.png"), "--csv", str(tmp_path / "o" / "scores.csv")])
    _no_traceback(res)
    assert res.exit_code == 2
    assert f"error: {tmp_path / 'o' / 'scores.csv'}: cannot write the output file (permission denied; check" in (
        res.output.replace("\n", "")
    )


class _Payload:
    def __init__(self, marker: Path) -> None:
        self.marker = marker

    def __reduce__(self):  # type: ignore[no-untyped-def]
        return (Path.touch, (self.marker,))


@pytest.mark.parametrize("command", ["enhance", "export", "train"])
def test_a_refused_checkpoint_teaches_and_runs_nothing(tmp_path: Path, command: str) -> None:
    marker = tmp_path / "PAYLOAD-RAN"
    ckpt = tmp_path / "legacy.pt"
    torch.save({"state_dict": {}, "extra": _Payload(marker)}, ckpt)
    _frame(tmp_path / "in" / "f1.png")
    if command == "enhance":
        args = ["enhance", str(tmp_path / "in"), "--out", str(tmp_path / "o"), "--method", "jointid"]
        args += ["--checkpoint", str(ckpt)]
    elif command == "export":
        args = ["export", "--checkpoint", str(ckpt), "--out", str(tmp_path / "m.onnx")]
    else:
        data = _tiny_dataset(tmp_path)
        cfg = tmp_path / "train.yaml"
        cfg.write_text(f"model:\n  kind: lite\n  variant: tiny\n  init_checkpoint: {ckpt}\n")
        args = ["train", "--config", str(cfg), "--data", str(data), "--out", str(tmp_path / "run"), "--steps", "1"]
        args += ["--batch", "2"]
    res = runner.invoke(app, args)
    _no_traceback(res)
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert f"{ckpt}: refusing to load it" in text
    assert "--trust-checkpoint" in text and "model.trust_checkpoint: true" in text
    assert "runs any code it holds" in text and "off by default" in text
    assert not marker.exists()


def _tiny_dataset(tmp_path: Path) -> Path:
    """A 'murk synth' folder of 4 clean images x 2 variants (48x64)."""
    rgbd = tmp_path / "rgbd"
    rng = np.random.default_rng(0)
    for i in range(4):
        _frame(rgbd / "rgb" / f"s{i}.png", seed=i, size=(48, 64))
        (rgbd / "depth").mkdir(parents=True, exist_ok=True)
        assert cv2.imwrite(str(rgbd / "depth" / f"s{i}.png"), rng.integers(500, 5000, (48, 64)).astype(np.uint16))
    data = tmp_path / "data"
    res = runner.invoke(app, ["synth", str(rgbd), str(data), "--variants", "2", "--water-types", "I", "-q"])
    assert res.exit_code == 0, res.output
    return data


def test_training_records_an_unreadable_sample_and_goes_on(tmp_path: Path) -> None:
    data = _tiny_dataset(tmp_path)
    broken = sorted((data / "degraded").glob("*.png"))
    for p in broken:  # every input of one split is unreadable in the same way
        if p.name.startswith("s1_"):
            p.write_text("not an image")
    cfg = tmp_path / "train.yaml"
    cfg.write_text("model:\n  kind: lite\n  variant: tiny\ndata:\n  crop_hw: [32, 32]\n  val_fraction: 0.25\n")
    run = tmp_path / "run"
    res = runner.invoke(
        app, ["train", "--config", str(cfg), "--data", str(data), "--out", str(run), "--steps", "4", "--batch", "2"]
    )
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    records = read_errors(run / "errors.jsonl")
    assert records and {r.input for r in records} <= {str(p) for p in broken if p.name.startswith("s1_")}
    assert all(r.stage == "read" and "cannot decode image" in r.error for r in records)
    assert (run / "latest.pt").is_file()
    summary = json.loads((run / "summary.json").read_text())
    assert summary["steps_done"] == 4 and summary["failed"] == len(records)


def test_broken_yaml_is_one_line_naming_the_place(tmp_path: Path) -> None:
    cfg = tmp_path / "synth.yaml"
    cfg.write_text("seed: [1\n")
    res = runner.invoke(app, ["synth", str(tmp_path), str(tmp_path / "o"), "--config", str(cfg)])
    _no_traceback(res)
    assert res.exit_code == 2
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"error: {cfg}: invalid YAML (") and "line 2" in lines[0], lines


@pytest.mark.parametrize("kind", ["broken_link", "not_an_image", "fifo"])
def test_scenes_record_a_bad_texture_and_use_the_others(tmp_path: Path, kind: str) -> None:
    tex = tmp_path / "textures"
    _frame(tex / "good.png")
    bad = _bad(tex, kind)
    out = tmp_path / "scenes"
    res = runner.invoke(app, ["scenes", str(out), "--count", "2", "--size", "64x48", "--textures", str(tex)])
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    assert sorted(p.name for p in (out / "rgb").iterdir()) == ["scene_000000.png", "scene_000001.png"]
    _one_record_naming(out / "errors.jsonl", bad)
