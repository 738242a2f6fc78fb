"""The training loop of ``murk train``: single process or DistributedDataParallel under ``torchrun``.

The run is set up by :mod:`murk.train.setup` (data, process group and device, step budget, model, optimiser,
resume) and evaluated by :mod:`murk.train.evaluation`; this module holds the step loop, its logs and
checkpoints (and re-exports ``DataSetup``, ``build_data``, ``detect_kind`` and ``evaluate``). :func:`train` reads
as the loop runs: set-up and resume (``_set_up``), then per step its batch (``_step_batch``), loss (``_loss``) and
update (``_update``), the log record (``_log_train``), evaluation and checkpoints (``_evaluate_and_save``), and at
the end the summary (``_finish``).

Determinism and exact resume: nothing random is carried in hidden state. The order of samples in epoch ``e``
is a permutation drawn from ``derive_seed(seed, "order", e)`` (each rank takes every ``world``-th sample),
the augmentation of step ``s`` on rank ``r`` from ``derive_seed(seed, "augment", s, r)``, and online
synthesis parameters from ``derive_seed(seed, "online", e, sample)``. A checkpoint therefore only needs the
weights, the optimiser state and the step: ``--resume`` continues bit-exactly on the CPU (tested).

Checkpoints (``save_checkpoint`` format, loadable by ``murk enhance --checkpoint``): ``latest.pt`` at every
evaluation and at the end (with the optimiser state), ``best.pt`` by ``eval.best_metric``. Logs:
``log.jsonl`` (one record per logged step and per evaluation), TensorBoard event files when tensorboard is
installed, ``config.yaml``, and ``summary.json`` at the end.
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Callable, Iterator, Sized
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal, NamedTuple, cast

import numpy as np
import torch
import torch.distributed as dist
from torch.utils.data import DataLoader

from murk._config import dump_yaml, to_dict
from murk._version import __version__
from murk.io.atomic import make_output_folder, write_text_atomic
from murk.io.jobs import ErrorLog, JobSummary
from murk.io.jsonl import append_jsonl, json_safe
from murk.rng import derive_seed
from murk.train.augment import apply_augment, augment_map, sample_augment
from murk.train.config import TrainConfig
from murk.train.data import record_unreadable
from murk.train.evaluation import check_real_folder, evaluate, to_device
from murk.train.losses import LossTerms, jointid_loss
from murk.train.schedule import Schedule
from murk.train.setup import (
    DataSetup,
    Runtime,
    build_data,
    build_model,
    build_optimiser,
    check_run_folder,
    detect_kind,
    init_runtime,
    plan_steps,
    resume_state,
)

__all__ = ["DataSetup", "TrainSummary", "build_data", "detect_kind", "epoch_batches", "evaluate", "train"]


@dataclass
class TrainSummary(JobSummary):
    """What a run did (also written to ``summary.json``): the job summary (:class:`murk.io.jobs.JobSummary`;
    ``processed`` counts the steps run by this invocation, ``skipped`` those resumed from ``latest.pt``) and
    the training figures."""

    command: str = "train"
    out_dir: str = ""
    steps_done: int = 0
    total_steps: int = 0
    images_per_s: float = 0.0
    last_loss: float = float("nan")
    best: dict[str, Any] = field(default_factory=dict)
    last_eval: dict[str, Any] = field(default_factory=dict)
    replica_checksums: list[float] = field(default_factory=list)
    peak_memory_gib: float | None = None


# ------------------------------------------------------------------------------------------------ order


def epoch_batches(n: int, batch: int, epoch: int, seed: int, rank: int, world: int) -> list[list[int]]:
    """The index batches of one epoch on one rank (shuffled by (seed, epoch); the incomplete tail dropped)."""
    perm = np.random.default_rng(derive_seed(seed, "order", epoch)).permutation(n)
    mine = perm[rank::world][: (n // world // batch) * batch]
    return [mine[i : i + batch].tolist() for i in range(0, len(mine), batch)]


# --------------------------------------------------------------------------------------------- helpers


class _Logger:
    def __init__(self, out: Path, enabled: bool) -> None:
        self.path = out / "log.jsonl"
        self.enabled = enabled
        self.tb = None
        if enabled:
            with contextlib.suppress(ImportError):
                from torch.utils.tensorboard import SummaryWriter

                self.tb = SummaryWriter(str(out / "tensorboard"))

    def log(self, record: dict[str, Any]) -> None:
        if not self.enabled:
            return
        clean = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in record.items()}
        append_jsonl(self.path, [clean])
        if self.tb is not None:
            for k, v in record.items():
                if isinstance(v, (int, float)) and k not in ("step", "epoch") and math.isfinite(float(v)):
                    self.tb.add_scalar(f"{record.get('kind', 'train')}/{k}", v, record.get("step", 0))

    def close(self) -> None:
        if self.tb is not None:
            self.tb.close()


# ------------------------------------------------------------------------------------------------ train


def train(
    config: TrainConfig,
    *,
    resume: bool = False,
    stop_after: int | None = None,
    on_log: Callable[[dict[str, Any]], None] | None = None,
    method_teacher: Callable[[torch.device], torch.nn.Module] | None = None,
) -> TrainSummary:
    """Train the network of ``config.model`` (Joint-ID, or ``lite``: see :mod:`murk.train.networks`) as
    ``config`` says. Under ``torchrun`` (``WORLD_SIZE`` > 1) it runs DDP: gloo on CPU, NCCL on CUDA, each process
    with ``config.batch`` samples per step.

    Args:
        config: the run.
        resume: continue from ``<out>/latest.pt`` (bit-exact on the CPU).
        stop_after: stop after this many steps in this invocation (a time-boxed job; resume later).
        on_log: called with every log record (the CLI prints progress with it).
        method_teacher: for ``loss.teacher: method:SPEC``, what builds the teacher on this process's device (under
            ``torchrun``, ``cuda:LOCAL_RANK``): a module that maps a batch (B, 3, H, W) in [0, 1] to the method's
            restoration (:mod:`murk.workflows.distill` gives it, since this layer does not run restoration
            methods).

    Raises:
        ValueError: ``loss.teacher`` names a method and no ``method_teacher`` was given.
    """
    run = _set_up(config, resume=resume, stop_after=stop_after, on_log=on_log, method_teacher=method_teacher)
    clock = _Throughput()
    batches = _batches_from(run, run.start)
    run.net.train()
    step = run.start
    while step < run.end:
        epoch, loaded = next(batches)
        batch = _step_batch(run, loaded, epoch, step)
        lr = run.schedule.lr(step)
        terms = _loss(run, batch)
        _update(run, terms, lr)
        step += 1
        clock.images += batch.inputs.shape[0] * run.rt.world
        run.summary.steps_done, run.summary.processed = step, step - run.start
        if step % config.log_every == 0 or step == run.end:
            _log_train(run, step, lr, terms, clock.lap())
        if step % config.eval.every == 0 or step == run.end:
            _evaluate_and_save(run, step)
            clock.restart()  # throughput excludes evaluation time
    return _finish(run)


# ------------------------------------------------------------------------------------------------ set-up


@dataclass(frozen=True)
class _Run:
    """What a run is set up with. The objects themselves change as it trains (weights, optimiser state, the
    summary); the bindings do not."""

    config: TrainConfig
    rt: Runtime
    out: Path
    data: DataSetup
    n_train: int
    steps_per_epoch: int
    schedule: Schedule
    model: torch.nn.Module
    net: Any  # the module itself, its DDP wrapper or its compiled form
    teacher: tuple[str, torch.nn.Module] | None
    optim: torch.optim.Optimizer
    autocast: contextlib.AbstractContextManager[Any]
    start: int
    end: int
    summary: TrainSummary
    errors: ErrorLog | None
    logger: _Logger
    on_log: Callable[[dict[str, Any]], None] | None


def _set_up(
    config: TrainConfig,
    *,
    resume: bool,
    stop_after: int | None,
    on_log: Callable[[dict[str, Any]], None] | None,
    method_teacher: Callable[[torch.device], torch.nn.Module] | None,
) -> _Run:
    """Everything before the first step: process and device, data, run folder, model, optimiser, the state of a
    resumed run, the summary and the error log."""
    rt = init_runtime(config.device)
    teacher = _teacher(config, rt.device, method_teacher)  # a method without its module stops here, before any file
    out = Path(config.out)
    check_run_folder(out, config, resume=resume)
    data = _training_data(config)  # a bad source or snow bank stops here, before anything is written
    if config.eval.real:  # and a bad --eval-real, not at the first evaluation, after steps that would be lost
        check_real_folder(config.eval.real)
    if rt.main:
        make_output_folder(out, "run folder")
        write_text_atomic(out / "config.yaml", dump_yaml(config, murk_version=__version__, world_size=rt.world))
    logger = _Logger(out, rt.main)

    n_train = len(cast(Sized, data.train))  # every training set has a length; torch's Dataset does not declare it
    spe, total, schedule = plan_steps(config, n_train, rt.world)
    model = build_model(config, rt.device)
    optim = build_optimiser(config, model, schedule.lr(0), rt.device)
    start, best = resume_state(out / "latest.pt", config, model, optim, rt.device) if resume else (0, {})
    net = _wrap(model, config, rt)
    summary = TrainSummary(out=out, out_dir=str(out), steps_done=start, skipped=start, total_steps=total, best=best)
    errors = ErrorLog(out, summary=summary).start() if rt.main else None
    if resume:  # a resumed run that has no step left to do keeps the loss its last step logged
        summary.last_loss = _previous_last_loss(out / "summary.json")
    if rt.device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(rt.device)
    return _Run(
        config=config,
        rt=rt,
        out=out,
        data=data,
        n_train=n_train,
        steps_per_epoch=spe,
        schedule=schedule,
        model=model,
        net=net,
        teacher=teacher,
        optim=optim,
        autocast=(
            torch.autocast(device_type=rt.device.type, dtype=torch.bfloat16)
            if config.precision == "bf16"
            else contextlib.nullcontext()
        ),
        start=start,
        end=total if stop_after is None else min(total, start + stop_after),
        summary=summary,
        errors=errors,
        logger=logger,
        on_log=on_log,
    )


def _teacher(
    config: TrainConfig, device: torch.device, method_teacher: Callable[[torch.device], torch.nn.Module] | None
) -> tuple[str, torch.nn.Module] | None:
    """``(kind, module)`` of the distillation teacher, or None when the run does not distil."""
    from murk.train.networks import load_teacher

    spec = config.loss.teacher
    if config.loss.distill <= 0 or not spec:
        return None
    if spec.startswith("method:"):
        if method_teacher is None:
            raise ValueError(
                f"teacher: {spec} is a restoration method; murk train (murk.workflows.distill.train_network) runs it, "
                f"murk.train.loop.train needs what builds it as method_teacher"
            )
        return "method", method_teacher(device)
    return load_teacher(spec, device)


def _training_data(config: TrainConfig) -> DataSetup:
    """The run's data (:func:`build_data`), refused when ``loss.snow`` asks for snow that prerendered data lacks."""
    data = build_data(config)
    if config.loss.snow > 0 and data.online is None:
        raise ValueError(
            f"loss.snow: needs the training inputs' marine snow, rendered online; data.source {config.data.source} "
            f"is {data.kind} data (prerendered): use clean RGB-D or scenes, or set loss.snow to 0"
        )
    return data


