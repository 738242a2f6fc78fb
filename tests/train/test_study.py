"""murk study: arm configs differ only in stages/out; arms train as subprocesses; finished arms are skipped."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from murk._config import to_dict
from murk.train.config import TrainConfig
from murk.train.study import (
    ArmConfig,
    StudyConfig,
    StudyEvalConfig,
    arm_config,
    arm_finished,
    load_study,
    train_arms,
)

TRAIN = {
    "model": {"variant": "tiny"},
    "data": {"source": "scenes", "scenes_count": 6, "crop_hw": [32, 64], "workers": 0, "val_fraction": 0.2},
    "eval": {"every": 2, "val_batches": 1, "real": None},
    "steps": 2,
    "batch": 2,
    "log_every": 1,
}


def _write(tmp: Path, jobs: int = 1) -> Path:
    (tmp / "train.yaml").write_text(yaml.safe_dump(TRAIN))
    study = {
        "train": "train.yaml",
        "arms": [{"name": "basic", "stages": ["basic"]}, {"name": "snowy", "stages": ["marine_snow", "basic"]}],
        "jobs": jobs,
        "threads_per_job": 1,
    }
    (tmp / "study.yaml").write_text(yaml.safe_dump(study))
    return tmp / "study.yaml"


def test_arm_configs_differ_only_in_stages_and_out(tmp_path: Path) -> None:
    study, base = load_study(_write(tmp_path))
    assert base.steps == 2  # the training config was found relative to the study file
    a, b = (to_dict(arm_config(base, arm, tmp_path / "s")) for arm in study.arms)
    assert a["data"]["synthesis"]["stages"] == ["basic"]
    assert b["data"]["synthesis"]["stages"] == ["basic", "marine_snow"]  # application order
    assert a["out"].endswith("models/basic") and b["out"].endswith("models/snowy")
    for d in (a, b):
        d["data"]["synthesis"].pop("stages")
        d.pop("out")
    assert a == b


def test_study_config_errors() -> None:
    with pytest.raises(ValueError, match="train: expected the path"):
        StudyConfig()
    with pytest.raises(ValueError, match="unique names"):
        StudyConfig(train="t.yaml", arms=(ArmConfig("a", ("basic",)), ArmConfig("a", ("basic",))))
    with pytest.raises(ValueError, match="stages"):
        ArmConfig("a", ("fog",))
    with pytest.raises(ValueError, match=r"arms\.name"):
        ArmConfig("a/b", ("basic",))
    with pytest.raises(ValueError, match="synthetic_scenes: expected >= 0"):  # was a silent skip
        StudyEvalConfig(synthetic_scenes=-4)
    with pytest.raises(ValueError, match="synthetic_hw: expected a height and width of at least 32"):
        StudyEvalConfig(synthetic_hw=(0, 320))


def test_train_arms_then_skip_finished(tmp_path: Path) -> None:
    study, base = load_study(_write(tmp_path, jobs=2))
    out = tmp_path / "study"
    events: list[str] = []
    runs = train_arms(study, base, out, on_event=events.append)
    assert [r.status for r in runs] == ["trained", "trained"], [
        (out / "models" / r.name / "train.out").read_text() for r in runs
    ]
    for arm in study.arms:
        cfg = arm_config(base, arm, out)
        assert arm_finished(cfg)
        assert (out / "models" / arm.name / "latest.pt").is_file()
        written = yaml.safe_load((out / "configs" / f"{arm.name}.yaml").read_text())
        assert written["data"]["synthesis"]["stages"] == list(arm.stages)
    before = (out / "models" / "basic" / "latest.pt").stat().st_mtime_ns
    runs = train_arms(study, base, out)
    assert [r.status for r in runs] == ["done", "done"]
    assert (out / "models" / "basic" / "latest.pt").stat().st_mtime_ns == before  # not retrained


def test_arm_finished_needs_all_steps(tmp_path: Path) -> None:
    cfg = TrainConfig(out=str(tmp_path))
    assert not arm_finished(cfg)
    (tmp_path / "summary.json").write_text(json.dumps({"steps_done": 3, "total_steps": 5}))
    assert not arm_finished(cfg)
    (tmp_path / "summary.json").write_text(json.dumps({"steps_done": 5, "total_steps": 5}))
    assert arm_finished(cfg)


def test_shipped_study_configs() -> None:
    """Both shipped studies load; the CPU study's last arm is exactly `murk train --config train-small-cpu.yaml`."""
    from murk._config import load_yaml, merge

    root = Path(__file__).resolve().parents[2] / "configs"
    for name in ("study-paper-cpu.yaml", "study-paper-gpu.yaml"):
        study, base = load_study(root / name)
        assert [a.stages for a in study.arms] == [
            ("basic",),
            ("basic", "forward_scatter"),
            ("basic", "forward_scatter", "marine_snow"),
        ]
    study, base = load_study(root / "study-paper-cpu.yaml")
    assert base.model.variant == "small"
    shipped = load_yaml(TrainConfig, root / "train-small-cpu.yaml")
    assert arm_config(base, study.arms[-1], "X") == merge(shipped, {"out": str(Path("X") / "models" / "proposed")})
    pair, pair_base = load_study(root / "study-basic-vs-proposed-cpu.yaml")  # the paper's study minus its middle arm
    assert [a.name for a in pair.arms] == ["basic", "proposed"] and pair.arms == (study.arms[0], study.arms[-1])
    assert pair_base == base and pair.eval == study.eval


