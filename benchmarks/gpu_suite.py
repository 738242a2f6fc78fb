"""Every GPU claim of BENCHMARKS.md, measured by one command in one short GPU window (at most 8 minutes).

Run it from the repository root on the machine with the GPU; it needs nothing beyond murk's source tree and the
packages such a machine has (torch with CUDA, numpy, opencv-python-headless, scikit-image, typer, rich, pyyaml;
pytest for the ``pytest_gpu`` part only, skipped with a note when absent)::

    make gpu-suite                                          # = PYTHONPATH=src python3 benchmarks/gpu_suite.py
    PYTHONPATH=src python3 benchmarks/gpu_suite.py --out DIR [--parts jointid_base,train]
    PYTHONPATH=src python3 benchmarks/gpu_suite.py --cpu-dry-run --out /tmp/dry    # the same code, CPU, tiny sizes
    python3 benchmarks/merge_gpu_suite.py gpu-suite/gpu_suite.json                  # figures -> BENCHMARKS.md

It writes three files into ``--out`` (default ``gpu-suite/``): ``gpu_suite.json`` (every figure with the
baseline measured in the same run, machine, versions, date, status of every part), ``gpu_suite.md`` (the same
as tables) and ``gpu_suite.log`` (each part's output, its last 200 KB), rewritten after every part.

Parts, in the order they run, with their budgets in seconds (``--list`` prints them): see ``PARTS``. Each figure's
baseline is measured in the same process: the official Joint-ID configuration (fp32 eager, NCHW) for inference,
fp32 batch 7 (the official trainer's) for training, murk's numpy path on one CPU core for synthesis, snow,
metrics, ``post`` and scenes, the plain training step for DDP.

The watchdog: every part runs in its own Python process (this script with ``--part NAME``), started in a new
session; when the part's budget runs out the whole process group is killed (SIGKILL), the part is recorded as
``timeout`` and the suite goes on. A process per part rather than budget checks between iterations, because:

- a hung CUDA kernel, NCCL collective or torch.compile/Triton build never returns control to Python, so a check
  between iterations would never run; killing the process always works, and the driver frees its GPU memory;
- a CUDA error (an illegal access, an out-of-memory during graph capture) can leave a process's CUDA context
  unusable: a fresh process keeps one failure from spoiling the parts after it;
- the benchmark modules pin threads and the allocator at import for their one-core baselines: that stays local.

The cost is the start of an interpreter, the imports and the CUDA initialisation per part: 2-5 s, about 40 s of
the 8 minutes. (The dry run saves most of it: its parts are forked, each in a new session, from a server process
that imported torch once, ``--fork-server``; the watchdog kills a forked part's process group the same way.)
Within a part the budget is also checked between measurements (``Recorder.attempt``: a
torch.compile shape that no longer fits is skipped and recorded, not half-run), and every figure is saved as soon
as it is measured, so a part killed at its budget keeps what it had. Overall, a part starts only with at least
``MIN_PART_S`` of the suite's limit left and never gets more than what is left.

``--cpu-dry-run`` runs the same parts and the same functions on the CPU at tiny sizes (a minimal Joint-ID
configuration of the same structure, 64x96 frames, batches of 2-4, two timed calls after one warm-up, one training
step after one warm-up), each part on one thread (``DRY_ENV``) and forked from the server above: the CUDA-graph
figures and the NCCL step are recorded as skipped with the reason (``Recorder.skip``; DDP runs over gloo instead,
same code), so is each GPU test that skips on the CPU, and ``torch.compile`` compiles one
shape with inductor's C++ backend, built as one file without optimisation (``TORCHINDUCTOR_CPP_WRAPPER=1``,
``TORCHINDUCTOR_DEBUG_COMPILE=1``, ``TORCHINDUCTOR_VEC_ISA_OK=0``; measured on the loaded 2-core development box:
about 25 s to compile, against 65 s with the default flags for the same network, 170 s for the tiny variant); it
needs a C++ compiler, and fails as a part without one. The whole dry run costs about 35 s of CPU time with
inductor's cache warm and 57 s with it empty (each part's ``cpu_s`` in the report; BENCHMARKS.md has timings).
The figures of a dry run are not GPU figures; ``merge_gpu_suite.py`` refuses them.
``tests/benchmarks/test_gpu_suite.py`` runs the dry run in CI.

The suite process itself never imports torch (so never touches the GPU): machine and GPU details come from a
child process too.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import importlib.util
import json
import os
import platform
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
if (ROOT / "src" / "murk").is_dir() and str(ROOT / "src") not in sys.path:
    sys.path.insert(0, str(ROOT / "src"))  # run from the source tree without installing
sys.path.insert(0, str(HERE))

from _common import Recorder  # noqa: E402

LIMIT_S = 480.0
"""The suite's wall-time limit on the GPU (8 minutes)."""
RESERVE_S = 10.0
"""Kept back from the limit for writing the outputs."""
MIN_PART_S = 15.0
"""A part starts only if at least this much of the limit is left."""
DRY_LIMIT_S = 1200.0
DRY_BUDGET_FACTOR = 3.0
DRY_MIN_BUDGET_S = 300.0
"""The dry run's limits are generous (its timings mean nothing; a loaded 2-core machine can be 10x slower than
a quiet one): a part gets ``max(DRY_BUDGET_FACTOR * budget, DRY_MIN_BUDGET_S)``, so only a hang trips them."""
LOG_TAIL_BYTES = 200_000
OUTPUT_FILES = ("gpu_suite.json", "gpu_suite.md", "gpu_suite.log")
ALLOWED_DISTRIBUTIONS = (
    "torch",
    "numpy",
    "opencv-python-headless",
    "scikit-image",
    "typer",
    "rich",
    "pyyaml",
    "onnxruntime",
)
"""What the GPU machine has. A part may import these and their dependencies, nothing else (checked per part)."""


NO_REASON = "no reason given"
"""The reason recorded for a skipped test without one (the CPU dry run's test fails on it)."""


