"""Folder walks never follow a symlink loop, and each broken or looping link is one error record (issue 49).

The outside attack corpus put a self link (``self.png -> self.png``) and a folder loop (``loop -> .``) beside a
good image: ``murk enhance DIR --recursive`` and ``murk compare DIR --recursive`` ended in ``RuntimeError: Symlink
loop from '.../self.png'`` (``Path.resolve()`` before Python 3.13) and enhance wrote nothing for the good image.
Here every command that walks folders gets the corpus's links: a self link, ``loop -> .``, ``sub/up -> ..``, a
chain to a missing file (``a -> b -> c -> missing``) and a chain that cycles (``x -> y -> x``). Each must process
every good image once, write one error record per link naming it, exit 1, and print no traceback.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.cli.main import app
from murk.io.jobs import read_errors
from tests.reliability.test_bad_input_corpus import COMMANDS, _frame, _no_traceback, _tiny_dataset, runner

pytestmark = pytest.mark.skipif(not hasattr(os, "symlink") or os.name == "nt", reason="needs POSIX symlinks")

LINKS = {  # the corpus's links: path relative to the input folder -> target as written
    "self.png": "self.png",
    "loop": ".",
    "sub/up": "..",
    "a.png": "b.png",
    "b.png": "c.png",
    "c.png": "missing.png",
    "x.png": "y.png",
    "y.png": "x.png",
}
FILE_LINKS = sorted(rel for rel in LINKS if rel.endswith(".png"))  # what a listing without recursion meets
GOOD = ("good.png", "sub/deep.png")


def _dive(inp: Path) -> Path:
    _frame(inp / GOOD[0])
    _frame(inp / GOOD[1], seed=2)
    for rel, target in LINKS.items():
        (inp / rel).symlink_to(target)
    return inp


def _records_name_the_links(records: list, inp: Path, rels: list[str]) -> None:  # type: ignore[type-arg]
    """One record per link, naming it, with the reason (a loop or a broken link) and what to do."""
    assert sorted(r.input for r in records) == sorted(str(inp / rel) for rel in rels), records
    for r in records:
        assert ("loop" in r.error or "broken symbolic link" in r.error) and "remove the link" in r.error, r


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_recursive_walk_records_each_loop_and_processes_every_good_image(tmp_path: Path, command: str) -> None:
    inp = _dive(tmp_path / "dive")
    out = tmp_path / "out"
    res = runner.invoke(app, [*COMMANDS[command](inp, out), *(["--recursive"] if command != "snow extract" else [])])
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    rels = sorted(LINKS)
    if command == "enhance":
        assert sorted(str(p.relative_to(out)) for p in out.rglob("*.png")) == sorted(GOOD)  # once each
        _records_name_the_links(read_errors(out / "errors.jsonl"), inp, rels)
    elif command == "compare":
        assert (out / "report.html").is_file()
        assert sorted(r["image"] for r in json.loads((out / "metrics.json").read_text())["rows"]) == [
            "deep.png",
            "good.png",
        ]
        _records_name_the_links(read_errors(out / "errors.jsonl"), inp, rels)
    elif command == "snow extract":
        from murk.snow.bank import load_bank

        assert sorted(s["path"] for s in load_bank(out / "bank.npz").meta["sources"]) == [str(inp / g) for g in GOOD]
        _records_name_the_links(read_errors(out / "bank_errors.jsonl"), inp, rels)
    else:
        scores = json.loads((out / "scores.json").read_text())
        assert sorted(row["file"] for row in scores["images"]) == sorted(GOOD)
        _records_name_the_links(read_errors(out / "errors.jsonl"), inp, rels)
    for rel in rels:
        assert str(inp / rel) in res.output


@pytest.mark.parametrize("command", ["enhance", "compare", "eval"])
def test_a_folder_without_recursion_records_its_own_links(tmp_path: Path, command: str) -> None:
    inp = _dive(tmp_path / "dive")
    out = tmp_path / "out"
    res = runner.invoke(app, COMMANDS[command](inp, out))
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    errors = out / "errors.jsonl"
    _records_name_the_links(read_errors(errors), inp, FILE_LINKS)
    if command == "enhance":
        assert [p.name for p in out.rglob("*.png")] == ["good.png"]


@pytest.mark.parametrize(
    ("pattern", "rels", "good"),
    [("**/*.png", sorted(LINKS), sorted(GOOD)), ("*.png", FILE_LINKS, ["good.png"])],
)
def test_an_enhance_glob_never_follows_a_loop(tmp_path: Path, pattern: str, rels: list[str], good: list[str]) -> None:
    inp = _dive(tmp_path / "dive")
    out = tmp_path / "out"
    res = runner.invoke(app, ["enhance", str(inp / pattern), "--out", str(out), "--method", "post"])
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*.png")) == good
    _records_name_the_links(read_errors(out / "errors.jsonl"), inp, rels)


def test_synth_records_each_looping_link_of_an_rgbd_folder(tmp_path: Path) -> None:
    rgbd = tmp_path / "rgbd"
    _frame(rgbd / "rgb" / "a.png", seed=3, size=(48, 64))
    (rgbd / "depth").mkdir()
    depth = np.random.default_rng(0).integers(500, 5000, (48, 64)).astype(np.uint16)
    assert cv2.imwrite(str(rgbd / "depth" / "a.png"), depth)
    (rgbd / "rgb" / "self.png").symlink_to("self.png")  # no depth: recorded as the loop it is, not as unpaired
    (rgbd / "rgb" / "loop").symlink_to(".")  # a folder in a folder of files: not walked
    (rgbd / "depth" / "x.png").symlink_to("y.png")  # a cycle of two links, both without an RGB image
    (rgbd / "depth" / "y.png").symlink_to("x.png")
    (rgbd / "rgb" / "c.png").symlink_to("d.png")  # a chain to a missing file, with a good depth map
    (rgbd / "rgb" / "d.png").symlink_to("missing.png")
    assert cv2.imwrite(str(rgbd / "depth" / "c.png"), depth)
    out = tmp_path / "out"
    res = runner.invoke(app, ["synth", str(rgbd), str(out), "--variants", "1", "--water-types", "I"])
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    assert sorted(p.name for p in (out / "degraded").iterdir()) == ["a_v0.png"]
    records = read_errors(out / "errors.jsonl")
    named = ["rgb/self.png", "depth/x.png", "depth/y.png", "rgb/c.png", "rgb/d.png"]
    assert sorted(r.input for r in records) == sorted(str(rgbd / n) for n in named), records
    assert all("loop" in r.error or "broken symbolic link" in r.error for r in records), records


def test_training_records_a_sample_that_became_a_self_link(tmp_path: Path) -> None:
    data = _tiny_dataset(tmp_path)
    looped = sorted((data / "degraded").glob("s1_*.png"))
    for p in looped:
        p.unlink()
        p.symlink_to(p.name)
    cfg = tmp_path / "train.yaml"
    cfg.write_text("model:\n  kind: lite\n  variant: tiny\ndata:\n  crop_hw: [32, 32]\n  val_fraction: 0.25\n")
    run = tmp_path / "run"
    args = ["train", "--config", str(cfg), "--data", str(data), "--out", str(run), "--steps", "4", "--batch", "2"]
    res = runner.invoke(app, args)
    _no_traceback(res)
    assert res.exit_code == 1, res.output
    records = read_errors(run / "errors.jsonl")
    assert records and {r.input for r in records} <= {str(p) for p in looped}
    assert all("a symbolic link loop" in r.error for r in records), records
    assert (run / "latest.pt").is_file()


def test_training_names_a_looping_link_of_an_rgbd_folder(tmp_path: Path) -> None:
    """Online training refuses an RGB-D folder whose files do not pair (exit 2, before any step): the link is
    named as the loop it is, not as a file without its depth map."""
    rgbd = tmp_path / "rgbd"
    _frame(rgbd / "rgb" / "a.png", size=(48, 64))
    (rgbd / "depth").mkdir()
    assert cv2.imwrite(str(rgbd / "depth" / "a.png"), np.full((48, 64), 2000, np.uint16))
    (rgbd / "rgb" / "self.png").symlink_to("self.png")
    cfg = tmp_path / "train.yaml"
    cfg.write_text("model:\n  kind: lite\n  variant: tiny\ndata:\n  crop_hw: [32, 32]\n")
    args = ["train", "--config", str(cfg), "--data", str(rgbd), "--out", str(tmp_path / "run"), "--steps", "1"]
    res = runner.invoke(app, args)
    _no_traceback(res)
    assert res.exit_code == 2, res.output
    text = " ".join(res.output.split())
    assert f"{rgbd / 'rgb' / 'self.png'}: a symbolic link loop (self.png -> self.png)" in text
