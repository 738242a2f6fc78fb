"""Evaluation during training: loss, PSNR/SSIM, the affine-fit PSNR (:mod:`murk.metrics.affine_psnr`: what is
left once a global colour correction is forgiven, for the output and for the degraded input) and depth errors
(AbsRel in m/m and median-scaled) on the held-out synthetic split, against the true clean scene; UIQM/UCIQE on
real images (what :func:`murk.train.loop.train` logs at every ``eval.every`` steps and picks ``best.pt`` by)."""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch.utils.data import DataLoader

from murk.io.jobs import ErrorLog
from murk.physics.balance import color_balance_torch
from murk.train.config import TrainConfig
from murk.train.data import record_unreadable
from murk.train.losses import jointid_loss
from murk.train.setup import DataSetup


def to_device(batch: dict[str, Any], device: torch.device) -> dict[str, Any]:
    """The tensors of ``batch`` on ``device`` (non-blocking); other values unchanged."""
    return {k: v.to(device, non_blocking=True) if torch.is_tensor(v) else v for k, v in batch.items()}


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
    from murk.metrics import affine_fit_psnr_torch, depth_errors_torch, psnr_torch, ssim_torch, uciqe_torch, uiqm_torch
    from murk.models.padding import pad_to_multiple
    from murk.train.networks import run_network, size_multiple

    kind = config.model.kind

    was_training = model.training
    model.eval()
    out: dict[str, float] = {}
    if data.val is not None and len(data.val) > 0:
        loader = DataLoader(data.val, batch_size=config.batch, shuffle=False, num_workers=0)
        ps, ss, errs, in_ps, losses, fit, in_fit = [], [], [], [], [], [], []
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
            in_ps.append(psnr_torch(inputs.float().clamp(0, 1), targets, data_range=1.0))
            ps.append(psnr_torch(enhanced.clamp(0, 1), targets, data_range=1.0))
            ss.append(ssim_torch(enhanced.clamp(0, 1), targets, data_range=1.0))
            fit.append(affine_fit_psnr_torch(enhanced.clamp(0, 1), targets, data_range=1.0))
            in_fit.append(affine_fit_psnr_torch(inputs.float().clamp(0, 1), targets, data_range=1.0))
            if depth_m is not None:  # networks without a depth head: no depth errors
                errs.append(depth_errors_torch(depth_m, batch["depth"]))
        if ps:
            out["val_loss"] = float(np.mean(losses))
            out["val_psnr"] = float(torch.cat(ps).clamp(max=100).mean())
            out["val_input_psnr"] = float(torch.cat(in_ps).clamp(max=100).mean())
            out["val_ssim"] = float(torch.cat(ss).mean())
            out["val_affine_psnr"] = float(torch.cat(fit).clamp(max=100).mean())
            out["val_input_affine_psnr"] = float(torch.cat(in_fit).clamp(max=100).mean())
            for name in ("silog", "abs_rel", "abs_rel_median", "rmse", "d1"):
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
            if config.model.input_balance_pct is not None:  # balanced before padding, as the restorers do
                pct = config.model.input_balance_pct
                x = color_balance_torch(x, pct, pct)
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