def test_a_killed_arm_resumes_to_the_same_weights(tmp_path: Path) -> None:
    """An arm stopped part-way (its latest.pt left behind, as by a killed study) is resumed by the next
    invocation and ends bit-identical to an arm trained in one go."""
    import torch

    from murk.models.jointid import read_checkpoint
    from murk.train.loop import train

    study, base = load_study(_write(tmp_path))
    study = StudyConfig(train=study.train, arms=study.arms[:1], jobs=1, threads_per_job=1)
    whole, part = tmp_path / "whole", tmp_path / "part"
    train_arms(study, base, whole)
    threads = torch.get_num_threads()
    torch.set_num_threads(1)  # as the arms' processes (threads_per_job 1): same float results
    try:
        train(arm_config(base, study.arms[0], part), stop_after=1)  # "killed" after 1 of 2 steps
    finally:
        torch.set_num_threads(threads)
    assert not arm_finished(arm_config(base, study.arms[0], part))
    (run,) = train_arms(study, base, part)
    assert run.status == "trained" and "--resume" in (part / "models" / "basic" / "train.out").read_text()
    a, _ = read_checkpoint(whole / "models" / "basic" / "latest.pt")
    b, _ = read_checkpoint(part / "models" / "basic" / "latest.pt")
    assert all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="SIGKILL of the parent: Linux death signal")
@pytest.mark.parametrize("how", ["SIGTERM", "SIGKILL"])
def test_a_killed_study_leaves_no_arm_training(tmp_path: Path, how: str) -> None:
    """`kill` (SIGTERM) runs the study's cleanup; SIGKILL cannot, and the arms get SIGTERM from the kernel."""
    _write(tmp_path, jobs=2)
    pids = tmp_path / "pids"
    fake = tmp_path / "fake_python.sh"  # stands in for `python -m murk train`: records its pid, then waits
    fake.write_text(f"#!/bin/sh\necho $$ >> {pids}\nexec sleep 120\n")
    fake.chmod(0o755)
    driver = (
        "from murk.train.study import load_study, train_arms\n"
        f"study, base = load_study({str(tmp_path / 'study.yaml')!r})\n"
        f"train_arms(study, base, {str(tmp_path / 'study')!r}, python={str(fake)!r})\n"
    )
    parent = subprocess.Popen([sys.executable, "-c", driver])
    deadline = time.monotonic() + 240  # generous: importing murk on a loaded 2-core machine
    while time.monotonic() < deadline and (not pids.exists() or len(pids.read_text().split()) < 2):
        time.sleep(0.1)
    assert pids.exists(), "the study did not start its arms"
    children = [int(p) for p in pids.read_text().split()]
    assert len(children) == 2
    os.kill(parent.pid, getattr(signal, how))
    parent.wait(timeout=60)
    deadline = time.monotonic() + 60  # a guard: the arms sleep 120 s, so any bound below that catches a survivor
    while time.monotonic() < deadline and any(_alive(p) for p in children):
        time.sleep(0.1)
    assert not any(_alive(p) for p in children)


def _alive(pid: int) -> bool:
    try:
        os.waitpid(pid, os.WNOHANG)  # reap if it happens to be our child (it is not: the driver's)
    except ChildProcessError:
        pass
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"  # a zombie waiting for its (dead) parent is not running
    except FileNotFoundError:
        return False