class PartSkipped(Exception):
    """Raised by a part that cannot run here (a missing package or model); the message is the note."""


@dataclass
class Ctx:
    """What a part gets: the device, the recorder of its figures, free-form details, a scratch folder."""

    dry: bool
    device: Any
    rec: Recorder
    scratch: Path
    details: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Part:
    name: str
    title: str
    section: str
    """The BENCHMARKS.md section whose GPU block receives the figures (``merge_gpu_suite.py``)."""
    budget_s: float
    run: Callable[[Ctx], None]
    needs: tuple[str, ...] = ()
    """Modules the part needs: when one is not installed the part is skipped with a note (checked before start)."""
    dry_env: tuple[tuple[str, str], ...] = ()
    """Environment of the part's process in the dry run only."""


# ---------------------------------------------------------------------------------------------------------------
# sizes: the GPU run and the dry run go through the same functions, with these arguments


def _dry_config() -> Any:
    """The dry run's Joint-ID: the base structure (4 stages, attention, decoder, both heads) at minimal widths."""
    from murk.models.jointid import JointIDConfig

    return JointIDConfig(
        embed_dims=(8, 16, 32, 64), depths=(1, 1, 1, 1), num_heads=(1, 1, 2, 4), decoder_blocks=1, decoder_dim=16
    )


def _base_model(ctx: Ctx) -> Any:
    """The base Joint-ID (random weights, seed 0); in the dry run :func:`_dry_config`."""
    import torch

    from murk.models.jointid import build_jointid

    torch.manual_seed(0)
    return build_jointid(_dry_config() if ctx.dry else "base")


def _inference_sizes(ctx: Ctx) -> dict[str, Any]:
    if ctx.dry:
        return {"hw": (64, 96), "large_hw": (96, 160), "batches": (2, 4), "repeats": 2, "warmup": 1}
    return {"hw": (288, 512), "large_hw": (1088, 1920), "batches": (8, 16, 32, 64), "repeats": 20, "warmup": 3}


def _train_model(ctx: Ctx) -> Any:
    return _dry_config() if ctx.dry else "base"


# ---------------------------------------------------------------------------------------------------------------
# the parts


def part_pytest_gpu(ctx: Ctx) -> None:
    """``pytest -m gpu`` on the test files that have GPU tests (on the CPU they skip)."""
    import xml.etree.ElementTree as ET

    files = sorted(
        str(p.relative_to(ROOT))
        for p in (ROOT / "tests").rglob("test_*.py")
        if "pytest.mark.gpu" in p.read_text(encoding="utf-8")
    )
    if not files:
        raise PartSkipped("no test file has a pytest.mark.gpu test")
    junit = ctx.scratch / "junit.xml"
    cmd = [sys.executable, "-m", "pytest", "-m", "gpu", "-q", "-p", "no:cacheprovider", f"--junitxml={junit}", *files]
    proc = subprocess.run(
        cmd, cwd=ROOT, capture_output=True, text=True, timeout=max(5.0, ctx.rec.left_s()), env=_child_env()
    )
    print(proc.stdout[-20000:], proc.stderr[-5000:], sep="\n", flush=True)
    if not junit.is_file():
        raise RuntimeError(f"pytest exited with {proc.returncode} without a report: {proc.stdout[-500:]}")
    counts = {"passed": 0, "failed": 0, "skipped": 0}
    for case in ET.parse(junit).getroot().iter("testcase"):
        name = f"{case.get('classname')}::{case.get('name')}"
        bad = case.find("failure") if case.find("failure") is not None else case.find("error")
        if bad is not None:
            counts["failed"] += 1
            ctx.rec.problem(name, "failed", (bad.get("message") or "")[:300])
        elif (skipped := case.find("skipped")) is not None:
            counts["skipped"] += 1
            ctx.rec.skip(name, (skipped.get("message") or skipped.text or "").strip() or NO_REASON)
        else:
            counts["passed"] += 1
    ctx.details.update(counts, files=files, exit_code=proc.returncode)
    ctx.rec.note(f"pytest -m gpu: {counts['passed']} passed, {counts['failed']} failed, {counts['skipped']} skipped")
    if proc.returncode != 0 and not counts["failed"]:
        raise RuntimeError(f"pytest exited with {proc.returncode}: {proc.stdout[-500:]}")


def part_jointid_base(ctx: Ctx) -> None:
    """Base Joint-ID inference: batch-1 latency (eager, CUDA graph), batches up to 64, 1088x1920, bf16 PSNR."""
    import bench_jointid

    ctx.rec.note("random weights (seed 0): speed as with trained weights; the bf16 PSNR is indicative")
    bench_jointid.gpu_figures(
        ctx.rec, _base_model(ctx), ctx.device, mode="eager", targets=not ctx.dry, **_inference_sizes(ctx)
    )


def part_jointid_base_compile(ctx: Ctx) -> None:
    """Base Joint-ID with torch.compile (+ CUDA graph): batch 8, 64, 1 and 1088x1920 (each shape compiles)."""
    import bench_jointid

    sizes = _inference_sizes(ctx)
    if ctx.dry:
        ctx.rec.note("dry run: one compiled shape (batch 1); each further shape compiles again")
        extra: dict[str, Any] = {"compile_batches": (1,), "compile_large": False, "compile_need_s": 0.0}
    else:
        extra = {"compile_need_s": 35.0}
    bench_jointid.gpu_figures(
        ctx.rec, _base_model(ctx), ctx.device, mode="compile", targets=not ctx.dry, **sizes, **extra
    )


def part_train(ctx: Ctx) -> None:
    """Base Joint-ID training step at 288x512: fp32 batch 7 (official), bf16 batch 7 and 32; synthesis share."""
    import bench_train

    if ctx.dry:
        bench_train.gpu_figures(
            ctx.rec,
            ctx.device,
            variant=_train_model(ctx),
            hw=(64, 96),
            configs=((2, "fp32"), (2, "bf16"), (3, "bf16")),
            steps=1,
            warmup=1,
            targets=False,
        )
    else:
        bench_train.gpu_figures(ctx.rec, ctx.device, steps=20, need_s=12.0)


