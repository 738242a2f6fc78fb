"""Setting up a training run (what :func:`murk.train.loop.train` starts with): the data (a ``murk synth`` folder,
a Joint-ID list, clean RGB-D with online synthesis, or procedural scenes), the process group and device, the
step budget and learning-rate schedule, the network and its optimiser, and the state resumed from ``latest.pt``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
import torch.distributed as dist
from torch.utils.data import Dataset

from murk._config import read_yaml, to_dict
from murk.io.pairs import DepthOptions
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
from murk.train.schedule import Schedule
from murk.train.sources import detect_kind

# ------------------------------------------------------------------------------------------------ data


@dataclass
class DataSetup:
    train: Dataset
    val: Dataset | None
    online: OnlineDegrader | None
    kind: str


def build_data(config: TrainConfig) -> DataSetup:
    d = config.data
    kind = d.kind if d.kind != "auto" else detect_kind(d.source, d.depth_from)
    crop = (int(d.crop_hw[0]), int(d.crop_hw[1]))
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
        sources = rgbd_sources(d.source, d.depth_from)
        opts = depth_options(config)
        ti, vi = split_by_stem([s.stem for s in sources], d.val_fraction, config.seed)
        online = OnlineDegrader(d.synthesis, seed=config.seed)
        train = CleanRGBDDataset([sources[i] for i in ti], crop, opts)
        val = CleanRGBDDataset([sources[i] for i in vi], crop, opts) if vi else None
        return DataSetup(train, val, online, kind)
    if kind == "shards":  # streamed tar shards (murk.train.shard_data): split by rank and worker per epoch
        from murk.train.shard_data import build_shard_data

        train_stream, val_shards = build_shard_data(config, dist_info()[1])
        return DataSetup(train_stream, val_shards, None, kind)  # type: ignore[arg-type]
    if kind == "scenes":
        from murk.train.scenes_source import SceneDataset

        count = int(d.source.split(":", 1)[1]) if ":" in d.source else d.scenes_count
        n_val = max(1, round(d.val_fraction * count)) if d.val_fraction > 0 else 0
        online = OnlineDegrader(d.synthesis, seed=config.seed)
        cache = d.cache_scenes and d.workers == 0
        from murk.scenes import SceneConfig

        scene_config = SceneConfig(water_background=d.scene_water_background) if d.scene_water_background else None

        def scenes_of(indices: range) -> SceneDataset:
            return SceneDataset(
                indices,
                crop,
                seed=config.seed,
                config=scene_config,
                cache=cache,
                scale=d.scene_scale,
                saturation=d.scene_saturation,
                contrast=d.scene_contrast,
                balance_pct=d.scene_balance_pct,
            )

        scenes = scenes_of(range(n_val, count))
        scenes_val = scenes_of(range(n_val)) if n_val else None
        if d.photos is not None:
            from murk.train.photo_source import PhotoDataset, ScenesAndPhotos, photo_repeats

            photos = rgbd_sources(d.photos, d.depth_from)
            repeats = photo_repeats(len(scenes), len(photos), d.photos_share)
            windows = PhotoDataset(
                photos,
                crop,
                depth_options(config),
                seed=config.seed,
                repeats=repeats,
                scale=d.photos_scale,
                balance_pct=d.scene_balance_pct,
                cache=cache,
            )
            return DataSetup(ScenesAndPhotos([scenes, windows]), scenes_val, online, kind)
        return DataSetup(scenes, scenes_val, online, kind)
    raise ValueError(f"data.kind: expected auto, synth, list, rgbd, scenes or shards, got {kind!r}")


def depth_options(config: TrainConfig) -> DepthOptions:
    """How the run reads the depth of its clean RGB-D sources (``data.depth_*``, ``data.invalid_depth``)."""
    d = config.data
    return DepthOptions(
        depth_scale=d.depth_scale,
        invalid=d.invalid_depth,
        encoding=d.depth_encoding,
        depth_from=d.depth_from,
        layout_seed=config.seed,
    )


# ---------------------------------------------------------------------------------------- process, device


@dataclass(frozen=True)
class Runtime:
    """Where this process trains: its rank among ``world`` processes and its device."""

    rank: int
    world: int
    device: torch.device

    @property
    def distributed(self) -> bool:
        return self.world > 1

    @property
    def main(self) -> bool:
        """The process that writes checkpoints and logs."""
        return self.rank == 0


def dist_info() -> tuple[int, int, int]:
    """(rank, world size, local rank) from the ``torchrun`` environment (0, 1, 0 without it)."""
    world = int(os.environ.get("WORLD_SIZE", "1"))
    return int(os.environ.get("RANK", "0")), world, int(os.environ.get("LOCAL_RANK", "0"))


def init_runtime(device_name: str) -> Runtime:
    """Join the process group under ``torchrun`` (gloo on CPU, NCCL on CUDA) and pick this process's device.

    Raises:
        ValueError: CUDA requested but not available.
    """
    rank, world, local_rank = dist_info()
    if device_name.startswith("cuda") and not torch.cuda.is_available():
        raise ValueError(
            f"device: {device_name} requested but CUDA is not available; leave --device out to train on the CPU, "
            "or install a CUDA build of torch"
        )
    if world > 1:
        backend = "nccl" if device_name.startswith("cuda") else "gloo"
        if not dist.is_initialized():
            dist.init_process_group(backend)
        if device_name.startswith("cuda"):
            device_name = f"cuda:{local_rank}"
    device = torch.device(device_name)
    if device.type == "cuda":
        torch.cuda.set_device(device)
        torch.backends.cuda.matmul.allow_tf32 = True
        torch.backends.cudnn.allow_tf32 = True
    return Runtime(rank, world, device)


# ------------------------------------------------------------------------------ steps, model, optimiser


def plan_steps(config: TrainConfig, n_train: int, world: int) -> tuple[int, int, Schedule]:
    """(steps per epoch, total steps, learning-rate schedule) of a run over ``n_train`` samples.

    Raises:
        ValueError: fewer samples than one step needs.
    """
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
    return spe, total, schedule


def build_model(config: TrainConfig, device: torch.device) -> torch.nn.Module:
    """The network of ``config.model``, seeded by ``config.seed``, on ``device``; checkpoint-only parameters
    (never used in forward) are frozen, and with ``model.trainable`` other than ``all`` everything but that head."""
    from murk.train.networks import build_network, frozen_parameter_names, trainable_parameter_names

    torch.manual_seed(config.seed)
    model = build_network(config.model)
    unused = set(frozen_parameter_names(config.model.kind, model))
    trainable = trainable_parameter_names(config.model, model)
    for name, p in model.named_parameters():
        if name in unused or name not in trainable:
            p.requires_grad_(False)
    model.to(device)
    if config.channels_last:
        model = model.to(memory_format=torch.channels_last)  # type: ignore[call-overload]  # torch stubs lack it
    return model


def build_optimiser(
    config: TrainConfig, model: torch.nn.Module, lr: float, device: torch.device
) -> torch.optim.Optimizer:
    """AdamW over the model's parameters as ``config.optim`` says (fused on CUDA)."""
    return torch.optim.AdamW(
        model.parameters(),
        lr=lr,
        betas=(float(config.optim.betas[0]), float(config.optim.betas[1])),
        eps=config.optim.eps,
        weight_decay=config.optim.weight_decay,
        fused=device.type == "cuda",
    )