def _wrap(model: torch.nn.Module, config: TrainConfig, rt: Runtime) -> Any:
    """The module the steps call: ``model`` in its DDP wrapper under ``torchrun``, compiled if ``config.compile``."""
    net: Any = model
    if rt.distributed:
        net = torch.nn.parallel.DistributedDataParallel(
            model, device_ids=[rt.device.index] if rt.device.type == "cuda" else None
        )
    if config.compile:
        net = torch.compile(net)
    return net


def _batches_from(run: _Run, step: int) -> Iterator[tuple[int, dict[str, Any]]]:
    """``(epoch, batch)`` of this rank from ``step`` on, epoch after epoch (a resumed run starts mid-epoch)."""
    config, rt, pin = run.config, run.rt, run.rt.device.type == "cuda"
    epoch, offset = divmod(step, run.steps_per_epoch)
    while True:
        if hasattr(run.data.train, "epoch_loader"):  # tar shards: this rank's stream of the epoch, from a batch on
            loader = run.data.train.epoch_loader(epoch, offset, rank=rt.rank, pin_memory=pin)
        else:
            idx = epoch_batches(run.n_train, config.batch, epoch, config.seed, rt.rank, rt.world)[offset:]
            loader = DataLoader(
                run.data.train,
                batch_sampler=idx,
                num_workers=config.data.workers,
                pin_memory=pin,
                persistent_workers=False,
            )
        for b in loader:
            yield epoch, b
        epoch, offset = epoch + 1, 0