def part_synth(ctx: Ctx) -> None:
    """Batched synthesis (Eqs. 1-6) on the device against numpy on one core."""
    import bench_synth  # pins one core at import (the baseline's setting)

    if ctx.dry:
        bench_synth.gpu_figures(ctx.rec, ctx.device, batches=(4,), hw=(64, 80), repeats=3, targets=False)
    else:
        bench_synth.gpu_figures(ctx.rec, ctx.device)


def part_snow(ctx: Ctx) -> None:
    """Batched marine-snow compositing (Eqs. 7-8) on the device against numpy on one core."""
    import bench_snow  # pins one core at import
    import numpy as np

    from murk.data import default_snow_bank
    from murk.snow.bank import load_bank

    hw, n, batches, repeats = ((64, 80), 50, (4,), 2) if ctx.dry else ((480, 640), 1600, (64, 256), 5)
    image = np.random.default_rng(0).random((*hw, 3)).astype(np.float32)
    bench_snow.gpu_figures(
        ctx.rec, ctx.device, image, load_bank(default_snow_bank()), n_particles=n, batches=batches, repeats=repeats
    )


def part_metrics(ctx: Ctx) -> None:
    """Batched UIQM/UCIQE on the device against numpy on one core (a real 640x480 photo)."""
    import bench_metrics  # one thread at import
    import cv2

    from murk.io import read_image

    rgb, _ = read_image(bench_metrics.IMAGE)
    if ctx.dry:
        rgb = cv2.resize(rgb, (80, 64), interpolation=cv2.INTER_AREA)
        bench_metrics.gpu_figures(ctx.rec, ctx.device, rgb, batch=2, repeats=3, targets=False)
    else:
        bench_metrics.gpu_figures(ctx.rec, ctx.device, rgb)


def part_post(ctx: Ctx) -> None:
    """Batched ``post`` (Eq. 9) on the device, on-device and numpy in/out, against one CPU core."""
    import bench_enhance
    from _common import pin_one_core

    pin_one_core()
    if ctx.dry:
        bench_enhance.gpu_figures(ctx.rec, ctx.device, sizes={"96x64": (64, 96)}, batches=(1, 2), seconds=0.05)
    else:
        bench_enhance.gpu_figures(ctx.rec, ctx.device, seconds=0.5)


def part_scenes(ctx: Ctx) -> None:
    """Batched procedural scenes on the device against numpy on one core."""
    import bench_scenes
    from _common import pin_one_core

    pin_one_core()
    if ctx.dry:
        bench_scenes.gpu_figures(ctx.rec, ctx.device, count=3, size=(80, 64), batches=(2,), reps=1)
    else:
        bench_scenes.gpu_figures(ctx.rec, ctx.device)


def part_jointid_small(ctx: Ctx) -> None:
    """The shipped small Joint-ID: the same inference figures, and its training step (bf16 batch 32 vs fp32 7)."""
    import bench_jointid
    import bench_train

    from murk.data import shipped_jointid_weights
    from murk.models.jointid import load_checkpoint

    model = load_checkpoint(shipped_jointid_weights())
    bench_jointid.gpu_figures(ctx.rec, model, ctx.device, mode="eager", targets=False, **_inference_sizes(ctx))
    if ctx.dry:
        bench_train.gpu_figures(
            ctx.rec,
            ctx.device,
            variant="small",
            hw=(64, 96),
            configs=((2, "fp32"), (2, "bf16")),
            steps=1,
            warmup=1,
            targets=False,
        )
    else:
        bench_train.gpu_figures(
            ctx.rec,
            ctx.device,
            variant="small",
            configs=((7, "fp32"), (32, "bf16")),
            steps=10,
            need_s=8.0,
            targets=False,
        )


def part_jointid_lite(ctx: Ctx) -> None:
    """The lite network (when ``murk.models.lite`` exists): restorer frames/s against the shipped small Joint-ID."""
    import torch
    from _common import Figure, device_sync, median_s

    from murk.enhance.restorer import create, weights_used

    sizes = _inference_sizes(ctx)
    reps, warmup = sizes["repeats"], (1 if ctx.dry else 2)
    sync = device_sync(ctx.device)
    try:
        lite = create("lite", device=str(ctx.device))
        ctx.rec.note(f"lite weights: {weights_used(lite).weights}")
    except ValueError as exc:  # no shipped weights yet: time the same network with random weights
        from murk.enhance.lite_restorer import LiteRestorer
        from murk.models.lite.network import build_lite

        torch.manual_seed(0)
        lite = LiteRestorer(build_lite(), device=ctx.device)
        print(f"create('lite'): {exc}", flush=True)
        ctx.rec.note("no shipped lite weights: random weights (seed 0), which run at the trained network's speed")
    ctx.rec.note("the lite network's training step is not measured (bench_train measures Joint-ID)")
    # The shipped small Joint-ID network, fp32, without the refine step or the lite blend after it: the network
    small = create("jointid", device=str(ctx.device), refine=0.0, lite_blend=0.0)
    for (h, w), batch in ((sizes["hw"], 1), (sizes["hw"], sizes["batches"][0]), (sizes["large_hw"], 1)):
        x = torch.rand(batch, 3, h, w, device=ctx.device, generator=torch.Generator(ctx.device).manual_seed(batch))
        t_small = ctx.rec.attempt(
            f"small Joint-ID {h}x{w} batch {batch}",
            lambda x=x: median_s(lambda: small.restore_tensor(x), repeats=reps, warmup=warmup, sync=sync),
        )
        t_lite = ctx.rec.attempt(
            f"lite {h}x{w} batch {batch}",
            lambda x=x: median_s(lambda: lite.restore_tensor(x), repeats=reps, warmup=warmup, sync=sync),
        )
        if t_lite is not None:
            base = f"shipped small Joint-ID fp32, {h}x{w} batch {batch}"
            ref = None if t_small is None else batch / t_small
            ctx.rec.add(
                Figure(
                    f"lite_{h}x{w}_b{batch}_img_s",
                    f"lite restorer, {h}x{w} batch {batch}",
                    batch / t_lite,
                    "img/s",
                    base,
                    ref,
                )
            )


