"""Evaluation during training: loss, PSNR/SSIM, the affine-fit PSNR (:mod:`murk.metrics.affine_psnr`: what is
left once a global colour correction is forgiven, for the output and for the degraded input) and depth errors
(AbsRel in m/m and median-scaled) on the held-out synthetic split, against the true clean scene; UIQM/UCIQE on
real images (what :func:`murk.train.loop.train` logs at every ``eval.every`` steps and picks ``best.pt`` by).

The metrics are rows of the metric table (:mod:`murk.metrics.table`) with a torch twin: every full-reference one
(``val_<name>``; those in dB also for the degraded input, ``val_input_<name>``, and capped at 100 dB, the PSNR of
an exact copy being infinite), the headline depth errors (``val_<name>``) and the headline no-reference scores
(``real_<name>``)."""

from __future__ import annotations

from collections.abc import Sized
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader

from murk.io.jobs import ErrorLog, ErrorRecord
from murk.metrics import table
from murk.metrics.depth import valid_depth_torch
from murk.restore_ops.balance import color_balance_torch
from murk.train.config import TrainConfig
from murk.train.data import record_unreadable
from murk.train.losses import jointid_loss
from murk.train.setup import DataSetup


def to_device(batch: dict[str, Any], device: torch.device) -> dict[str, Any]:
    """The tensors of ``batch`` on ``device`` (non-blocking); other values unchanged."""
    return {k: v.to(device, non_blocking=True) if torch.is_tensor(v) else v for k, v in batch.items()}


def check_real_folder(folder: str | Path) -> None:
    """``eval.real`` (``murk train --eval-real``) checked before the first step: a folder holding images.

    Raises:
        InputFileError: not a folder, no image in it (recursively), or none that can be read.
    """
    from murk.errors import InputFileError
    from murk.io.images import list_images, read_image

    path = Path(folder)
    if not path.is_dir():
        raise InputFileError(path, "eval.real (--eval-real): not a folder")
    files = list_images(path, recursive=True)
    if not files:
        raise InputFileError(path, "eval.real (--eval-real): no images in this folder")
    for f in files:  # the first image that decodes ends the check (the rest are read at each evaluation)
        try:
            read_image(f)
            return
        except (OSError, ValueError):
            continue
    raise InputFileError(path, f"eval.real (--eval-real): none of its {len(files)} images can be read")


@torch.no_grad()
def evaluate(
    model: torch.nn.Module,
    data: DataSetup,
    config: TrainConfig,
    device: torch.device,
    step: int,
    errors: ErrorLog | None = None,
) -> dict[str, float]:
    """Loss, PSNR/SSIM (and the degraded input's PSNR) and depth errors on the held-out synthetic split (the
    same ``eval.val_batches`` batches every time, unaugmented); UIQM/UCIQE on real images."""
    from murk.models.padding import pad_to_multiple
    from murk.train.networks import run_network, size_multiple

    kind = config.model.kind

    was_training = model.training
    model.eval()
    out: dict[str, float] = {}
    refs = [m for m in table.metrics("reference") if m.torch_function is not None]
    depths = [m for m in table.metrics("depth") if m.headline and m.torch_function is not None]
    if data.val is not None and len(cast(Sized, data.val)) > 0:
        loader = DataLoader(data.val, batch_size=config.batch, shuffle=False, num_workers=0)
        twins = {m.name: m.load(torch=True) for m in refs}
        depth_twin = depths[0].load(torch=True) if depths else None
        scores: dict[str, list[torch.Tensor]] = {}
        errs, losses = [], []
        for bi, batch in enumerate(loader):
            if bi >= config.eval.val_batches:
                break
            record_unreadable(batch, errors)  # an unreadable validation sample: replaced, recorded
            batch = to_device(batch, device)
            if data.online is not None:
                # fixed validation degradations: epoch -1 is never used for training
                inputs = data.online(batch["clean"], batch["depth_filled"], -1, batch["index"].tolist())
                targets = batch["clean"]
            else:
                inputs, targets = batch["input"], batch["target"]
            enhanced, depth_m = run_network(kind, model, inputs, config.model.input_balance_pct)
            enhanced = enhanced.float()
            depth_m = None if depth_m is None else depth_m.float()
            losses.append(float(jointid_loss(enhanced, targets, depth_m, batch["depth"], config.loss).total))
            for m in refs:
                fn = twins[m.name]
                scores.setdefault(m.name, []).append(m.value(fn(enhanced.clamp(0, 1), targets, data_range=1.0)))
                if m.unit == "dB":  # and the degraded input's, the bar to clear
                    x = inputs.float().clamp(0, 1)
                    scores.setdefault(f"input_{m.name}", []).append(m.value(fn(x, targets, data_range=1.0)))
            if depth_m is not None and depth_twin is not None:  # networks without a depth head: no depth errors
                # a layout-prior distance is no target (all invalid): those images get no depth errors
                scored = valid_depth_torch(batch["depth"]).flatten(1).any(dim=1)
                if bool(scored.any()):
                    errs.append(depth_twin(depth_m[scored], batch["depth"][scored]))
        if losses:
            out["val_loss"] = float(np.mean(losses))
            for m in refs:
                for key in (m.name, f"input_{m.name}") if m.unit == "dB" else (m.name,):
                    values = torch.cat(scores[key])
                    out[f"val_{key}"] = float((values.clamp(max=100) if m.unit == "dB" else values).mean())
            for m in depths:
                if errs:
                    out[f"val_{m.name}"] = float(torch.cat([m.value(e).reshape(-1) for e in errs]).nanmean())
    if config.eval.real:
        from murk.io.images import list_images, read_rgb

        files = list_images(config.eval.real, recursive=True)[: config.eval.real_max]
        norefs = [m for m in table.metrics("none") if m.headline and m.torch_function is not None]
        real: dict[str, list[torch.Tensor]] = {m.name: [] for m in norefs}
        for f in files:
            try:
                img = read_rgb(f)
            except (OSError, ValueError) as exc:  # one unreadable image costs its score, never the run
                if errors is not None:
                    why = str(exc) if str(f) in str(exc) else f"{f}: {exc}"
                    errors.add_once(ErrorRecord(str(f), "eval", f"{why}; left out of the real-image scores"))
                continue
            h, w = img.shape[:2]
            scale = min(1.0, config.eval.real_max_side / max(h, w))
            x = torch.from_numpy(img).permute(2, 0, 1)[None].to(device)
            if scale < 1.0:
                x = F.interpolate(x, scale_factor=scale, mode="area")
            if config.model.input_balance_pct is not None:  # balanced before padding, as the restorers do
                pct = config.model.input_balance_pct
                x = color_balance_torch(x, pct, pct)
            xp, padding = pad_to_multiple(x, size_multiple(kind))
            o = padding.crop(run_network(kind, model, xp)[0].float()).clamp(0, 1)
            for m in norefs:
                real[m.name].append(m.value(m.load(torch=True)(o, data_range=1.0)))
        scored_n = len(next(iter(real.values()), []))
        if scored_n:
            out.update({f"real_{name}": float(torch.cat(values).mean()) for name, values in real.items()})
            out["real_images"] = float(scored_n)
    if was_training:
        model.train()
    return out
