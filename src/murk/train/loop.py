"""The training loop of ``murk train``: single process or DistributedDataParallel under ``torchrun``.

The run is set up by :mod:`murk.train.setup` (data, process group and device, step budget, model, optimiser,
resume) and evaluated by :mod:`murk.train.evaluation`; this module holds the step loop, its logs and
checkpoints (and re-exports ``DataSetup``, ``build_data``, ``detect_kind`` and ``evaluate``).

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
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

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
from murk.train.evaluation import evaluate, to_device
from murk.train.losses import jointid_loss
from murk.train.setup import (
    DataSetup,
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
) -> TrainSummary:
    """Train the network of ``config.model`` (Joint-ID, or ``lite``: see :mod:`murk.train.networks`) as
    ``config`` says. Under ``torchrun`` (``WORLD_SIZE`` > 1) it runs DDP: gloo on CPU, NCCL on CUDA, each process
    with ``config.batch`` samples per step.

    Args:
        config: the run.
        resume: continue from ``<out>/latest.pt`` (bit-exact on the CPU).
        stop_after: stop after this many steps in this invocation (a time-boxed job; resume later).
        on_log: called with every log record (the CLI prints progress with it).
    """
    from murk.train.networks import has_depth, load_teacher, run_network, save_network

    kind = config.model.kind
    rt = init_runtime(config.device)
    rank, world, distributed, device, main_rank = rt.rank, rt.world, rt.distributed, rt.device, rt.main
    out = Path(config.out)
    check_run_folder(out, config, resume=resume)
    data = build_data(config)  # a bad source or snow bank stops here, before anything is written
    if config.loss.snow > 0 and data.online is None:
        raise ValueError(
            f"loss.snow: needs the training inputs' marine snow, rendered online; data.source {config.data.source} "
            f"is {data.kind} data (prerendered): use clean RGB-D or scenes, or set loss.snow to 0"
        )
    if main_rank:
        make_output_folder(out, "run folder")
        write_text_atomic(out / "config.yaml", dump_yaml(config, murk_version=__version__, world_size=world))
    logger = _Logger(out, main_rank)

    n_train = len(data.train)
    spe, total, schedule = plan_steps(config, n_train, world)
    model = build_model(config, device)
    teacher = load_teacher(config.loss.teacher, device) if config.loss.distill > 0 and config.loss.teacher else None
    optim = build_optimiser(config, model, schedule.lr(0), device)
    start = 0
    best: dict[str, Any] = {}
    latest = out / "latest.pt"
    if resume:
        start, best = resume_state(latest, config, model, optim, device)
    net: Any = model  # the module itself, its DDP wrapper or its compiled form
    if distributed:
        net = torch.nn.parallel.DistributedDataParallel(
            model, device_ids=[device.index] if device.type == "cuda" else None
        )
    if config.compile:
        net = torch.compile(net)

    summary = TrainSummary(out=out, out_dir=str(out), steps_done=start, skipped=start, total_steps=total, best=best)
    errors = ErrorLog(out, summary=summary).start() if main_rank else None
    if resume:  # a resumed run that has no step left to do keeps the loss its last step logged
        summary.last_loss = _previous_last_loss(out / "summary.json")
    autocast = (
        torch.autocast(device_type=device.type, dtype=torch.bfloat16)
        if config.precision == "bf16"
        else contextlib.nullcontext()
    )
    end = total if stop_after is None else min(total, start + stop_after)

    def batches_from(step: int) -> Iterator[tuple[int, dict[str, Any]]]:
        epoch, offset = divmod(step, spe)
        while True:
            if hasattr(data.train, "epoch_loader"):  # tar shards: this rank's stream of the epoch, from a batch on
                loader = data.train.epoch_loader(epoch, offset, rank=rank, pin_memory=device.type == "cuda")
            else:
                idx = epoch_batches(n_train, config.batch, epoch, config.seed, rank, world)[offset:]
                loader = DataLoader(
                    data.train,
                    batch_sampler=idx,
                    num_workers=config.data.workers,
                    pin_memory=device.type == "cuda",
                    persistent_workers=False,
                )
            for b in loader:
                yield epoch, b
            epoch, offset = epoch + 1, 0

    def emit(rec: dict[str, Any]) -> None:
        logger.log(rec)
        if on_log and main_rank:
            on_log(rec)

    step = start
    t_last, imgs = time.perf_counter(), 0
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    it = batches_from(start)
    net.train()
    while step < end:
        epoch, batch = next(it)
        record_unreadable(batch, errors)
        batch = to_device(batch, device)
        snow_alpha = None
        if data.online is not None:
            with torch.no_grad():
                rendered = data.online.render(batch["clean"], batch["depth_filled"], epoch, batch["index"].tolist())
            inputs, targets = rendered.degraded, batch["clean"]
            if config.loss.snow > 0:
                snow_alpha = rendered.snow_alpha
        else:
            inputs, targets = batch["input"], batch["target"]
        gen = torch.Generator().manual_seed(derive_seed(config.seed, "augment", step, rank))
        aug = sample_augment(inputs.shape[0], config.augment, gen)
        inputs, targets, depth = apply_augment(inputs, targets, batch["depth"], aug, config.augment)
        if snow_alpha is not None:
            snow_alpha = augment_map(snow_alpha, aug, config.augment)
        lr = schedule.lr(step)
        for group in optim.param_groups:
            group["lr"] = lr
        x = inputs.contiguous(memory_format=torch.channels_last) if config.channels_last else inputs
        with autocast:
            enhanced, depth_m = run_network(kind, net, x, config.model.input_balance_pct)
        taught = None
        if teacher is not None:
            with torch.no_grad():
                t_kind, t_net = teacher
                balance = getattr(t_net, "input_balance_pct", None)
                taught = run_network(t_kind, t_net, inputs, balance)[0].float().clamp(0.0, 1.0)
        terms = jointid_loss(
            enhanced.float(),
            targets,
            None if depth_m is None else depth_m.float(),
            depth,
            config.loss,
            snow_alpha,
            taught,
        )
        optim.zero_grad(set_to_none=True)
        terms.total.backward()
        if config.optim.grad_clip > 0:
            torch.nn.utils.clip_grad_norm_(model.parameters(), config.optim.grad_clip)
        optim.step()
        step += 1
        imgs += inputs.shape[0] * world
        summary.steps_done = step
        summary.processed = step - start
        if step % config.log_every == 0 or step == end:
            loss = float(terms.total.detach())
            now = time.perf_counter()
            rate = imgs / max(now - t_last, 1e-9)
            t_last, imgs = now, 0
            summary.last_loss, summary.images_per_s = loss, rate
            record = {
                "kind": "train",
                "step": step,
                "epoch": round(step / spe, 4),
                "lr": lr,
                "loss": loss,
                "l2": float(terms.l2),
                "lap": float(terms.lap),
                "silog": float(terms.silog),
                "images_per_s": rate,
            }
            if not has_depth(kind):
                del record["silog"]
            if terms.snow is not None:
                record["snow"] = float(terms.snow)
            if terms.distill is not None:
                record["distill"] = float(terms.distill)
            if terms.local is not None:
                record["local"] = float(terms.local)
            emit(record)
        if step % config.eval.every == 0 or step == end:
            metrics = evaluate(model, data, config, device, step, errors) if main_rank else {}
            if metrics:
                emit({"kind": "eval", "step": step, **metrics})
                summary.last_eval = metrics
            if main_rank:
                key = config.eval.best_metric
                value = metrics.get(key)
                better = (
                    value is not None
                    and math.isfinite(value)
                    and (
                        "value" not in best
                        or (value > best["value"] if config.eval.best_mode == "max" else value < best["value"])
                    )
                )
                if better and value is not None:
                    best = {"metric": key, "value": float(value), "step": step}
                    summary.best = best
                    save_network(
                        kind, model, out / "best.pt", step=step, best=best, metrics=metrics, config=to_dict(config)
                    )
                save_network(
                    kind,
                    model,
                    latest,
                    step=step,
                    optimizer=optim.state_dict(),
                    best=best,
                    metrics=metrics,
                    config=to_dict(config),
                )
            if distributed:
                dist.barrier()
            t_last, imgs = time.perf_counter(), 0  # throughput excludes evaluation time
    if device.type == "cuda":
        summary.peak_memory_gib = torch.cuda.max_memory_allocated(device) / 2**30
    summary.replica_checksums = _replica_checksums(model, distributed)
    if main_rank:
        summary.finish()
        doc = {k: v for k, v in to_dict(summary).items() if k not in ("started", "failures")}
        text = json.dumps(json_safe(doc), indent=2, default=str, allow_nan=False)  # NaN is not JSON: null
        write_text_atomic(out / "summary.json", text + "\n")
    logger.close()
    if distributed:
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
