"""murk study scores every arm on real paired photographs (eval.real_pairs / --real-pairs)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from murk.report import compare as compare_module
from murk.report.compare import CompareResult, summarise
from murk.report.study import evaluate_study, pair_sets, run_study
from tests.train._study import study_with_one_arm


def _pairs(root: Path, name: str, n: int) -> None:
    for sub in ("input", "reference"):
        (root / name / sub).mkdir(parents=True)
        for i in range(n):
            cv2.imwrite(str(root / name / sub / f"p{i}.png"), np.full((12, 12, 3), 60 + 10 * i, np.uint8))


def test_pair_sets_finds_one_set_or_a_folder_of_sets(tmp_path: Path) -> None:
    _pairs(tmp_path / "many", "b", 1)
    _pairs(tmp_path / "many", "a", 1)
    assert list(pair_sets(tmp_path / "many")) == ["a", "b"]
    assert list(pair_sets(tmp_path / "many" / "a")) == ["a"]
    with pytest.raises(ValueError, match="neither input/ and reference/"):
        pair_sets(tmp_path)


def test_study_scores_the_arms_on_each_set_and_averages_the_sets(tmp_path: Path, monkeypatch) -> None:
    _pairs(tmp_path / "pairs", "set1", 2)
    _pairs(tmp_path / "pairs", "set2", 1)
    cfg, base, out = study_with_one_arm(tmp_path, real_pairs=str(tmp_path / "pairs"))
    calls: list = []

    def fake_run_compare(images, methods, out_dir, **kwargs):
        labels = [m.label for m in methods]
        calls.append((Path(out_dir).name, labels, kwargs.get("ref_dir"), kwargs.get("max_side")))
        psnr = 20.0 if Path(out_dir).name == "set1" else 10.0
        rows = [
            {
                "method": lab,
                "psnr": psnr + i,
                "ssim": 0.5,
                "ciede2000": 9.0,
                "d_psnr": float(i),
                "d_ssim": 0.0,
                "d_ciede2000": -1.0 * i,
            }
            for i, lab in enumerate(labels)
        ]
        reference = kwargs.get("ref_dir") is not None
        return CompareResult(out=Path(out_dir), summary=summarise(rows, labels, reference=reference))

    monkeypatch.setattr(compare_module, "run_compare", fake_run_compare)
    report = evaluate_study(cfg, base, out)
    pair_calls = [c for c in calls if c[2] is not None]
    assert [c[0] for c in pair_calls] == ["set1", "set2"]
    assert all(c[3] == 256 and Path(c[2]).name == "reference" for c in pair_calls)
    labels = pair_calls[0][1]
    assert labels[:4] == ["raw", "greyworld+clahe", "colorbalance", "udcp"] and "proposed+post_murk" in labels
    assert "proposed+post" in labels  # Eq. (9) as the paper writes it, beside murk's default post
    means = report["real_pairs"]["mean_over_sets"]
    assert means["raw"]["psnr"] == pytest.approx(15.0)  # (20 + 10) / 2: each set counted once
    md = (out / "study.md").read_text()
    assert "## Real paired photographs" in md and "### set1 (2 pairs)" in md and "| udcp |" in md


def test_real_pairs_flag_overrides_the_config(tmp_path: Path, monkeypatch) -> None:
    seen = {}

    def fake_eval(study, base, out, on_event=None):
        seen["real_pairs"] = study.eval.real_pairs
        return {"real": {"errors": []}}

    from murk.report import study as study_module

    monkeypatch.setattr(study_module, "train_arms", lambda *a, **k: [])
    monkeypatch.setattr(study_module, "evaluate_study", fake_eval)
    train = {"model": {"variant": "tiny"}, "data": {"source": "scenes"}, "eval": {"real": None}, "steps": 1}
    (tmp_path / "train.yaml").write_text(yaml.safe_dump(train))
    (tmp_path / "study.yaml").write_text(yaml.safe_dump({"train": "train.yaml"}))
    for sub in ("input", "reference"):  # checked before the arms train: it must be a set
        (tmp_path / "pairs" / sub).mkdir(parents=True)
    run_study(tmp_path / "study.yaml", tmp_path / "out", real_pairs=tmp_path / "pairs")
    assert seen["real_pairs"] == str(tmp_path / "pairs")


def test_study_scores_the_arms_on_snow_pairs(tmp_path: Path, monkeypatch) -> None:
    for sub in ("snowy", "clean"):
        (tmp_path / "snow" / sub).mkdir(parents=True)
        cv2.imwrite(str(tmp_path / "snow" / sub / "s.png"), np.full((16, 16, 3), 90, np.uint8))
    cfg, base, out = study_with_one_arm(tmp_path, snow_pairs=str(tmp_path / "snow"))
    seen = {}

    def fake_run_compare(images, methods, out_dir, **kwargs):
        labels = [m.label for m in methods]
        if kwargs.get("snow_clean") is not None:
            seen["snow"] = (labels, Path(kwargs["snow_clean"]).name)
        rows = [{"method": lab, "snow_residue": 0.5, "snow_sites_left": 0.4} for lab in labels]
        return CompareResult(out=Path(out_dir), summary=summarise(rows, labels))

    monkeypatch.setattr(compare_module, "run_compare", fake_run_compare)
    report = evaluate_study(cfg, base, out)
    labels, clean = seen["snow"]
    assert clean == "clean" and labels[0] == "raw" and "proposed" in labels
    assert report["snow_pairs"]["summary"]["proposed"]["snow_residue"]["mean"] == 0.5
    assert "## Marine snow on real pairs" in (out / "study.md").read_text()


def test_arm_contrasts_pair_each_arm_with_the_one_before_and_the_last_with_the_first() -> None:
    from murk.report.study import arm_contrasts

    assert arm_contrasts(["basic", "basic_fs", "proposed"]) == [
        ("basic_fs", "basic"),
        ("proposed", "basic_fs"),
        ("proposed", "basic"),
    ]
    assert arm_contrasts(["basic", "proposed"]) == [("proposed", "basic")]
    assert arm_contrasts(["proposed"]) == []


def test_paired_contrasts_are_per_image_differences_over_all_sets() -> None:
    """a - b per image over both sets (an image name repeated in two sets is two images); an image scored by one
    method only, or a metric missing or NaN for an image, is left out; the t statistic is mean / (sd / sqrt(n))."""
    from murk.report.study import paired_contrasts, real_pairs_markdown

    d_psnr = {("s1", "x.png"): 1.0, ("s1", "y.png"): 2.0, ("s2", "x.png"): -0.5, ("s2", "z.png"): 3.5}
    rows = []
    for (st, im), d in d_psnr.items():
        rows.append({"set": st, "image": im, "method": "b", "psnr": 20.0, "ciede2000": 10.0})
        rows.append({"set": st, "image": im, "method": "a", "psnr": 20.0 + d, "ciede2000": 10.0 - d})
    rows.append({"set": "s2", "image": "only_a.png", "method": "a", "psnr": 99.0, "ciede2000": 0.0})
    rows.append({"set": "s3", "image": "unscored.png", "method": "a", "psnr": float("nan")})  # no ciede2000 key
    rows.append({"set": "s3", "image": "unscored.png", "method": "b", "psnr": 20.0})
    (c,) = paired_contrasts(rows, [("a", "b")])
    diffs = np.array(list(d_psnr.values()))
    assert c["n"] == 5 and c["psnr"]["n"] == 4 and c["ciede2000"]["n"] == 4
    assert c["psnr"]["higher"] == 3 and c["ciede2000"]["higher"] == 1
    assert c["psnr"]["mean"] == pytest.approx(diffs.mean()) and c["ciede2000"]["mean"] == pytest.approx(-diffs.mean())
    assert c["psnr"]["std"] == pytest.approx(diffs.std(ddof=1))
    assert c["psnr"]["t"] == pytest.approx(diffs.mean() / (diffs.std(ddof=1) / 2.0))
    # 95 % interval: Student's t with 3 degrees of freedom, 3.182446 (tables), times sd / sqrt(4)
    assert c["psnr"]["ci95"] == pytest.approx(3.182446 * diffs.std(ddof=1) / 2.0, rel=1e-6)
    (same,) = paired_contrasts(rows, [("b", "b")])
    assert same["psnr"]["mean"] == 0.0 and np.isnan(same["psnr"]["t"])  # no spread: no t
    pairs = {"max_side": 256, "folder": "F", "sets": {}, "methods": [], "mean_over_sets": {}, "contrasts": [c]}
    md = "\n".join(real_pairs_markdown(pairs))
    assert "### Arms against each other" in md and "| a - b | 5 | +1.50 +- 1.68 (-1.18 to +4.18) | 3 | 1.78 |" in md