def part_ddp(ctx: Ctx) -> None:
    """One DistributedDataParallel training step over NCCL (world size 1, one GPU) against the plain step."""
    import bench_train
    import torch
    import torch.distributed as dist
    from _common import Figure

    if ctx.dry:
        backend = "gloo"
        ctx.rec.skip("DDP nccl step", "NCCL needs CUDA: the dry run runs the same DDP step over gloo")
    else:
        if not dist.is_available() or not dist.is_nccl_available():
            raise PartSkipped(f"torch {torch.__version__} has no NCCL")
        backend = "nccl"
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    os.environ.update(MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port), RANK="0", WORLD_SIZE="1", LOCAL_RANK="0")
    dev = torch.device(ctx.device)
    if dev.type == "cuda":
        torch.cuda.set_device(dev)
    dist.init_process_group(backend, rank=0, world_size=1)
    try:
        variant, hw, batch, steps = (_train_model(ctx), (64, 96), 2, 1) if ctx.dry else ("base", (288, 512), 7, 6)
        warmup = 1 if ctx.dry else 2
        ids = [dev.index or 0] if dev.type == "cuda" else None
        plain = ctx.rec.attempt(
            "plain step", lambda: bench_train.measure(variant, hw, batch, "bf16", dev, steps, warmup=warmup)
        )
        ddp = ctx.rec.attempt(
            f"DDP {backend} step",
            lambda: bench_train.measure(
                variant,
                hw,
                batch,
                "bf16",
                dev,
                steps,
                wrap=lambda m: torch.nn.parallel.DistributedDataParallel(m, device_ids=ids),
                warmup=warmup,
            ),
        )
        name = variant if isinstance(variant, str) else "custom"
        label = f"{name} {hw[0]}x{hw[1]} bf16 batch {batch}"
        if ddp is not None:
            base = None if plain is None else plain["img_s"]
            ctx.rec.add(
                Figure(
                    "ddp_img_s",
                    f"DDP ({backend}, world size 1) training step, {label}",
                    ddp["img_s"],
                    "img/s",
                    f"plain training step, {label}",
                    base,
                )
            )
    finally:
        dist.destroy_process_group()


DRY_ENV = (("OMP_NUM_THREADS", "1"), ("MKL_NUM_THREADS", "1"))
"""Environment of every part's process in the dry run: one thread. Its timings mean nothing, and on a shared
2-core machine torch's default of 2 OpenMP threads per process makes every small operation wait for a thread
that another process has the core of (measured on the loaded dev box, 2026-12-03: the ``jointid_small`` part took
64-104 s with 2 threads and 12 s with one)."""

_INDUCTOR_DRY = (
    ("TORCHINDUCTOR_CPP_WRAPPER", "1"),
    ("TORCHINDUCTOR_DEBUG_COMPILE", "1"),
    ("TORCHINDUCTOR_VEC_ISA_OK", "0"),
    ("TORCHINDUCTOR_COMPILE_THREADS", "1"),
)

PARTS: tuple[Part, ...] = (
    Part("pytest_gpu", "pytest -m gpu (CUDA = CPU, CUDA graph = eager, bf16 within 40 dB of fp32)", "gpu-suite", 40,
         part_pytest_gpu, needs=("pytest",)),
    Part("jointid_base", "Joint-ID base inference, eager and CUDA graph", "jointid", 70, part_jointid_base),
    Part("jointid_base_compile", "Joint-ID base inference, torch.compile", "jointid", 120, part_jointid_base_compile,
         dry_env=_INDUCTOR_DRY),
    Part("train", "Joint-ID base training step with online synthesis", "train", 55, part_train),
    Part("synth", "synthesis, Eqs. (1)-(6), batched torch", "synth", 15, part_synth),
    Part("snow", "marine snow, Eqs. (7)-(8), batched torch", "snow", 20, part_snow),
    Part("metrics", "UIQM / UCIQE, batched torch", "metrics", 15, part_metrics),
    Part("post", "post (Eq. 9), batched torch", "enhance", 20, part_post),
    Part("scenes", "procedural scenes, batched torch", "scenes", 20, part_scenes),
    Part("jointid_small", "shipped small Joint-ID: inference and training step", "jointid", 30, part_jointid_small),
    Part("jointid_lite", "lite network inference", "jointid", 20, part_jointid_lite, needs=("murk.models.lite",)),
    Part("ddp", "DDP training step over NCCL", "train", 30, part_ddp),
)  # fmt: skip


def _selftest_ok(ctx: Ctx) -> None:
    from _common import Figure

    ctx.rec.add(Figure("one", "self-test figure", 1.0, "ms"))


def _selftest_fail(ctx: Ctx) -> None:
    raise RuntimeError("self-test failure")


def _selftest_hang(ctx: Ctx) -> None:
    """Measures one figure, starts a child process, then hangs: the watchdog must kill both, keep the figure."""
    from _common import Figure

    ctx.rec.add(Figure("before_hang", "figure measured before the hang", 2.0, "ms"))
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    ctx.rec.note(f"grandchild pid {child.pid}")
    time.sleep(3600)


SELFTEST_PARTS = (
    Part("_selftest_ok", "self-test: one figure", "selftest", 20, _selftest_ok),
    Part("_selftest_fail", "self-test: raises", "selftest", 20, _selftest_fail),
    Part("_selftest_hang", "self-test: hangs", "selftest", 2, _selftest_hang),
)
"""Parts that test the suite's watchdog (``--parts _selftest_hang,...``; never run by default)."""
PARTS_BY_NAME = {p.name: p for p in (*PARTS, *SELFTEST_PARTS)}


# ---------------------------------------------------------------------------------------------------------------
# inside a part's process


