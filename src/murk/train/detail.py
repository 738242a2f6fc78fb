"""Train the detail network (:mod:`murk.models.detail`) on a base method's restorations of murk's synthetic water.

A sample is a base method's restoration of a degraded scene and the true clean scene, of one size (the workflow
:mod:`murk.workflows.detail_train` makes them). Each step takes ``batch`` random crops of ``crop_px`` pixels and adds
the network's residual to the restorations. With ``crops="frame"`` (the default) every crop is cut from the restoration
padded once by :data:`~murk.models.detail.network.RADIUS_PX` repeated border pixels, with that margin, and the network
runs unpadded on it (:meth:`DetailNet.unpadded`): every pixel of the loss sees the neighbourhood it sees at inference,
the frame's own border only at the frame's edge. ``crops="own"`` pads each crop at its own edges (the first shipped
weights, 2026-12-06 13:40, were learnt so: about a third of each 96x96 crop's loss then sees a border that inference
does not). Frame crops hold one padded copy of the restorations (about 1.1x their memory). The loss is the mean squared
error that the best gain and offset per image and channel leave against the clean scene
(:func:`murk.train.losses.local_mse`: what no global colour correction can do), plus ``colour_weight`` times the mean
over images and channels of the squared mean of the residual (the base's colour stays; without it the colour drifts,
docs/train.md). Adam, a fixed number of steps, seeded; every sample but a tenth trains, the tenth is the validation
split (the same loss on whole images) logged every ``log_every`` steps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor

from murk.models.detail.network import DEFAULT_CHANNELS, RADIUS_PX, DetailNet
from murk.train.losses import local_mse

CROPS = ("frame", "own")
"""How a training crop's border is made (the module doc)."""


@dataclass(frozen=True)
class DetailTrainSettings:
    """``steps`` of Adam (``lr``) on batches of ``batch`` crops of ``crop_px`` pixels, seeded by ``seed``; the
    residual's mean per image and channel costs ``colour_weight`` times its square; the network has ``channels``."""

    steps: int = 2000
    batch: int = 16
    crop_px: int = 96
    lr: float = 1e-3
    colour_weight: float = 10.0
    channels: int = DEFAULT_CHANNELS
    seed: int = 0
    log_every: int = 250
    crops: str = "frame"

    def __post_init__(self) -> None:
        if self.crops not in CROPS:
            raise ValueError(f"crops: expected one of {', '.join(CROPS)}, got {self.crops!r}")
        if min(self.steps, self.batch, self.log_every) < 1 or self.crop_px < 16:
            raise ValueError("steps, batch and log_every: expected at least 1; crop_px: at least 16")
        if isinstance(self.channels, bool) or not isinstance(self.channels, int) or not 1 <= self.channels <= 256:
            raise ValueError(f"channels: expected an int in [1, 256], got {self.channels!r}")
        if not self.lr > 0 or self.colour_weight < 0:
            raise ValueError(f"lr: expected > 0, colour_weight >= 0; got {self.lr!r}, {self.colour_weight!r}")


@dataclass(frozen=True)
class DetailSamples:
    """Training samples of one size: ``restored`` (the base's restorations) and ``clean`` (N, H, W, 3) in
    [0, 1]."""

    restored: np.ndarray
    clean: np.ndarray

    def __post_init__(self) -> None:
        shape = self.restored.shape
        if shape != self.clean.shape or len(shape) != 4 or shape[0] < 10 or shape[3] != 3:
            raise ValueError(
                f"samples: expected restored and clean (N, H, W, 3) alike, N >= 10; got {self.restored.shape}, "
                f"{self.clean.shape}"
            )


def detail_loss(
    net: DetailNet, restored: Tensor, clean: Tensor, colour_weight: float, *, margin: bool = False
) -> Tensor:
    """The loss of the module doc for batches (B, 3, H, W); ``margin``: ``restored`` carries
    :data:`RADIUS_PX` pixels more on each side than ``clean`` (its neighbourhood), and the network runs unpadded."""
    if margin:
        residual = net.unpadded(restored)
        restored = restored[..., RADIUS_PX:-RADIUS_PX, RADIUS_PX:-RADIUS_PX]
    else:
        residual = net(restored)
    colour = (residual.mean(dim=(2, 3)) ** 2).mean()
    return local_mse(restored + residual, clean) + colour_weight * colour


def fit_detail(
    samples: DetailSamples, settings: DetailTrainSettings, log: Callable[[dict[str, float]], None] | None = None
) -> DetailNet:
    """Learn the network from ``samples``; ``log`` receives ``{"step", "loss", "val_loss"}`` every
    ``settings.log_every`` steps and at the end. Deterministic in ``settings.seed`` on the CPU.

    Raises:
        ValueError: images smaller than ``settings.crop_px``.
    """
    n, h, w = samples.restored.shape[:3]
    crop = settings.crop_px
    if min(h, w) < crop:
        raise ValueError(f"samples: images of {w}x{h} are smaller than crop_px {crop}")
    gen = torch.Generator().manual_seed(settings.seed)
    x = torch.from_numpy(np.ascontiguousarray(samples.restored, np.float32)).permute(0, 3, 1, 2)
    y = torch.from_numpy(np.ascontiguousarray(samples.clean, np.float32)).permute(0, 3, 1, 2)
    margin = settings.crops == "frame"
    if margin:  # once, as inference pads the frame: a crop at (t, s) of y has x's [t, t + crop + 2 R) around it
        x = F.pad(x, (RADIUS_PX,) * 4, mode="replicate")
    side = crop + 2 * RADIUS_PX if margin else crop
    order = torch.randperm(n, generator=gen)
    val, train = order[: n // 10], order[n // 10 :]
    with torch.random.fork_rng(devices=[]):  # the initial weights are seeded; the caller's CPU generator is kept
        torch.default_generator.manual_seed(settings.seed)
        net = DetailNet(settings.channels)
    opt = torch.optim.Adam(net.parameters(), lr=settings.lr)
    for step in range(1, settings.steps + 1):
        idx = train[torch.randint(len(train), (settings.batch,), generator=gen)]
        tops = torch.randint(h - crop + 1, (settings.batch,), generator=gen)
        lefts = torch.randint(w - crop + 1, (settings.batch,), generator=gen)
        xb = torch.stack([x[i, :, t : t + side, s : s + side] for i, t, s in zip(idx, tops, lefts, strict=True)])
        yb = torch.stack([y[i, :, t : t + crop, s : s + crop] for i, t, s in zip(idx, tops, lefts, strict=True)])
        loss = detail_loss(net, xb, yb, settings.colour_weight, margin=margin)
        opt.zero_grad()
        loss.backward()
        opt.step()
        if log is not None and (step % settings.log_every == 0 or step == settings.steps):
            with torch.no_grad():
                val_loss = np.mean([float(detail_loss(net, x[i : i + 1], y[i : i + 1], settings.colour_weight,
                                                      margin=margin)) for i in val.tolist()])  # fmt: skip
            log({"step": step, "loss": float(loss.detach()), "val_loss": float(val_loss)})
    return net.eval()