def test_study_result_is_a_job_summary_with_failed_arms_in_errors_jsonl(tmp_path: Path, monkeypatch) -> None:
    """Issue 14: murk study returns the job summary; a failed arm is an errors.jsonl record (stage train)."""
    import murk.report.study as report_study
    from murk.io.jobs import read_errors
    from murk.train.study import ArmRun

    runs = [ArmRun("basic", "done"), ArmRun("basic_fs", "trained", 1.0), ArmRun("proposed", "failed", 1.0, "exit 1")]
    monkeypatch.setattr(report_study, "train_arms", lambda *a, **k: runs)
    root = Path(__file__).resolve().parents[2] / "configs"
    res = report_study.run_study(root / "study-paper-cpu.yaml", tmp_path, train_only=True)
    assert (res.processed, res.skipped, res.failed, res.ok) == (1, 1, 1, False)
    (rec,) = read_errors(tmp_path / "errors.jsonl")
    assert (rec.stage, rec.index, rec.error) == ("train", 2, "arm proposed: exit 1")
    assert rec.input == str(tmp_path / "models" / "proposed")


def test_final_recipe_studies_differ_only_in_stages() -> None:
    """The ablations with the final data recipe (lite and the small Joint-ID) load; their arms are the paper's three
    stage sets, each with the camera stage, and each arm's config is the training config with only the stages
    changed (trained from scratch: no init checkpoint)."""
    from murk._config import merge

    root = Path(__file__).resolve().parents[2] / "configs"
    for name, variant in (("study-lite-balance-cpu.yaml", "base"), ("study-small-balance-cpu.yaml", "small")):
        study, base = load_study(root / name)
        assert [a.stages for a in study.arms] == [
            ("basic", "camera"),
            ("basic", "forward_scatter", "camera"),
            ("basic", "forward_scatter", "marine_snow", "camera"),
        ]
        assert base.model.variant == variant and base.model.init_checkpoint is None
        assert study.eval.synthetic_balance_pct == 0.5
        for arm in study.arms:
            expected = merge(base, {"data": {"synthesis": {"stages": list(arm.stages)}}, "out": f"X/models/{arm.name}"})
            assert arm_config(base, arm, "X") == expected


def test_jointid_arms_are_scored_as_trained_without_the_affine_transfer_lite_or_depth_pass() -> None:
    from murk.enhance.restorer import Blend, create
    from murk.report.methods import parse_method
    from murk.report.study import arm_spec

    spec = parse_method(arm_spec("jointid", "full=jointid:runs/a/latest.pt"))
    assert (spec.label, spec.checkpoint, dict(spec.options)) == (
        "full",
        "runs/a/latest.pt",
        {"refine": 0, "lite_blend": 0, "depth_area": 0},
    )
    chained = parse_method(arm_spec("jointid", "full+post=jointid+post:x.pt", "preset=paper", "lam=0.5"))
    assert dict(chained.options) == {"preset": "paper", "lam": 0.5, "refine": 0, "lite_blend": 0, "depth_area": 0}
    assert arm_spec("lite", "a=lite:x.pt") == "a=lite:x.pt"
    restorer = create(arm_spec("jointid", "jointid"))
    assert restorer.refine_settings.radius == 0.0 and not isinstance(restorer, Blend)  # the options reach it
    assert restorer.depth_area == 0  # the depth of the frame's own pass, as trained


def test_a_bad_evaluation_folder_stops_the_study_before_any_arm_trains(tmp_path: Path, monkeypatch) -> None:
    from murk.report import study as report_study
    from tests.train._study import study_with_one_arm

    trained: list[str] = []
    monkeypatch.setattr(report_study, "train_arms", lambda *a, **k: trained.append("arms") or [])
    for flag, message in (
        ("real_pairs", r"eval\.real_pairs: .* holds neither input/"),
        ("snow_pairs", r"eval\.snow_pairs: .* must hold snowy/ and clean/"),
    ):
        (tmp_path / flag).mkdir()
        study_with_one_arm(tmp_path / flag)
        with pytest.raises(ValueError, match=message):
            report_study.run_study(tmp_path / flag / "study.yaml", tmp_path / flag / "out", **{flag: tmp_path / "no"})
    (tmp_path / "r").mkdir()
    study_with_one_arm(tmp_path / "r")
    (tmp_path / "r" / "real" / "a.png").unlink()  # eval.real now holds no image
    with pytest.raises(ValueError, match=r"eval\.real: .* holds no images"):
        report_study.run_study(tmp_path / "r" / "study.yaml", tmp_path / "r" / "out")
    assert trained == []  # no arm trained for any of them
    report_study.run_study(tmp_path / "r" / "study.yaml", tmp_path / "r" / "o2", train_only=True)  # needs none
    assert trained == ["arms"]