# ------------------------------------------------------------------------------------------------ one step


class _StepBatch(NamedTuple):
    """What one step trains on: the network's inputs, the clean targets, the depth targets and, for the snow
    term, the inputs' snow alpha; all augmented alike."""

    inputs: torch.Tensor
    targets: torch.Tensor
    depth: torch.Tensor
    snow_alpha: torch.Tensor | None


def _step_batch(run: _Run, loaded: dict[str, Any], epoch: int, step: int) -> _StepBatch:
    """The batch of step ``step`` (0-based) from a loaded one: unreadable entries recorded, moved to the device,
    degraded online when the data is clean RGB-D, then augmented from ``(seed, "augment", step, rank)``."""
    config = run.config
    record_unreadable(loaded, run.errors)
    batch = to_device(loaded, run.rt.device)
    snow_alpha = None
    if run.data.online is not None:
        with torch.no_grad():
            rendered = run.data.online.render(batch["clean"], batch["depth_filled"], epoch, batch["index"].tolist())
        inputs, targets = rendered.degraded, batch["clean"]
        if config.loss.snow > 0:
            snow_alpha = rendered.snow_alpha
    else:
        inputs, targets = batch["input"], batch["target"]
    gen = torch.Generator().manual_seed(derive_seed(config.seed, "augment", step, run.rt.rank))
    aug = sample_augment(inputs.shape[0], config.augment, gen)
    inputs, targets, depth = apply_augment(inputs, targets, batch["depth"], aug, config.augment)
    if snow_alpha is not None:
        snow_alpha = augment_map(snow_alpha, aug, config.augment)
    return _StepBatch(inputs, targets, depth, snow_alpha)


