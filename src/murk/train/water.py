"""Train the water estimator (:mod:`murk.models.water`) on samples of murk's synthetic water.

A sample is a degraded image, the distance map a depth network gave for it and the true clean scene, all at
:data:`murk.restore_ops.water.FEATURE_HW` (the workflow :mod:`murk.workflows.water_train` makes them). The network
reads :func:`murk.restore_ops.water.water_features` and gives the water; the loss inverts Eq. (1) with it
(:func:`murk.restore_ops.water.invert_eq1_torch`, transmission floored at ``t_min``) and measures what a global
colour map cannot take from the result to the clean scene (:func:`murk.train.losses.local_mse`). AdamW, a fixed
number of steps, seeded; every sample but a tenth trains, the tenth is the validation split (same loss) logged every
``log_every`` steps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from murk.models.water.estimator import HIDDEN, VEIL_MAX, WaterEstimator
from murk.restore_ops.water import FEATURES, invert_eq1_torch, water_features
from murk.train.losses import local_mse


@dataclass(frozen=True)
class WaterTrainSettings:
    """``steps`` of AdamW (``lr``, weight decay ``weight_decay``) on batches of ``batch`` samples, seeded by
    ``seed``; the loss inverts Eq. (1) with the transmission floored at ``t_min``."""

    steps: int = 4000
    batch: int = 128
    lr: float = 2e-3
    weight_decay: float = 1e-4
    seed: int = 0
    t_min: float = 0.1
    log_every: int = 500

    def __post_init__(self) -> None:
        if self.steps < 1 or self.batch < 1 or self.log_every < 1:
            raise ValueError("steps, batch and log_every: expected at least 1")
        if not 0.0 < self.t_min <= 1.0:
            raise ValueError(f"t_min: expected a transmission floor in (0, 1], got {self.t_min!r}")


@dataclass(frozen=True)
class WaterSamples:
    """Training samples at the features' size: ``degraded`` and ``clean`` (N, h, w, 3) in [0, 1], ``distance_m``
    (N, h, w) from the depth network."""

    degraded: np.ndarray
    distance_m: np.ndarray
    clean: np.ndarray

    def __post_init__(self) -> None:
        n = self.degraded.shape[0]
        if self.clean.shape != self.degraded.shape or self.distance_m.shape != self.degraded.shape[:3] or n < 10:
            raise ValueError(
                "samples: expected degraded and clean (N, h, w, 3), distance_m (N, h, w), N >= 10; got "
                f"{self.degraded.shape}, {self.clean.shape}, {self.distance_m.shape}"
            )


def water_network() -> nn.Sequential:
    """The estimator's network in torch (the numpy one of :class:`WaterEstimator` computes the same)."""
    return nn.Sequential(
        nn.Linear(FEATURES, HIDDEN),
        nn.GELU(approximate="tanh"),
        nn.Linear(HIDDEN, HIDDEN),
        nn.GELU(approximate="tanh"),
        nn.Linear(HIDDEN, 6),
    )


def _water_torch(outputs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Torch twin of :func:`murk.models.water.water_from_outputs`."""
    return torch.sigmoid(outputs[:, :3]) * VEIL_MAX, torch.exp(outputs[:, 3:].clamp(-8.0, 2.0))


def fit_water(
    samples: WaterSamples,
    settings: WaterTrainSettings,
    log: Callable[[dict[str, float]], None] | None = None,
) -> WaterEstimator:
    """Learn the estimator from ``samples``; ``log`` receives ``{"step", "loss", "val_loss"}`` every
    ``settings.log_every`` steps and at the end. Deterministic in ``settings.seed`` on the CPU."""
    gen = torch.Generator().manual_seed(settings.seed)
    torch.manual_seed(settings.seed)
    feats = np.stack([water_features(i, d) for i, d in zip(samples.degraded, samples.distance_m, strict=True)])
    x = torch.from_numpy(feats.astype(np.float32))
    images = torch.from_numpy(samples.degraded.astype(np.float32))
    dist = torch.from_numpy(samples.distance_m.astype(np.float32))
    clean = torch.from_numpy(samples.clean.astype(np.float32))
    mu, sd = x.mean(0), x.std(0) + 1e-6
    n = x.shape[0]
    order = torch.randperm(n, generator=gen)
    val, train = order[: n // 10], order[n // 10 :]
    net = water_network()
    opt = torch.optim.AdamW(net.parameters(), lr=settings.lr, weight_decay=settings.weight_decay)

    def loss_of(idx: torch.Tensor) -> torch.Tensor:
        veil, att = _water_torch(net((x[idx] - mu) / sd))
        restored = invert_eq1_torch(images[idx], dist[idx], veil, att, settings.t_min)
        return local_mse(restored.permute(0, 3, 1, 2), clean[idx].permute(0, 3, 1, 2))

    for step in range(1, settings.steps + 1):
        idx = train[torch.randint(len(train), (settings.batch,), generator=gen)]
        loss = loss_of(idx)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if log is not None and (step % settings.log_every == 0 or step == settings.steps):
            with torch.no_grad():
                val_loss = float(loss_of(val))
            log({"step": step, "loss": float(loss.detach()), "val_loss": val_loss})
    layers = [m for m in net if isinstance(m, nn.Linear)]
    arrays = {"mu": mu.numpy(), "sd": sd.numpy()}
    for k, layer in enumerate(layers, 1):
        arrays[f"w{k}"] = layer.weight.detach().numpy().T.copy()
        arrays[f"b{k}"] = layer.bias.detach().numpy().copy()
    return WaterEstimator({k: v.astype(np.float64) for k, v in arrays.items()})
