"""The paper's ablation as one job: models that differ ONLY in the training data's synthesis stages.

A study config (``configs/study-paper-cpu.yaml``) names one training config and the arms; every arm is that
training config with ``data.synthesis.stages`` replaced and ``out`` set to ``<study>/models/<arm>``, nothing
else (same architecture, seed, steps, schedule, scenes and water draws: turning a stage on or off never
changes the other stages' random draws, see :func:`murk.synth.params.sample_variant`). So the arm whose
stages equal the training config's own is exactly ``murk train --config <that file>``.

Resumable: an arm whose ``summary.json`` records all its steps is finished and never retrained; an arm with a
``latest.pt`` continues with ``--resume`` (bit-exact on the CPU). Arms run as ``murk train`` subprocesses,
``jobs`` at a time, each limited to ``threads_per_job`` threads; their console output goes to
``<study>/models/<arm>/train.out``.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from murk._config import dump_yaml, load_yaml, merge
from murk._workers import TerminateAsExit, subprocess_dies_with_parent
from murk.io.atomic import make_output_folder, write_text_atomic
from murk.synth.config import parse_stages
from murk.train.config import TrainConfig


@dataclass(frozen=True)
class ArmConfig:
    """One trained model of the study: a label and the synthesis stages of its training data."""

    name: str
    stages: tuple[str, ...]

    def __post_init__(self) -> None:
        if not self.name or not all(c.isalnum() or c in "-_." for c in self.name):
            raise ValueError(f"arms.name: expected letters, digits, '-', '_' or '.', got {self.name!r}")
        object.__setattr__(self, "stages", parse_stages(self.stages))


def _paper_arms() -> tuple[ArmConfig, ...]:
    return (
        ArmConfig("basic", ("basic",)),
        ArmConfig("basic_fs", ("basic", "forward_scatter")),
        ArmConfig("proposed", ("basic", "forward_scatter", "marine_snow")),
    )


@dataclass(frozen=True)
class StudyEvalConfig:
    """How the trained arms are evaluated (``murk.report.study``)."""

    real: str = "builtin:underwater"
    """Folder of REAL underwater images (the Fig. 8 table and Fig. 9 grids)."""
    synthetic_scenes: int = 64
    """Held-out procedural scenes with references (PSNR/SSIM, depth errors); 0 = skip."""
    synthetic_seed: int = 20261201
    """Seed of the held-out scenes and their water (differs from any training seed used in configs/)."""
    synthetic_hw: tuple[int, int] = (240, 320)
    synthetic_balance_pct: float | None = None
    """Held-out scenes with photographic targets: each clean scene colour-balanced with this percentage (as
    ``data.scene_balance_pct`` balances the training scenes; :func:`murk.report.heldout.make_heldout`), and the
    classical ``colorbalance`` scored beside the arms. None: the procedural scenes as rendered."""
    post_lambda: float = 0.3
    """lambda of Eq. (9) for the '+post' methods."""
    baselines: tuple[str, ...] = ()
    """Extra ``murk compare`` method specs scored on the real images beside the arms, e.g. the paper's
    comparison baselines ``udaformer:weights/UDA.pt`` and ``ursct:weights/URSCT.pth`` (``docs/baselines.md``;
    weights the user downloads; they must load with weights_only=True)."""
    real_pairs: str | None = None
    """Real paired photographs for full-reference scoring (PSNR, SSIM, CIEDE2000 with paired differences to
    the raw input): a folder with ``input/`` and ``reference/`` (matched by file stem), or a folder of such
    sets (each scored on its own, then the mean of the set means). None: skipped (``murk study --real-pairs``
    sets it)."""
    real_pairs_max_side: int = 256
    """Pairs are scored after downscaling to this long side (the field's published real-pair tables)."""
    snow_pairs: str | None = None
    """Pairs of the same real scenes with and without marine snow: a folder with ``snowy/`` and ``clean/``
    (matched by file stem); every arm's snow residue on the known particle sites
    (:mod:`murk.metrics.snow_pairs`). None: skipped (``murk study --snow-pairs`` sets it)."""

    def __post_init__(self) -> None:
        if self.real_pairs_max_side < 8:
            raise ValueError(f"real_pairs_max_side: expected >= 8, got {self.real_pairs_max_side}")
        if self.synthetic_scenes < 0:
            raise ValueError(
                f"synthetic_scenes: expected >= 0 (0 skips the held-out scenes), got {self.synthetic_scenes}"
            )
        h, w = self.synthetic_hw
        if h < 32 or w < 32:
            raise ValueError(f"synthetic_hw: expected a height and width of at least 32, got {list(self.synthetic_hw)}")
        if self.synthetic_balance_pct is not None and not 0.0 <= self.synthetic_balance_pct < 50.0:
            raise ValueError(
                f"synthetic_balance_pct: expected a percentage in [0, 50), got {self.synthetic_balance_pct}"
            )
        if self.post_lambda < 0:
            raise ValueError(f"post_lambda: expected >= 0, got {self.post_lambda}")


@dataclass(frozen=True)
class StudyConfig:
    """A whole study."""

    train: str = ""
    """The training config every arm starts from (a path; relative paths are relative to the study file)."""
    arms: tuple[ArmConfig, ...] = field(default_factory=_paper_arms)
    jobs: int = 1
    """Arms trained at the same time (separate processes)."""
    threads_per_job: int = 0
    """torch/OpenMP threads of each arm's process (0 = the library default)."""
    eval: StudyEvalConfig = field(default_factory=StudyEvalConfig)

    def __post_init__(self) -> None:
        if not self.train:
            raise ValueError("train: expected the path of a training config (e.g. train-small-cpu.yaml)")
        names = [a.name for a in self.arms]
        if not names or len(set(names)) != len(names):
            raise ValueError(f"arms: expected at least one arm and unique names, got {names}")
        if self.jobs < 1:
            raise ValueError(f"jobs: expected >= 1, got {self.jobs}")
        if self.threads_per_job < 0:
            raise ValueError(f"threads_per_job: expected >= 0, got {self.threads_per_job}")


def load_study(path: str | Path) -> tuple[StudyConfig, TrainConfig]:
    """Load a study config and the training config it names (resolved relative to the study file)."""
    path = Path(path)
    study = load_yaml(StudyConfig, path)
    train_path = Path(study.train)
    if not train_path.is_absolute():
        train_path = path.parent / train_path
    return study, load_yaml(TrainConfig, train_path)


def arm_config(base: TrainConfig, arm: ArmConfig, study_dir: str | Path) -> TrainConfig:
    """The training config of ``arm``: ``base`` with only the stages and the output folder replaced."""
    return merge(
        base,
        {"data": {"synthesis": {"stages": list(arm.stages)}}, "out": str(Path(study_dir) / "models" / arm.name)},
        where=f"study arm {arm.name}",
    )


def arm_finished(config: TrainConfig) -> bool:
    """True when the arm's run wrote a summary with all its steps done."""
    summary = Path(config.out) / "summary.json"
    if not summary.is_file():
        return False
    try:
        s = json.loads(summary.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        return False
    return int(s.get("steps_done", -1)) >= int(s.get("total_steps", 1 << 62))


WALL_FILE = "study_wall.json"
"""Per arm: training wall seconds summed over all invocations (resumed runs add up)."""


def _add_wall_seconds(arm_dir: Path, seconds: float) -> None:
    path = arm_dir / WALL_FILE
    total = 0.0
    if path.is_file():
        try:
            total = float(json.loads(path.read_text(encoding="utf-8"))["wall_s"])
        except (OSError, ValueError, KeyError, TypeError):
            total = 0.0
    write_text_atomic(path, json.dumps({"wall_s": total + seconds}) + "\n")


@dataclass
class ArmRun:
    """What happened to one arm in this invocation."""

    name: str
    status: str
    """``done`` (already finished), ``trained``, or ``failed``."""
    seconds: float = 0.0
    error: str | None = None


def train_arms(
    study: StudyConfig,
    base: TrainConfig,
    study_dir: str | Path,
    *,
    on_event: Callable[[str], None] | None = None,
    python: str = sys.executable,
) -> list[ArmRun]:
    """Train every unfinished arm (``study.jobs`` at a time) as ``murk train`` subprocesses.

    Each arm's full training config is written to ``<study>/configs/<arm>.yaml`` first. A failed arm is
    reported (its ``train.out`` holds the traceback) and the others go on.
    """
    study_dir = Path(study_dir)
    make_output_folder(study_dir / "configs", "study folder")
    say = on_event or (lambda _m: None)
    runs: dict[str, ArmRun] = {}
    pending: list[tuple[ArmConfig, TrainConfig, Path]] = []
    for arm in study.arms:
        cfg = arm_config(base, arm, study_dir)
        cfg_path = study_dir / "configs" / f"{arm.name}.yaml"
        write_text_atomic(cfg_path, dump_yaml(cfg))
        if arm_finished(cfg):
            runs[arm.name] = ArmRun(arm.name, "done")
            say(f"{arm.name}: already trained ({cfg.out})")
        else:
            pending.append((arm, cfg, cfg_path))
    env = dict(os.environ)
    if study.threads_per_job > 0:
        env["OMP_NUM_THREADS"] = env["MKL_NUM_THREADS"] = str(study.threads_per_job)
    active: list[tuple[ArmConfig, subprocess.Popen, float, Any]] = []
    with TerminateAsExit():
        _run_arms(pending, active, runs, study, study_dir, python, env, say)
    return [runs[a.name] for a in study.arms]


def _run_arms(
    pending: list[tuple[ArmConfig, Any, Path]],
    active: list[tuple[ArmConfig, subprocess.Popen, float, Any]],
    runs: dict[str, ArmRun],
    study: StudyConfig,
    study_dir: Path,
    python: str,
    env: dict[str, str],
    say: Callable[[str], None],
) -> None:
    """Start pending arms (``study.jobs`` at a time) and collect them; on any exit (Ctrl+C, SIGTERM, an
    exception) the running arms are stopped. Each arm also gets SIGTERM if this process is killed outright."""
    try:
        while pending or active:
            while pending and len(active) < study.jobs:
                arm, cfg, cfg_path = pending.pop(0)
                out = Path(cfg.out)
                make_output_folder(out)
                cmd = [python, "-m", "murk", "train", "--config", str(cfg_path), "--quiet"]
                if (out / "latest.pt").is_file():
                    cmd.append("--resume")
                log = open(out / "train.out", "a", encoding="utf-8")
                log.write(f"$ {' '.join(cmd)}\n")
                log.flush()
                proc = subprocess.Popen(
                    cmd, stdout=log, stderr=subprocess.STDOUT, env=env, preexec_fn=subprocess_dies_with_parent()
                )
                active.append((arm, proc, time.perf_counter(), log))
                say(f"{arm.name}: training ({'resumed' if '--resume' in cmd else 'started'}), log {out / 'train.out'}")
            time.sleep(0.5)
            still = []
            for arm, proc, t0, log in active:
                code = proc.poll()
                if code is None:
                    still.append((arm, proc, t0, log))
                    continue
                log.close()
                dt = time.perf_counter() - t0
                _add_wall_seconds(study_dir / "models" / arm.name, dt)
                if code == 0:
                    runs[arm.name] = ArmRun(arm.name, "trained", dt)
                    say(f"{arm.name}: trained in {dt / 60:.1f} min")
                else:
                    err = f"murk train exited with {code}; see {study_dir / 'models' / arm.name / 'train.out'}"
                    runs[arm.name] = ArmRun(arm.name, "failed", dt, err)
                    say(f"{arm.name}: FAILED ({err})")
            active = still
    finally:  # interrupted (Ctrl+C, an exception): no arm keeps training behind the user's back
        for _arm, proc, _t0, log in active:
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    proc.kill()
            log.close()
