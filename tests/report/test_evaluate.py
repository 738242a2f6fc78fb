"""murk eval as a library call (murk.report.evaluate): rows, failures in the job schema, shared statistics."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.io.jobs import read_errors
from murk.metrics.stats import column_stats
from murk.report.evaluate import EvalOptions, evaluate, run_eval, summarize


def _images(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    for name in ("a", "b"):
        cv2.imwrite(str(folder / f"{name}.png"), rng.integers(0, 256, (32, 40, 3), dtype=np.uint8))
    (folder / "bad.png").write_bytes(b"not a png")
    return folder


def test_evaluate_returns_rows_and_error_records(tmp_path: Path) -> None:
    res = evaluate([_images(tmp_path / "imgs")])
    assert [r["file"] for r in res.images] == ["a.png", "b.png"]
    assert res.processed == 2 and res.failed == 1 and res.exit_code == 1
    (rec,) = res.failures
    assert (Path(rec.input).name, rec.stage) == ("bad.png", "score") and "decode" in rec.error
    stats = column_stats(r["uiqm"] for r in res.images)
    assert summarize(res.images)["uiqm"] == {"n": 2, "mean": stats.mean, "std": stats.std}


def test_run_eval_writes_errors_beside_the_json(tmp_path: Path) -> None:
    out = tmp_path / "out" / "r.json"
    res = run_eval([_images(tmp_path / "imgs")], json_out=out, options=EvalOptions(recursive=True))
    assert out.is_file() and res.errors_path == out.parent / "errors.jsonl"
    assert [Path(r.input).name for r in read_errors(out.parent / "errors.jsonl")] == ["bad.png"]


def test_a_table_over_an_input_file_is_refused_before_any_work(tmp_path: Path) -> None:
    imgs = _images(tmp_path / "imgs")
    before = (imgs / "a.png").read_bytes()
    with pytest.raises(ValueError, match=r"--json .*a\.png: this is the input"):
        run_eval([imgs / "a.png"], json_out=imgs / "a.png")
    with pytest.raises(ValueError, match=r"--csv .*b\.png: an input file of"):
        run_eval([imgs], csv_out=imgs / "." / "b.png")
    with pytest.raises(ValueError, match=r"--json .*: this is the input"):
        run_eval([imgs / "b.png"], ref=imgs / "a.png", json_out=imgs / "a.png")
    raw = _images(tmp_path / "raw")  # the --input folder (the raw frames beside the restorations)
    with pytest.raises(ValueError, match=r"--json .*a\.png: an input file of"):
        run_eval([imgs], inputs=raw, json_out=raw / "a.png")
    assert (imgs / "a.png").read_bytes() == before
    fine = run_eval([imgs], csv_out=imgs / "scores.csv")  # a new file beside the inputs is fine
    assert (imgs / "scores.csv").is_file() and fine.processed == 2


def test_two_references_of_one_stem_are_named_as_paths(tmp_path: Path) -> None:
    imgs = _images(tmp_path / "imgs")
    refs = tmp_path / "refs"
    refs.mkdir()
    for name in ("a.png", "a.jpg"):
        cv2.imwrite(str(refs / name), np.full((32, 40, 3), 90, np.uint8))
    res = evaluate([imgs / "a.png"], ref=refs)
    (rec,) = res.failures
    assert f"several reference images with stem 'a' in --ref: {refs / 'a.jpg'}, {refs / 'a.png'}" in rec.error
    assert "PosixPath" not in rec.error


def test_usage_errors_name_the_option() -> None:
    with pytest.raises(ValueError, match="nothing to evaluate"):
        evaluate([])
    with pytest.raises(ValueError, match="--ref: needs IMAGES"):
        evaluate([], ref=Path("x"))
    with pytest.raises(ValueError, match="--ssim-window"):
        EvalOptions(ssim_window="box")


def test_a_depth_map_of_another_size_than_its_reference_names_both_files(tmp_path: Path) -> None:
    for folder, (h, w) in (("pred", (24, 32)), ("gt", (48, 64))):
        (tmp_path / folder).mkdir()
        cv2.imwrite(str(tmp_path / folder / "x.png"), np.full((h, w), 2000, np.uint16))
    res = evaluate(depth=tmp_path / "pred", depth_ref=tmp_path / "gt")
    (rec,) = res.failures
    assert rec.input == str(tmp_path / "pred" / "x.png") and rec.stage == "depth"
    assert rec.error == f"size 32x24 differs from the reference depth {tmp_path / 'gt' / 'x.png'} (64x48)"
