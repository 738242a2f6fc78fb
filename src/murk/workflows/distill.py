"""``murk train`` as a library call, with any restoration method as the distillation teacher.

``loss.teacher: method:SPEC`` (with ``loss.distill`` > 0) names a method as ``murk enhance --method`` takes it, for
example ``method:water``: Joint-ID's distance, the water estimator and the inversion of Eq. (1) together. Training
(:mod:`murk.train`) sits below the restoration methods (:mod:`murk.enhance`) and does not run them, so this module
hands :func:`murk.train.loop.train` what builds the method on the process's device (under ``torchrun``, each rank's
own GPU), wrapped as a module (:class:`MethodTeacher`). Every other config trains exactly as
:func:`murk.train.loop.train` alone would.

The method is built from the files murk ships at the time of the run (``method:water`` runs the shipped Joint-ID,
``lite``, and water estimator); neither the run's ``config.yaml`` nor its checkpoints record them, so a run resumed
after those files changed learns from the new ones, and a rerun needs the commit of the first.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import torch

if TYPE_CHECKING:
    from murk.enhance.restorer import Restorer
    from murk.train.config import TrainConfig
    from murk.train.loop import TrainSummary

METHOD_PREFIX = "method:"


class MethodTeacher(torch.nn.Module):
    """A restoration method as a distillation teacher: a batch (B, 3, H, W) in [0, 1] -> the method's restoration
    of it (B, 3, H, W), without gradient. The method gets the raw input and applies its own input balance."""

    def __init__(self, restorer: Restorer) -> None:
        super().__init__()
        self.restorer = restorer

    @torch.no_grad()
    def forward(self, images: torch.Tensor) -> torch.Tensor:
        out = self.restorer.restore_tensor(images.detach().float().to(self.restorer.device)).images
        return out.to(images.device, images.dtype)


def method_teacher(config: TrainConfig) -> Callable[[torch.device], MethodTeacher] | None:
    """What builds the teacher of ``loss.teacher: method:SPEC`` on a device; None for any other config (no
    distillation, or a ``lite`` / ``jointid`` network teacher, which training loads itself). SPEC's names and
    options are checked here, before training starts.

    Raises:
        ValueError: an unknown method or option in SPEC, named as ``loss.teacher``'s.
    """
    from murk.enhance.restorer import check, create

    spec = config.loss.teacher or ""
    if config.loss.distill <= 0 or not spec.startswith(METHOD_PREFIX):
        return None
    method = spec[len(METHOD_PREFIX) :]
    try:
        check(method, shared={"device": config.device})
    except ValueError as exc:
        raise ValueError(f"loss.teacher: {spec}: {exc}") from exc

    def build(device: torch.device) -> MethodTeacher:
        return MethodTeacher(create(method, shared={"device": str(device)}))

    return build


def train_network(
    config: TrainConfig,
    *,
    resume: bool = False,
    stop_after: int | None = None,
    on_log: Callable[[dict[str, Any]], None] | None = None,
) -> TrainSummary:
    """:func:`murk.train.loop.train` with the method teacher that ``config.loss.teacher`` names, if it names one."""
    from murk.train.loop import train

    return train(config, resume=resume, stop_after=stop_after, on_log=on_log, method_teacher=method_teacher(config))