RESUMABLE_CHANGES = ("out", "eval", "log_every", "device", "data.workers", "data.cache_scenes", "compile")
"""Settings that may differ when a run is resumed (where it writes, how it reports, where it runs); every other
setting shapes the training and must stay as the run began, or the continuation is not the run it claims."""


def check_run_folder(out: Path, config: TrainConfig, *, resume: bool) -> None:
    """Refuse to start a run over an earlier one, and to resume one with other training settings.

    Raises:
        ValueError: ``out`` holds a ``latest.pt`` and ``resume`` is False; ``resume`` without a ``latest.pt``; or
            ``resume`` with settings that differ from the run's ``config.yaml`` outside :data:`RESUMABLE_CHANGES`
            (the message lists them).
    """
    latest = out / "latest.pt"
    if not resume:
        if latest.exists():
            raise ValueError(
                f"{out}: holds an earlier run ({latest.name}); pass --resume to continue it, or choose another --out"
            )
        return
    if not latest.is_file():
        raise ValueError(f"--resume: {latest} not found (nothing to resume); leave --resume out to start a new run")
    try:
        before = read_yaml(out / "config.yaml")
    except ValueError:  # no (readable) config.yaml: an older run folder; the checkpoint itself is checked later
        return
    now = _flat(to_dict(config))
    then = _flat(before)
    changed = [
        k
        for k in sorted(now)
        if k in then and now[k] != then[k] and not any(k == p or k.startswith(p + ".") for p in RESUMABLE_CHANGES)
    ]
    if changed:
        listed = ", ".join(f"{k} {then[k]!r} -> {now[k]!r}" for k in changed[:6])
        more = f" and {len(changed) - 6} more" if len(changed) > 6 else ""
        raise ValueError(
            f"--resume: {out / 'config.yaml'} was trained with other settings ({listed}{more}); resume with the "
            "run's own settings, or start a new run in another --out (model.init_checkpoint starts from its weights)"
        )


def _flat(tree: Any, prefix: str = "") -> dict[str, Any]:
    """Nested dicts -> {"a.b": value}; lists and tuples compare as lists."""
    if isinstance(tree, dict):
        out: dict[str, Any] = {}
        for k, v in tree.items():
            out.update(_flat(v, f"{prefix}{k}."))
        return out
    return {prefix[:-1]: list(tree) if isinstance(tree, (list, tuple)) else tree}


def resume_state(
    latest: Path, config: TrainConfig, model: torch.nn.Module, optim: torch.optim.Optimizer, device: torch.device
) -> tuple[int, dict[str, Any]]:
    """Load the weights and optimiser state of ``latest`` into ``model``/``optim``; return (step, best).

    Raises:
        ValueError: no ``latest.pt``, or one without optimiser state and step (weights only).
    """
    from murk.train.networks import read_network_checkpoint

    if not latest.is_file():
        raise ValueError(f"--resume: {latest} not found (nothing to resume); leave --resume out to start a new run")
    state, meta = read_network_checkpoint(config.model.kind, latest, trust=config.model.trust_checkpoint)
    missing = [k for k in ("optimizer", "step") if k not in meta]
    if missing:
        raise ValueError(
            f"--resume: {latest} has no {' and no '.join(missing)} (not a 'murk train' latest.pt: it holds "
            "weights only); start a new run, or use it as model.init_checkpoint"
        )
    model.load_state_dict({k: v.to(device) for k, v in state.items()}, strict=True)
    optim.load_state_dict(meta["optimizer"])
    return int(meta["step"]), dict(meta.get("best") or {})