def _child_env() -> dict[str, str]:
    """This environment with ``src`` on PYTHONPATH (for processes started by a part)."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), *filter(None, [env.get("PYTHONPATH")])])
    return env


def _write_json(path: Path, data: dict[str, Any]) -> None:
    from murk.io.atomic import write_text_atomic

    write_text_atomic(path, json.dumps(data, indent=1, default=str) + "\n")


def _installed_modules() -> dict[str, bool] | None:
    """Top-level modules of the installed distributions -> whether ``ALLOWED_DISTRIBUTIONS`` or what they require
    (from the installed metadata; extras excluded) provide them; None when the metadata cannot tell."""
    from importlib import metadata

    def canon(name: str) -> str:
        return re.sub(r"[-_.]+", "-", name).lower()

    closure: set[str] = set()
    todo = list(ALLOWED_DISTRIBUTIONS)
    while todo:
        name = canon(todo.pop())
        if name in closure:
            continue
        closure.add(name)
        try:
            requires = metadata.distribution(name).requires or []
        except metadata.PackageNotFoundError:
            continue
        todo += [re.split(r"[\s;<>=!~\[(]", r.strip(), maxsplit=1)[0] for r in requires if "extra ==" not in r]
    try:
        by_module = metadata.packages_distributions()
    except Exception:
        return None
    return {mod: any(canon(d) in closure for d in dists) for mod, dists in by_module.items()}


def foreign_imports(before: set[str]) -> list[str]:
    """Top-level packages imported since ``before`` that come from an installed distribution the GPU machine may
    lack (not in ``ALLOWED_DISTRIBUTIONS`` or their requirements). Modules of no distribution (the standard
    library, murk and these scripts from the source tree, Cython's runtime modules) are not counted."""
    installed = _installed_modules()
    if installed is None:
        return []
    now = {m.split(".")[0] for m in list(sys.modules)} - {m.split(".")[0] for m in before}
    local = {"murk", "_common", "gpu_suite", *(p.stem for p in HERE.glob("bench_*.py"))}
    suspects = [m for m in now if installed.get(m) is False and m not in local and m not in sys.stdlib_module_names]
    # vendored inside an allowed package (setuptools/_vendor/jaraco, ...): present wherever that package is
    roots = [_module_dir(m) for m, ok in installed.items() if ok and m in sys.modules]
    return sorted(m for m in suspects if not any(r and _module_dir(m) and r in _module_dir(m).parents for r in roots))


def _module_dir(name: str) -> Path | None:
    mod = sys.modules.get(name)
    f = getattr(mod, "__file__", None)
    if f:
        return Path(f).resolve().parent
    paths = list(getattr(mod, "__path__", None) or [])  # a namespace package
    return Path(paths[0]).resolve() if paths else None


def run_part(name: str, result_path: Path, budget_s: float, dry: bool) -> int:
    """Run one part in this process, saving its result after every figure; 0 when it ran to its end."""
    before = set(sys.modules)
    started = time.monotonic()
    state: dict[str, Any] = {"part": name, "finished": False}
    rec = Recorder(deadline=started + budget_s - 3.0)
    details: dict[str, Any] = {}

    def save(_: object = None) -> None:
        state.update(
            figures=[f.to_dict() for f in rec.figures],
            problems=rec.problems,
            notes=rec.notes,
            attempt_s=rec.attempt_s,
            details=details,
            wall_s=round(time.monotonic() - started, 2),
        )
        _write_json(result_path, state)

    rec.on_change = save
    rc = 0
    try:
        import torch

        device = torch.device("cpu" if dry else "cuda")
        with tempfile.TemporaryDirectory(prefix=f"gpu-suite-{name}-") as scratch:
            PARTS_BY_NAME[name].run(Ctx(dry, device, rec, Path(scratch), details))
        state["finished"] = True
    except PartSkipped as exc:
        state.update(finished=True, skipped=str(exc))
    except BaseException as exc:  # recorded for the report; the exit code tells the suite
        traceback.print_exc()
        state["error"] = f"{type(exc).__name__}: {str(exc).strip()[:1000]}"
        rc = 1
    state["foreign_imports"] = foreign_imports(before)
    save()
    return rc


def machine_info(dry: bool) -> dict[str, Any]:
    """The machine, versions and GPU, gathered in a child process (a wedged driver cannot hang the suite)."""
    import cv2
    import numpy as np
    import torch

    from murk import __version__

    info: dict[str, Any] = {
        "host": platform.node(),
        "platform": platform.platform(),
        "cpu": _cpu_model(),
        "cpus": os.cpu_count(),
        "load_average": [round(v, 2) for v in os.getloadavg()] if hasattr(os, "getloadavg") else None,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "opencv": cv2.__version__,
        "torch": torch.__version__,
        "cuda": torch.version.cuda,
        "murk": __version__,
        "git": _git_commit(),
        "gpu": None,
    }
    if not dry and torch.cuda.is_available():
        props = torch.cuda.get_device_properties(0)
        info["gpu"] = {
            "name": props.name,
            "count": torch.cuda.device_count(),
            "memory_gib": round(props.total_memory / 2**30, 1),
            "capability": f"{props.major}.{props.minor}",
            "multiprocessors": props.multi_processor_count,
            "driver": _nvidia_smi("driver_version"),
        }
        info["cudnn"] = torch.backends.cudnn.version()
        with contextlib.suppress(Exception):
            v = torch.cuda.nccl.version()
            info["nccl"] = ".".join(str(x) for x in v) if isinstance(v, tuple) else str(v)
    return info


def _cpu_model() -> str:
    with contextlib.suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine()


def _git_commit() -> str | None:
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        head = subprocess.run(
            ["git", "rev-parse", "--short=12", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=10
        )
        if head.returncode == 0:
            dirty = subprocess.run(
                ["git", "status", "--porcelain", "--untracked-files=no"],
                cwd=ROOT,
                capture_output=True,
                text=True,
                timeout=10,
            ).stdout.strip()
            return head.stdout.strip() + (" (with uncommitted changes)" if dirty else "")
    return None


def _nvidia_smi(field_name: str) -> str | None:
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        out = subprocess.run(
            ["nvidia-smi", f"--query-gpu={field_name}", "--format=csv,noheader"],
            capture_output=True,
            text=True,
            timeout=15,
        )
        if out.returncode == 0 and out.stdout.strip():
            return out.stdout.strip().splitlines()[0]
    return None


# ---------------------------------------------------------------------------------------------------------------
# the suite (parent process)


def _spawn(args: list[str], log: Path, timeout_s: float, env: dict[str, str]) -> tuple[int | None, float, float]:
    """Run this script with ``args`` in a new session; kill its process group after ``timeout_s``.
    Returns (exit code or None when killed, wall seconds, CPU seconds of the process and the children it waited
    for, such as the compiler: unlike the wall time, the same on a loaded machine as on an idle one)."""
    t0 = time.monotonic()
    cpu0 = _children_cpu_s()
    with open(log, "wb") as out:
        proc = subprocess.Popen(
            [sys.executable, str(Path(__file__).resolve()), *args],
            stdout=out,
            stderr=subprocess.STDOUT,
            cwd=ROOT,
            env=env,
            start_new_session=True,
        )
        rc: int | None = None
        try:
            rc = proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:  # the budget ran out: end the part's whole process group
            _kill_group(proc)
        except BaseException:  # the suite itself is interrupted (Ctrl-C, TERM): end the part too
            _kill_group(proc)
            raise
    return rc, time.monotonic() - t0, _children_cpu_s() - cpu0


def _children_cpu_s() -> float:
    import resource

    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _fork_server() -> int:
    """``--fork-server`` (the dry run's): import torch once, then for each request read from stdin (one JSON line:
    the part's arguments, log file and extra environment) fork a process that runs the part in a new session with
    its output in the log, and answer two JSON lines: ``{"pid": ...}`` at once, and ``{"rc": ..., "cpu_s": ...}``
    when it has ended (``rc`` None when a signal killed it; ``cpu_s`` includes the children it waited for)."""
    import torch  # noqa: F401  (imported once here: each forked part starts with it)

    for line in sys.stdin:
        req = json.loads(line)
        pid = os.fork()
        if pid == 0:  # the part's process
            rc = 1
            try:
                os.setsid()
                os.environ.update(req["env"])
                null = os.open(os.devnull, os.O_RDONLY)
                log = os.open(req["log"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
                os.dup2(null, 0)
                os.dup2(log, 1)
                os.dup2(log, 2)
                rc = main(req["args"])
            except BaseException:
                traceback.print_exc()
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os._exit(rc)
        print(json.dumps({"pid": pid}), flush=True)
        _, status, usage = os.wait4(pid, 0)
        code = os.waitstatus_to_exitcode(status)
        cpu = usage.ru_utime + usage.ru_stime
        print(json.dumps({"rc": code if code >= 0 else None, "cpu_s": cpu}), flush=True)
    return 0


class _ForkServer:
    """The parent's side of :func:`_fork_server`: runs parts like :func:`_spawn` (a new session per part, its whole
    process group killed at the budget), without starting an interpreter and importing torch for each."""

    def __init__(self, env: dict[str, str], log: Path) -> None:
        self._env, self._log = env, log
        self._proc: subprocess.Popen | None = None
        self._buf = b""
        self._part_pid: int | None = None

    def start(self) -> subprocess.Popen:
        """Start the server (again, if it ended); it imports torch meanwhile."""
        if self._proc is None or self._proc.poll() is not None:
            with open(self._log, "ab") as err:
                self._proc = subprocess.Popen(
                    [sys.executable, str(Path(__file__).resolve()), "--fork-server"],
                    stdin=subprocess.PIPE,
                    stdout=subprocess.PIPE,
                    stderr=err,
                    cwd=ROOT,
                    env=self._env,
                    start_new_session=True,
                )
            self._buf = b""
        return self._proc

    def _reply(self, timeout_s: float) -> dict[str, Any] | None:
        """The next JSON line from the server; None when ``timeout_s`` passed or the server ended."""
        import select

        assert self._proc is not None and self._proc.stdout is not None
        fd = self._proc.stdout.fileno()
        end = time.monotonic() + timeout_s
        while b"\n" not in self._buf:
            left = end - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                return None
            chunk = os.read(fd, 4096)
            if not chunk:
                return None
            self._buf += chunk
        line, self._buf = self._buf.split(b"\n", 1)
        return json.loads(line)

    def run(
        self, args: list[str], log: Path, timeout_s: float, extra_env: dict[str, str]
    ) -> tuple[int | None, float, float]:
        """Like :func:`_spawn`: (exit code or None when killed, wall seconds, CPU seconds)."""
        t0 = time.monotonic()
        proc = self.start()
        assert proc.stdin is not None
        try:
            proc.stdin.write((json.dumps({"args": args, "log": str(log), "env": extra_env}) + "\n").encode())
            proc.stdin.flush()
            started = self._reply(60.0)
            if started is None:
                raise RuntimeError(f"the dry run's fork server did not start the part: {_tail(self._log, 600)}")
            self._part_pid = started["pid"]
            done = self._reply(timeout_s - (time.monotonic() - t0))
            if done is None:  # the budget ran out (or the server ended): end the part's whole process group
                server_ended = proc.poll() is not None
                self._kill_part()
                done = self._reply(30.0) or {"cpu_s": 0.0}
                done["rc"] = 1 if server_ended else None
            self._part_pid = None
        except BaseException:
            self.close()
            raise
        return done["rc"], time.monotonic() - t0, float(done.get("cpu_s") or 0.0)

    def _kill_part(self) -> None:
        if self._part_pid is not None:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self._part_pid, signal.SIGKILL)
            self._part_pid = None

    def close(self) -> None:
        """End the running part (if any) and the server."""
        self._kill_part()
        if self._proc is not None:
            _kill_group(self._proc)
            self._proc = None


def _kill_group(proc: subprocess.Popen) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()


def _tail(path: Path, n: int) -> str:
    if not path.is_file():
        return ""
    data = path.read_bytes()
    return data[-n:].decode("utf-8", errors="replace")


def _status(entry: dict[str, Any]) -> str:
    if entry.get("timed_out"):
        return "timeout"
    if entry.get("skipped"):
        return "skipped"
    if entry.get("error") or not entry.get("finished"):
        return "failed"
    kinds = {p["kind"] for p in entry.get("problems", []) if p["kind"] != "skipped"}  # cannot run here: not missing
    if "failed" in kinds:
        return "partial" if entry.get("figures") else "failed"
    return "partial" if kinds else "ok"


def run_suite(args: argparse.Namespace) -> int:
    dry = args.cpu_dry_run
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    names = [n.strip() for n in args.parts.split(",")] if args.parts else [p.name for p in PARTS]
    unknown = [n for n in names if n not in PARTS_BY_NAME]
    if unknown:
        print(f"--parts: unknown {unknown}; known: {', '.join(p.name for p in PARTS)}", file=sys.stderr)
        return 2
    limit = args.limit_s if args.limit_s is not None else (DRY_LIMIT_S if dry else LIMIT_S)
    started = time.monotonic()
    deadline = started + limit - RESERVE_S
    env = _child_env()
    report: dict[str, Any] = {
        "suite": "murk benchmarks/gpu_suite.py",
        "schema": 1,
        "mode": "cpu-dry-run" if dry else "gpu",
        "date": dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "limit_s": limit,
        "command": " ".join([Path(sys.executable).name, *sys.argv]),
        "machine": {},
        "parts": [],
    }
    log_path = out / "gpu_suite.log"
    log_path.write_text("")
    with tempfile.TemporaryDirectory(prefix="gpu-suite-") as tmp, contextlib.ExitStack() as stack:
        scratch = Path(tmp)
        server = _ForkServer({**env, **dict(DRY_ENV)}, scratch / "fork-server.log") if dry else None
        if server is not None:
            stack.callback(server.close)
            server.start()  # imports torch while the machine is described
        info_path = scratch / "machine.json"
        rc, _, _ = _spawn(
            ["--machine-info", str(info_path)] + (["--cpu-dry-run"] if dry else []), scratch / "m.log", 60.0, env
        )
        if rc == 0 and info_path.is_file():
            report["machine"] = json.loads(info_path.read_text())
        else:
            report["machine"] = {"error": _tail(scratch / "m.log", 2000) or "timed out"}
        if not dry and not report["machine"].get("gpu"):
            print(
                "no CUDA device here (or it did not answer): run with --cpu-dry-run to check the suite on the CPU",
                file=sys.stderr,
            )
            _append_log(log_path, "machine", scratch / "m.log")
            return 2
        print(f"murk GPU suite ({report['mode']}): {len(names)} parts, limit {limit:.0f} s, out {out}", flush=True)
        for i, name in enumerate(names, 1):
            part = PARTS_BY_NAME[name]
            budget = part.budget_s * (DRY_BUDGET_FACTOR if dry else 1.0)
            if dry and part in PARTS:  # (the self-test parts keep their short budgets)
                budget = max(budget, DRY_MIN_BUDGET_S)
            entry: dict[str, Any] = {"name": name, "title": part.title, "section": part.section, "budget_s": budget}
            missing = [m for m in part.needs if not _importable(m)]
            left = deadline - time.monotonic()
            if missing:
                entry["skipped"] = f"not installed: {', '.join(missing)}" + (
                    " (the lite network of issue 15 does not exist yet)" if "murk.models.lite" in missing else ""
                )
            elif left < MIN_PART_S:
                entry["skipped"] = f"the suite's limit: {max(left, 0):.0f} s left"
            else:
                timeout = min(budget, left)
                result_path = scratch / f"{name}.json"
                cmd = ["--part", name, "--result", str(result_path), "--budget", f"{timeout:.1f}"]
                if server is not None:
                    entry["env"] = {**dict(DRY_ENV), **dict(part.dry_env)}
                    run = server.run([*cmd, "--cpu-dry-run"], scratch / f"{name}.log", timeout, dict(part.dry_env))
                else:
                    run = _spawn(cmd, scratch / f"{name}.log", timeout, env)
                rc, wall, cpu = run
                result = json.loads(result_path.read_text()) if result_path.is_file() else {}
                entry.update(
                    result, timeout_s=round(timeout, 1), wall_s=round(wall, 2), cpu_s=round(cpu, 2), exit_code=rc
                )
                entry.pop("part", None)
                if rc is None:
                    entry.update(timed_out=True, error=f"killed at its budget ({timeout:.0f} s)")
                elif rc != 0 and not entry.get("error"):
                    entry["error"] = f"exit code {rc}: " + _tail(scratch / f"{name}.log", 600)
                _append_log(log_path, name, scratch / f"{name}.log")
            entry["status"] = _status(entry)
            report["parts"].append(entry)
            report["wall_s"] = round(time.monotonic() - started, 1)
            _write_outputs(out, report)
            why = entry.get("skipped") or entry.get("error") or ""
            print(
                f"[{i}/{len(names)}] {name}: {entry['status']} ({entry.get('wall_s', 0):.0f} s of {budget:.0f} s, "
                f"CPU {entry.get('cpu_s', 0):.0f} s), "
                f"{len(entry.get('figures', []))} figures{'; ' + why[:200] if why else ''}",
                flush=True,
            )
    print(render_markdown(report))
    bad = [p["name"] for p in report["parts"] if p["status"] not in ("ok", "skipped")]
    print(f"wall {report['wall_s']:.0f} s; " + (f"not complete: {', '.join(bad)}" if bad else "every part complete"))
    return 1 if bad else 0


def _importable(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def _append_log(log_path: Path, name: str, part_log: Path) -> None:
    text = _tail(part_log, LOG_TAIL_BYTES)
    with open(log_path, "a", encoding="utf-8") as f:
        f.write(f"\n===== {name} =====\n{text}\n")


def _write_outputs(out: Path, report: dict[str, Any]) -> None:
    from murk.io.atomic import write_text_atomic

    _write_json(out / "gpu_suite.json", report)
    write_text_atomic(out / "gpu_suite.md", render_markdown(report))


# ---------------------------------------------------------------------------------------------------------------
# Markdown


def _cell(v: Any) -> str:
    return str(v).replace("|", "\\|").replace("\n", " ")


def fmt_value(v: float | None) -> str:
    if v is None:
        return ""
    if abs(v) >= 1000:
        return f"{v:,.0f}"
    if abs(v) >= 100:
        return f"{v:.1f}"
    return f"{v:.3g}" if abs(v) >= 0.01 else f"{v:.2e}"


def figure_row(f: dict[str, Any]) -> str:
    """One Markdown table row: figure | value | same-run baseline | ratio | target."""
    base = f"{_cell(f['baseline'])}: {fmt_value(f['baseline_value'])} {f['unit']}" if f.get("baseline_value") else ""
    ratio = f"x{f['ratio']:.2f}" if f.get("ratio") else ""
    return (
        f"| {_cell(f['label'])} | **{fmt_value(f['value'])} {f['unit']}** | {base} | {ratio} | "
        f"{_cell(f.get('target') or '')} |"
    )


def machine_line(report: dict[str, Any]) -> str:
    m = report.get("machine", {})
    gpu = m.get("gpu")
    dev = (
        f"{gpu['name']} ({gpu['memory_gib']} GiB, sm {gpu['capability']}, driver {gpu.get('driver') or '?'})"
        if gpu
        else "no GPU (CPU dry run)"
    )
    versions = f"torch {m.get('torch')}, CUDA {m.get('cuda')}"
    if m.get("cudnn"):
        versions += f", cuDNN {m['cudnn']}"
    if m.get("nccl"):
        versions += f", NCCL {m['nccl']}"
    return (
        f"{dev}; {m.get('cpus')} x {m.get('cpu')}; Python {m.get('python')}, {versions}, numpy {m.get('numpy')}, "
        f"OpenCV {m.get('opencv')}; murk {m.get('murk')} ({m.get('git') or 'no git'})"
    )


def render_markdown(report: dict[str, Any]) -> str:
    dry = report["mode"] != "gpu"
    lines = [
        "# murk GPU suite" + (" - CPU DRY RUN (tiny sizes: these are not GPU figures)" if dry else ""),
        "",
        f"- date: {report['date']}; wall {report.get('wall_s', 0):.0f} s (limit {report['limit_s']:.0f} s)",
        f"- machine: {machine_line(report)}",
        f"- command: `{report.get('command', '')}`",
        "",
        "| part | status | wall / budget | figures | notes |",
        "|---|---|---|---|---|",
    ]
    for p in report["parts"]:
        notes = [*p.get("notes", [])]
        for key in ("skipped", "error"):
            if p.get(key):
                notes.append(p[key])
        notes += [f"{q['label']}: {q['kind']} ({q['why']})" for q in p.get("problems", []) if q["kind"] != "skipped"]
        if any(q["kind"] == "skipped" for q in p.get("problems", [])):
            notes.append(f"{sum(q['kind'] == 'skipped' for q in p['problems'])} skipped (listed below)")
        if p.get("foreign_imports"):
            notes.append(f"imported packages the GPU machine lacks: {', '.join(p['foreign_imports'])}")
        wall = f"{p.get('wall_s', 0):.0f} / {p['budget_s']:.0f} s"
        lines.append(
            f"| {p['name']} | {p['status']} | {wall} | {len(p.get('figures', []))} | {_cell('; '.join(notes))} |"
        )
    lines += ["", "| part | figure | value | same-run baseline | ratio | target |", "|---|---|---|---|---|---|"]
    for p in report["parts"]:
        lines += [f"| {p['name']} " + figure_row(f) for f in p.get("figures", [])]
    skips = skipped_items(report)
    if skips:
        lines += ["", "What this run skipped (it cannot run here), with the reason:", ""]
        lines += [f"- {name}: {_cell(what)}: {_cell(why)}" for name, what, why in skips]
    return "\n".join(lines) + "\n"


def skipped_items(report: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(part, what, why) for every part skipped whole and every measurement or test a part skipped."""
    out: list[tuple[str, str, str]] = []
    for p in report["parts"]:
        if p.get("skipped"):
            out.append((p["name"], "the whole part", p["skipped"]))
        out += [(p["name"], q["label"], q["why"]) for q in p.get("problems", []) if q["kind"] == "skipped"]
    return out


# ---------------------------------------------------------------------------------------------------------------


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="gpu-suite", help="output folder (default: gpu-suite)")
    ap.add_argument("--cpu-dry-run", action="store_true", help="the same parts on the CPU at tiny sizes")
    ap.add_argument("--parts", default="", help="comma list of parts to run (default: all, in order)")
    ap.add_argument("--limit-s", type=float, default=None, help=f"wall-time limit (default {LIMIT_S:.0f} s)")
    ap.add_argument("--list", action="store_true", help="print the parts and their budgets")
    ap.add_argument("--part", help=argparse.SUPPRESS)
    ap.add_argument("--result", help=argparse.SUPPRESS)
    ap.add_argument("--budget", type=float, help=argparse.SUPPRESS)
    ap.add_argument("--machine-info", help=argparse.SUPPRESS)
    ap.add_argument("--fork-server", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.list:
        for p in PARTS:
            print(f"{p.name:22s} {p.budget_s:4.0f} s  -> BENCHMARKS.md [{p.section}]  {p.title}")
        print(f"{'total':22s} {sum(p.budget_s for p in PARTS):4.0f} s of budgets; limit {LIMIT_S:.0f} s")
        return 0
    if args.machine_info:
        _write_json(Path(args.machine_info), machine_info(args.cpu_dry_run))
        return 0
    if args.fork_server:
        return _fork_server()
    if args.part:
        return run_part(args.part, Path(args.result), args.budget, args.cpu_dry_run)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # a TERM ends the running part's group too
    return run_suite(args)


if __name__ == "__main__":
    sys.exit(main())
