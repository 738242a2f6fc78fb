"""The training loop of ``murk train``: single process or DistributedDataParallel under ``torchrun``.

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
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.distributed as dist
import torch.nn.functional as F
from torch.utils.data import DataLoader, Dataset

from murk._config import dump_yaml, to_dict
from murk._version import __version__
from murk.io.atomic import write_text_atomic
from murk.io.jobs import JobSummary
from murk.io.jsonl import append_jsonl
from murk.io.pairs import DepthOptions
from murk.rng import derive_seed
from murk.train.augment import apply_augment, sample_augment
from murk.train.config import TrainConfig
from murk.train.data import (
    CleanRGBDDataset,
    OnlineDegrader,
    PairDataset,
    items_from_list,
    items_from_synth_folder,
    rgbd_sources,
    split_by_stem,
)
from murk.train.losses import jointid_loss
from murk.train.schedule import Schedule


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


# ------------------------------------------------------------------------------------------------ data


@dataclass
class DataSetup:
    train: Dataset
    val: Dataset | None
    online: OnlineDegrader | None
    kind: str


def detect_kind(source: str) -> str:
    """``synth`` (folder with manifest.jsonl), ``list`` (a file), ``rgbd`` (rgb/ + depth/) or ``scenes``."""
    p = Path(source)
    if source == "scenes" or source.startswith("scenes:"):
        return "scenes"
    if p.is_file():
        return "list"
    if (p / "manifest.jsonl").is_file():
        return "synth"
    if p.is_dir() and (p / "depth").is_dir():
        return "rgbd"
    raise ValueError(
        f"data.source: {source or '(empty)'} is neither a 'murk synth' folder, a Joint-ID list file, a folder with "
        "rgb/ and depth/, nor 'scenes'"
    )


def build_data(config: TrainConfig) -> DataSetup:
    d = config.data
    kind = d.kind if d.kind != "auto" else detect_kind(d.source)
    crop = tuple(d.crop_hw)
    online = None
    if kind in ("synth", "list"):
        items = items_from_synth_folder(d.source) if kind == "synth" else items_from_list(d.source, d.list_root)
        if d.val_source:
            vk = detect_kind(d.val_source)
            val_items = items_from_synth_folder(d.val_source) if vk == "synth" else items_from_list(d.val_source)
            tr, va = items, val_items
        else:
            ti, vi = split_by_stem([i.stem for i in items], d.val_fraction, config.seed)
            tr, va = [items[i] for i in ti], [items[i] for i in vi]
        return DataSetup(PairDataset(tr, crop), PairDataset(va, crop) if va else None, None, kind)
    if kind == "rgbd":
        sources = rgbd_sources(d.source)
        opts = DepthOptions(depth_scale=d.depth_scale, invalid=d.invalid_depth, encoding=d.depth_encoding)
        ti, vi = split_by_stem([s.stem for s in sources], d.val_fraction, config.seed)
        online = OnlineDegrader(d.synthesis, seed=config.seed)
        train = CleanRGBDDataset([sources[i] for i in ti], crop, opts)
        val = CleanRGBDDataset([sources[i] for i in vi], crop, opts) if vi else None
        return DataSetup(train, val, online, kind)
    if kind == "scenes":
        from murk.train.scenes_source import SceneDataset

        count = int(d.source.split(":", 1)[1]) if ":" in d.source else d.scenes_count
        n_val = max(1, round(d.val_fraction * count)) if d.val_fraction > 0 else 0
        online = OnlineDegrader(d.synthesis, seed=config.seed)
        cache = d.cache_scenes and d.workers == 0
        scale = d.scene_scale
        train = SceneDataset(range(n_val, count), crop, seed=config.seed, cache=cache, scale=scale)
        val = SceneDataset(range(n_val), crop, seed=config.seed, cache=cache, scale=scale) if n_val else None
        return DataSetup(train, val, online, kind)
    raise ValueError(f"data.kind: expected auto, synth, list, rgbd or scenes, got {kind!r}")


def epoch_batches(n: int, batch: int, epoch: int, seed: int, rank: int, world: int) -> list[list[int]]:
    """The index batches of one epoch on one rank (shuffled by (seed, epoch); the incomplete tail dropped)."""
    perm = np.random.default_rng(derive_seed(seed, "order", epoch)).permutation(n)
    mine = perm[rank::world][: (n // world // batch) * batch]
    return [mine[i : i + batch].tolist() for i in range(0, len(mine), batch)]


# --------------------------------------------------------------------------------------------- helpers


def _dist_info() -> tuple[int, int, int]:
    world = int(os.environ.get("WORLD_SIZE", "1"))
    return int(os.environ.get("RANK", "0")), world, int(os.environ.get("LOCAL_RANK", "0"))


def _to_device(batch: dict[str, Any], device: torch.device) -> dict[str, Any]:
    return {k: v.to(device, non_blocking=True) if torch.is_tensor(v) else v for k, v in batch.items()}


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
    from murk.train.networks import (
        build_network,
        frozen_parameter_names,
        has_depth,
        read_network_checkpoint,
        run_network,
        save_network,
    )

    kind = config.model.kind
    rank, world, local_rank = _dist_info()
    distributed = world > 1
    dev_name = config.device
    if dev_name.startswith("cuda") and not torch.cuda.is_available():
        raise ValueError(f"device: {dev_name} requested but CUDA is not available")
    if distributed:
        backend = "nccl" if dev_name.startswith("cuda") else "gloo"
        if not dist.is_initialized():
            dist.init_process_group(backend)
        if dev_name.startswith("cuda"):
            dev_name = f"cuda:{local_rank}"
    device = torch.device(dev_name)
    if device.type == "cuda":
        torch.cuda.set_device(device)
        torch.backends.cuda.matmul.allow_tf32 = True
        torch.backends.cudnn.allow_tf32 = True
    out = Path(config.out)
    main_rank = rank == 0
    if main_rank:
        out.mkdir(parents=True, exist_ok=True)
        write_text_atomic(out / "config.yaml", dump_yaml(config, murk_version=__version__, world_size=world))
    logger = _Logger(out, main_rank)

    data = build_data(config)
    n_train = len(data.train)
    spe = n_train // world // config.batch
    if spe < 1:
        raise ValueError(
            f"data: {n_train} training samples are fewer than batch {config.batch} x {world} process(es); "
            "lower --batch or add data"
        )
    total = config.steps if config.steps is not None else math.ceil(config.epochs * spe)
    epochs_for_schedule = total / spe
    warm = min(config.optim.warmup_epochs, epochs_for_schedule / 5)
    schedule = Schedule(
        spe, epochs=epochs_for_schedule, base_lr=config.optim.lr, min_lr=config.optim.min_lr, warmup_epochs=warm
    )

    torch.manual_seed(config.seed)
    model = build_network(config.model)
    unused = set(frozen_parameter_names(kind, model))
    for name, p in model.named_parameters():
        if name in unused:
            p.requires_grad_(False)  # checkpoint-only parameters: never used in forward
    model.to(device)
    if config.channels_last:
        model = model.to(memory_format=torch.channels_last)
    optim = torch.optim.AdamW(
        model.parameters(),
        lr=schedule.lr(0),
        betas=tuple(config.optim.betas),
        eps=config.optim.eps,
        weight_decay=config.optim.weight_decay,
        fused=device.type == "cuda",
    )
    start, best = 0, {}
    latest = out / "latest.pt"
    if resume:
        if not latest.is_file():
            raise ValueError(f"--resume: {latest} not found (nothing to resume)")
        state, meta = read_network_checkpoint(kind, latest)
        missing = [k for k in ("optimizer", "step") if k not in meta]
        if missing:
            raise ValueError(
                f"--resume: {latest} has no {' and no '.join(missing)} (not a 'murk train' latest.pt: it holds "
                "weights only); start a new run, or use it as model.init_checkpoint"
            )
        model.load_state_dict({k: v.to(device) for k, v in state.items()}, strict=True)
        optim.load_state_dict(meta["optimizer"])
        start = int(meta["step"])
        best = dict(meta.get("best") or {})
    net = model
    if distributed:
        net = torch.nn.parallel.DistributedDataParallel(
            model, device_ids=[device.index] if device.type == "cuda" else None
        )
    if config.compile:
        net = torch.compile(net)

    summary = TrainSummary(out=out, out_dir=str(out), steps_done=start, skipped=start, total_steps=total, best=best)
    autocast = (
        torch.autocast(device_type=device.type, dtype=torch.bfloat16)
        if config.precision == "bf16"
        else contextlib.nullcontext()
    )
    end = total if stop_after is None else min(total, start + stop_after)

    def batches_from(step: int) -> Iterator[tuple[int, dict[str, Any]]]:
        epoch, offset = divmod(step, spe)
        while True:
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
        batch = _to_device(batch, device)
        if data.online is not None:
            with torch.no_grad():
                inputs = data.online(batch["clean"], batch["depth_filled"], epoch, batch["index"].tolist())
            targets = batch["clean"]
        else:
            inputs, targets = batch["input"], batch["target"]
        gen = torch.Generator().manual_seed(derive_seed(config.seed, "augment", step, rank))
        aug = sample_augment(inputs.shape[0], config.augment, gen)
        inputs, targets, depth = apply_augment(inputs, targets, batch["depth"], aug, config.augment)
        lr = schedule.lr(step)
        for group in optim.param_groups:
            group["lr"] = lr
        x = inputs.contiguous(memory_format=torch.channels_last) if config.channels_last else inputs
        with autocast:
            enhanced, depth_m = run_network(kind, net, x)
        terms = jointid_loss(
            enhanced.float(), targets, None if depth_m is None else depth_m.float(), depth, config.loss
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
            emit(record)
        if step % config.eval.every == 0 or step == end:
            metrics = evaluate(model, data, config, device, step) if main_rank else {}
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
                if better:
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
        write_text_atomic(out / "summary.json", json.dumps(doc, indent=2, default=str) + "\n")
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


# --------------------------------------------------------------------------------------------- evaluation


@torch.no_grad()
def evaluate(
    model: torch.nn.Module, data: DataSetup, config: TrainConfig, device: torch.device, step: int
) -> dict[str, float]:
    """Loss, PSNR/SSIM (and the degraded input's PSNR) and depth errors on the held-out synthetic split (the
    same ``eval.val_batches`` batches every time, unaugmented); UIQM/UCIQE on real images."""
    from murk.metrics import depth_errors_torch, psnr_torch, ssim_torch, uciqe_torch, uiqm_torch
    from murk.models.padding import pad_to_multiple
    from murk.train.networks import run_network, size_multiple

    kind = config.model.kind

    was_training = model.training
    model.eval()
    out: dict[str, float] = {}
    if data.val is not None and len(data.val) > 0:
        loader = DataLoader(data.val, batch_size=config.batch, shuffle=False, num_workers=0)
        ps, ss, errs, in_ps, losses = [], [], [], [], []
        for bi, batch in enumerate(loader):
            if bi >= config.eval.val_batches:
                break
            batch = _to_device(batch, device)
            if data.online is not None:
                # fixed validation degradations: epoch -1 is never used for training
                inputs = data.online(batch["clean"], batch["depth_filled"], -1, batch["index"].tolist())
                targets = batch["clean"]
            else:
                inputs, targets = batch["input"], batch["target"]
            enhanced, depth_m = run_network(kind, model, inputs)
            enhanced = enhanced.float()
            depth_m = None if depth_m is None else depth_m.float()
            losses.append(float(jointid_loss(enhanced, targets, depth_m, batch["depth"], config.loss).total))
            in_ps.append(psnr_torch(inputs.float().clamp(0, 1), targets, data_range=1.0))
            ps.append(psnr_torch(enhanced.clamp(0, 1), targets, data_range=1.0))
            ss.append(ssim_torch(enhanced.clamp(0, 1), targets, data_range=1.0))
            if depth_m is not None:  # networks without a depth head: no depth errors
                errs.append(depth_errors_torch(depth_m, batch["depth"]))
        if ps:
            out["val_loss"] = float(np.mean(losses))
            out["val_psnr"] = float(torch.cat(ps).clamp(max=100).mean())
            out["val_input_psnr"] = float(torch.cat(in_ps).clamp(max=100).mean())
            out["val_ssim"] = float(torch.cat(ss).mean())
            for name in ("silog", "abs_rel", "rmse", "d1"):
                vals = [getattr(e, name, None) for e in errs]
                if vals and all(v is not None for v in vals):
                    out[f"val_{name}"] = float(torch.cat([v.reshape(-1) for v in vals]).nanmean())
    if config.eval.real:
        from murk.io.images import list_images, read_rgb

        files = list_images(config.eval.real, recursive=True)[: config.eval.real_max]
        uiqms, uciqes = [], []
        for f in files:
            img = read_rgb(f)
            h, w = img.shape[:2]
            scale = min(1.0, config.eval.real_max_side / max(h, w))
            x = torch.from_numpy(img).permute(2, 0, 1)[None].to(device)
            if scale < 1.0:
                x = F.interpolate(x, scale_factor=scale, mode="area")
            xp, padding = pad_to_multiple(x, size_multiple(kind))
            o = padding.crop(run_network(kind, model, xp)[0].float()).clamp(0, 1)
            uiqms.append(uiqm_torch(o, data_range=1.0).uiqm)
            uciqes.append(uciqe_torch(o, data_range=1.0).uciqe)
        if uiqms:
            out["real_uiqm"] = float(torch.cat(uiqms).mean())
            out["real_uciqe"] = float(torch.cat(uciqes).mean())
            out["real_images"] = float(len(uiqms))
    if was_training:
        model.train()
    return out