def _loss(run: _Run, batch: _StepBatch) -> LossTerms:
    """The forward pass (and the teacher's, when distilling) and the loss terms of one batch."""
    from murk.train.networks import run_network

    config = run.config
    x = batch.inputs.contiguous(memory_format=torch.channels_last) if config.channels_last else batch.inputs
    with run.autocast:
        enhanced, depth_m = run_network(config.model.kind, run.net, x, config.model.input_balance_pct)
    taught = None
    if run.teacher is not None:
        with torch.no_grad():
            t_kind, t_net = run.teacher
            if t_kind == "method":  # the method takes the raw input and balances it itself, if it does
                taught = t_net(batch.inputs).float().clamp(0.0, 1.0)
            else:
                balance = getattr(t_net, "input_balance_pct", None)
                taught = run_network(t_kind, t_net, batch.inputs, balance)[0].float().clamp(0.0, 1.0)
    return jointid_loss(
        enhanced.float(),
        batch.targets,
        None if depth_m is None else depth_m.float(),
        batch.depth,
        config.loss,
        batch.snow_alpha,
        taught,
    )


def _update(run: _Run, terms: LossTerms, lr: float) -> None:
    """One optimiser step at learning rate ``lr``: gradients of the total loss, clipped if asked."""
    for group in run.optim.param_groups:
        group["lr"] = lr
    run.optim.zero_grad(set_to_none=True)
    terms.total.backward()
    if run.config.optim.grad_clip > 0:
        torch.nn.utils.clip_grad_norm_(run.model.parameters(), run.config.optim.grad_clip)
    run.optim.step()


# ------------------------------------------------------------------------------------------------ logging


@dataclass
class _Throughput:
    """Images trained since ``since`` (a ``time.perf_counter`` reading): the rate of each train record."""

    since: float = field(default_factory=time.perf_counter)
    images: int = 0

    def lap(self) -> float:
        """Images per second since the last lap or restart; counting starts again."""
        now = time.perf_counter()
        rate = self.images / max(now - self.since, 1e-9)
        self.since, self.images = now, 0
        return rate

    def restart(self) -> None:
        self.since, self.images = time.perf_counter(), 0


def _emit(run: _Run, record: dict[str, Any]) -> None:
    """Write a log record (main process) and hand it to ``on_log``."""
    run.logger.log(record)
    if run.on_log and run.rt.main:
        run.on_log(record)


