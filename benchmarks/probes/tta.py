"""Probe (issue 46, item 3, 2026-12-07; measured, not kept): test-time adaptation of ``lite`` to each image.

A fresh copy of the shipped ``lite`` is fine-tuned on the image it is about to restore (Adam, every parameter,
``steps`` steps at ``lr``), from nothing but that image, then restores it. ``target``:
- ``rehaze`` (the write-up's arm ``a``): the shipped output ``J0`` hazed again by Eq. (1) with the water the
  ``water`` estimator reads from the image and ``jointid_net``'s distance, ``J0 t + B (1 - t)``, is the training
  input and ``J0`` the target;
- ``synth`` (``s``): ``J0`` and the same distance through four draws of the study's synthesis
  (configs/train-lite-mild-scratch-cpu.yaml: Eqs. 1-8, real snow) are the inputs, ``J0`` the target;
  for both, the adapted network's output ``J`` gives the result ``J0 + mix (J - J0)``;
- ``cycle`` (``c``): the output ``J`` hazed again with the estimated water must match the image after the best
  per-channel gain and offset, beside an L1 anchor to ``J0`` weighted ``mix``; the result is ``J``.
The ``rehaze`` and ``synth`` targets flip their inputs every other step.

Run (the write-up's table, docs/train.md "Test-time adaptation to each image"): PYTHONPATH=src python
     benchmarks/bench_arms.py --probe benchmarks/probes/tta.py lite=lite "a=tta?target=rehaze,steps=20"
     "s=tta?target=synth,steps=20" "c=tta?target=cycle,steps=20,mix=1" --ref lite --real-pairs <pairs>
     --heldout-scenes 24 --threads 1
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import torch

from murk._config import load_yaml
from murk.enhance.restorer import Restored, Restorer, create, register
from murk.models.lite.network import work_image
from murk.models.water import load_water_estimator
from murk.restore_ops.balance import color_balance_torch
from murk.train.config import TrainConfig
from murk.train.data import OnlineDegrader

TARGETS = ("rehaze", "synth", "cycle")
STUDY_CONFIG = Path(__file__).resolve().parents[2] / "configs" / "train-lite-mild-scratch-cpu.yaml"
SYNTH_DRAWS = 4


def chw(image: np.ndarray) -> torch.Tensor:
    """(H, W, 3) numpy -> (1, 3, H, W) torch."""
    return torch.from_numpy(np.ascontiguousarray(np.asarray(image, np.float32).transpose(2, 0, 1)))[None]


class TestTimeLite(Restorer):
    name = "tta"

    def __init__(self, target: str, steps: int, lr: float, mix: float) -> None:
        if target not in TARGETS:
            raise ValueError(f"target: expected one of {', '.join(TARGETS)}, got {target!r}")
        self.target, self.steps, self.lr, self.mix = target, steps, lr, mix
        self.lite, self.depth = create("lite"), create("jointid_net")
        self.estimator = load_water_estimator(None)
        synthesis = load_yaml(TrainConfig, STUDY_CONFIG).data.synthesis
        self.degrader, self.calls = OnlineDegrader(synthesis, seed=99), 0

    def _balanced(self, x: torch.Tensor) -> torch.Tensor:
        pct = self.lite.input_balance_pct
        return color_balance_torch(x, pct, pct) if pct is not None else x

    def restore(self, images: np.ndarray) -> Restored:
        images = np.asarray(images, np.float32)
        return Restored(np.stack([self._one(image) for image in images]).astype(np.float32))

    def _one(self, image: np.ndarray) -> np.ndarray:
        j0 = self.lite.restore(image[None]).images[0]
        distance = self.depth.restore(image[None]).depth_m[0]
        water = self.estimator.estimate(image, distance)
        veil = np.asarray(water.veil, np.float32)
        t = np.exp(-np.asarray(water.attenuation_per_m, np.float32)[None, None] * distance[..., None]).astype(
            np.float32
        )
        net = copy.deepcopy(self.lite.model).train().to(memory_format=torch.contiguous_format)
        opt = torch.optim.Adam(net.parameters(), lr=self.lr)
        x0 = self._balanced(chw(image))
        w0 = work_image(x0, net.config.work_area_px)
        if self.target == "cycle":
            self._fit_cycle(net, opt, x0, w0, chw(image), chw(j0), chw(t), torch.from_numpy(veil)[None, :, None, None])
        else:
            if self.target == "synth":
                clean = chw(j0).repeat(SYNTH_DRAWS, 1, 1, 1)
                depth = torch.from_numpy(np.ascontiguousarray(distance))[None, None].repeat(SYNTH_DRAWS, 1, 1, 1)
                hazed = self.degrader(clean, depth, self.calls, list(range(SYNTH_DRAWS))).clamp(0, 1)
                self.calls += 1
            else:
                hazed = chw(j0 * t + veil * (1 - t))
            self._fit_pairs(net, opt, self._balanced(hazed.contiguous()), chw(j0).repeat(len(hazed), 1, 1, 1))
        net.eval()
        with torch.no_grad():
            y = net(x0, w0).clamp(0, 1)[0].numpy().transpose(1, 2, 0)
        return y if self.target == "cycle" else j0 + self.mix * (y - j0)

    def _fit_pairs(
        self, net: torch.nn.Module, opt: torch.optim.Optimizer, x: torch.Tensor, target: torch.Tensor
    ) -> None:
        work = work_image(x, net.config.work_area_px)
        for step in range(self.steps):
            flip = step % 2 == 1
            xi, wi, ti = (x.flip(-1), work.flip(-1), target.flip(-1)) if flip else (x, work, target)
            loss = (net(xi, wi).clamp(0, 1) - ti).abs().mean()
            opt.zero_grad()
            loss.backward()
            opt.step()

    def _fit_cycle(self, net, opt, x0, w0, image, j0, t, veil) -> None:  # type: ignore[no-untyped-def]
        for _ in range(self.steps):
            out = net(x0, w0).clamp(0, 1)
            hazed = (out * t + veil * (1 - t)).flatten(2)
            seen = image.flatten(2)
            hm, sm = hazed.mean(-1, keepdim=True), seen.mean(-1, keepdim=True)
            gain = ((hazed - hm) * (seen - sm)).mean(-1, keepdim=True) / (
                (hazed - hm).pow(2).mean(-1, keepdim=True) + 1e-6
            )
            loss = (gain * (hazed - hm) + sm - seen).abs().mean() + self.mix * (out - j0).abs().mean()
            opt.zero_grad()
            loss.backward()
            opt.step()


@register("tta")
def make_tta(*, target: str = "cycle", steps: int = 20, lr: float = 3e-4, mix: float = 1.0) -> TestTimeLite:
    """``lite`` fine-tuned on each image before it restores it (a probe, not kept)."""
    return TestTimeLite(target, steps, lr, mix)