def _log_train(run: _Run, step: int, lr: float, terms: LossTerms, rate: float) -> None:
    """Log the train record of ``step`` (the loss and its terms; ``silog`` only for networks with depth; ``snow``,
    ``distill`` and ``local`` when their weights are on) and keep its loss and rate in the summary."""
    from murk.train.networks import has_depth

    loss = float(terms.total.detach())
    run.summary.last_loss, run.summary.images_per_s = loss, rate
    record = {
        "kind": "train",
        "step": step,
        "epoch": round(step / run.steps_per_epoch, 4),
        "lr": lr,
        "loss": loss,
        "l2": float(terms.l2),
        "lap": float(terms.lap),
        "silog": float(terms.silog),
        "images_per_s": rate,
    }
    if not has_depth(run.config.model.kind):
        del record["silog"]
    if terms.snow is not None:
        record["snow"] = float(terms.snow)
    if terms.distill is not None:
        record["distill"] = float(terms.distill)
    if terms.local is not None:
        record["local"] = float(terms.local)
    _emit(run, record)


# ------------------------------------------------------------------------------------ evaluation, checkpoints


def _evaluate_and_save(run: _Run, step: int) -> None:
    """Evaluate (main process), log the eval record and write the checkpoints; under DDP all ranks wait here."""
    main = run.rt.main
    metrics = evaluate(run.model, run.data, run.config, run.rt.device, step, run.errors) if main else {}
    if metrics:
        _emit(run, {"kind": "eval", "step": step, **metrics})
        run.summary.last_eval = metrics
    if main:
        _save_checkpoints(run, step, metrics)
    if run.rt.distributed:
        dist.barrier()


def _save_checkpoints(run: _Run, step: int, metrics: dict[str, Any]) -> None:
    """``best.pt`` when ``eval.best_metric`` improved on the best so far, and ``latest.pt`` (with the optimiser
    state) always."""
    from murk.train.networks import save_network

    config, kind, best = run.config, run.config.model.kind, run.summary.best
    key = config.eval.best_metric
    value = metrics.get(key)
    if value is not None and _improves(value, best, config.eval.best_mode):
        best = run.summary.best = {"metric": key, "value": float(value), "step": step}
        save_network(
            kind, run.model, run.out / "best.pt", step=step, best=best, metrics=metrics, config=to_dict(config)
        )
    save_network(
        kind,
        run.model,
        run.out / "latest.pt",
        step=step,
        optimizer=run.optim.state_dict(),
        best=best,
        metrics=metrics,
        config=to_dict(config),
    )


def _improves(value: float, best: dict[str, Any], mode: Literal["max", "min"]) -> bool:
    """Whether a finite ``value`` beats ``best["value"]`` (or there is no best yet)."""
    if not math.isfinite(value):
        return False
    return "value" not in best or (value > best["value"] if mode == "max" else value < best["value"])


# ------------------------------------------------------------------------------------------------ finish


def _finish(run: _Run) -> TrainSummary:
    """After the last step: peak memory, replica checksums, ``summary.json``; then the process group ends."""
    summary = run.summary
    if run.rt.device.type == "cuda":
        summary.peak_memory_gib = torch.cuda.max_memory_allocated(run.rt.device) / 2**30
    summary.replica_checksums = _replica_checksums(run.model, run.rt.distributed)
    if run.rt.main:
        summary.finish()
        doc = {k: v for k, v in to_dict(summary).items() if k not in ("started", "failures")}
        text = json.dumps(json_safe(doc), indent=2, default=str, allow_nan=False)  # NaN is not JSON: null
        write_text_atomic(run.out / "summary.json", text + "\n")
    run.logger.close()
    if run.rt.distributed:
        dist.barrier()
        dist.destroy_process_group()
    return summary.finish()


def _replica_checksums(model: torch.nn.Module, distributed: bool) -> list[float]:
    """A float64 checksum of the weights on every rank (equal when the replicas are identical)."""
    with torch.no_grad():
        s = torch.zeros((), dtype=torch.float64, device=next(model.parameters()).device)
        for i, p in enumerate(model.parameters()):
            s += (p.double() * (1.0 + 1e-3 * (i % 97))).sum()
    if not distributed:
        return [float(s)]
    gathered = [torch.zeros_like(s) for _ in range(dist.get_world_size())]
    dist.all_gather(gathered, s)
    return [float(g) for g in gathered]


def _previous_last_loss(path: Path) -> float:
    """``last_loss`` of an earlier ``summary.json`` of this run; NaN when there is none (or it is unreadable)."""
    try:
        value = json.loads(path.read_text(encoding="utf-8")).get("last_loss")
    except (OSError, ValueError, AttributeError):
        return float("nan")
    return float(value) if isinstance(value, (int, float)) else float("nan")
