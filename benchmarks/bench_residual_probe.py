"""A learned local residual after ``lite``, probed (issue 46, item 3; docs/train.md, "A learned local residual after
`lite`"): ``out = lite(x) + R(lite(x))``, ``R`` a small full-resolution network trained here on ``lite``'s outputs of
murk's synthetic water with the affine-fit loss, then scored beside ``lite`` on the measures of issue 46. Nothing is
kept but what it prints (and ``--out``, when given: the training images and the weights, for a look).

Run: PYTHONPATH=src python benchmarks/bench_residual_probe.py --real-pairs <realpairs_dev> --snow-pairs <snow pairs>
     [--scenes 500] [--draws 2] [--steps 2000] [--colour-weight 0] [--threads 2] [--out DIR]

- ``R``: five 3x3 convolutions (24 channels, dilations 1, 2, 4, 1), ReLU between, the last starting at zero.
- Training images: ``--scenes`` procedural scenes at 320x240 (their own seeds, balanced 0.5 % as the held-out
  targets are), ``--draws`` degradations each with ``configs/train-lite-mild-scratch-cpu.yaml``'s synthesis (basic,
  forward scatter, marine snow), restored by the shipped ``lite``; 96x96 crops, batch 16, Adam 1e-3.
- Loss: the mean squared error left after the output's best gain and offset per channel onto the true clean scene
  (``murk.train.losses.affine_fit_torch``), plus ``--colour-weight`` x the square of the residual's mean per image and
  channel (0: the colour may move; 10: ``lite``'s colour stays).
- Scores: the 64 held-out scenes of ``murk study`` (seed 20261201) in the study's water and in
  ``configs/train-small-cpu.yaml``'s, scored and printed as ``bench_arms.py`` does (affine-fit PSNR and PSNR against
  the true scene, paired); the real pairs (PSNR at 256 px, mean over sets and paired over images) and the real snow
  pairs (snow residue). ``R`` is no registered method, so the last two are scored here with murk's metrics.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from bench_arms import heldout, paired  # this folder's: the same paired figures and held-out lines
from torch import nn

from murk._config import load_yaml, merge
from murk.enhance.restorer import Restored, Restorer, create
from murk.io import read_rgb
from murk.io.images import list_images
from murk.metrics import psnr
from murk.metrics.snow_pairs import snow_residue, snow_sites
from murk.report.compare import downscale_to
from murk.report.heldout import make_heldout
from murk.restore_ops.balance import color_balance
from murk.rng import derive_seed
from murk.scenes import render_scene, sample_scene
from murk.train.augment import centre_crop
from murk.train.config import TrainConfig
from murk.train.data import OnlineDegrader
from murk.train.losses import affine_fit_torch
from murk.train.scenes_source import render_size

HELDOUT_SEED = 20261201
STUDY_WATER = Path("configs/train-lite-mild-scratch-cpu.yaml")
SMALL_WATER = Path("configs/train-small-cpu.yaml")
CROP_PX = 96


def residual_net(channels: int = 24) -> nn.Sequential:
    """``R``: the residual it adds to ``lite``'s output (zero at the start)."""
    c = channels
    net = nn.Sequential(
        nn.Conv2d(3, c, 3, padding=1),
        nn.ReLU(),
        nn.Conv2d(c, c, 3, padding=2, dilation=2),
        nn.ReLU(),
        nn.Conv2d(c, c, 3, padding=4, dilation=4),
        nn.ReLU(),
        nn.Conv2d(c, c, 3, padding=1),
        nn.ReLU(),
        nn.Conv2d(c, 3, 3, padding=1),
    )
    last = net[-1]
    assert isinstance(last, nn.Conv2d)
    nn.init.zeros_(last.weight)
    nn.init.zeros_(last.bias)  # type: ignore[arg-type]
    return net


def synthesis(config: Path) -> Any:
    return merge(load_yaml(TrainConfig, config).data.synthesis, {"stages": ["basic", "forward_scatter", "marine_snow"]})


def training_images(scenes: int, draws: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """``lite``'s outputs of degraded scenes and the true scenes, (N, 3, 240, 320) each."""
    cleans, dists = [], []
    for i in range(scenes):
        scene = sample_scene(derive_seed(seed, "probe-res", i))
        rgb, dist_m = centre_crop(list(render_scene(scene, render_size((240, 320)))), (240, 320), source=f"scene {i}")
        cleans.append(color_balance(rgb, 0.5, 0.5))
        dists.append(dist_m)
    clean = torch.from_numpy(np.stack(cleans).astype(np.float32)).permute(0, 3, 1, 2)
    dist = torch.from_numpy(np.stack(dists).astype(np.float32))[:, None]
    degrader, lite = OnlineDegrader(synthesis(STUDY_WATER), seed=seed), create("lite")
    inputs, targets = [], []
    for draw in range(draws):
        for start in range(0, scenes, 50):
            idx = list(range(start, min(scenes, start + 50)))
            degraded = degrader(clean[idx], dist[idx], draw, idx).clamp(0, 1).permute(0, 2, 3, 1).numpy()
            inputs.append(torch.from_numpy(np.clip(lite(degraded).images, 0, 1)).permute(0, 3, 1, 2))
            targets.append(clean[idx])
    return torch.cat(inputs), torch.cat(targets)


def train(x: torch.Tensor, y: torch.Tensor, steps: int, colour_weight: float, seed: int) -> nn.Sequential:
    torch.manual_seed(seed)
    net, rng = residual_net(), np.random.default_rng(seed)
    opt = torch.optim.Adam(net.parameters(), 1e-3)
    n, h, w = x.shape[0], x.shape[2], x.shape[3]
    t0 = time.perf_counter()
    for step in range(steps):
        idx, ys, xs = rng.integers(0, n, 16), rng.integers(0, h - CROP_PX, 16), rng.integers(0, w - CROP_PX, 16)
        xb = torch.stack([x[i, :, r : r + CROP_PX, c : c + CROP_PX] for i, r, c in zip(idx, ys, xs, strict=True)])
        yb = torch.stack([y[i, :, r : r + CROP_PX, c : c + CROP_PX] for i, r, c in zip(idx, ys, xs, strict=True)])
        residual = net(xb)
        out = xb + residual
        loss = ((affine_fit_torch(out, yb) - yb) ** 2).mean() + colour_weight * (residual.mean(dim=(2, 3)) ** 2).mean()
        opt.zero_grad()
        loss.backward()
        opt.step()
        if step % 500 == 0 or step == steps - 1:
            print(f"step {step}: loss {loss.item():.5f} ({time.perf_counter() - t0:.0f} s)", flush=True)
    return net.eval()


def apply(net: nn.Sequential, images: np.ndarray) -> np.ndarray:
    """``images + R(images)`` for float RGB (B, H, W, 3), clipped to [0, 1]."""
    with torch.no_grad():
        t = torch.from_numpy(np.ascontiguousarray(images, dtype=np.float32)).permute(0, 3, 1, 2)
        return np.clip((t + net(t)).permute(0, 2, 3, 1).numpy(), 0.0, 1.0)


class LitePlusResidual(Restorer):
    """``lite``, then ``R``: the arm scored beside ``lite`` (a restorer, as murk's held-out scoring takes them)."""

    name = "lite+R"

    def __init__(self, net: nn.Sequential) -> None:
        self.net, self.lite = net, create("lite")

    def restore(self, images: np.ndarray) -> Restored:
        return Restored(apply(self.net, np.clip(self.lite(images).images, 0.0, 1.0)))


def score_heldout(net: nn.Sequential, config: Path) -> None:
    """``murk study``'s held-out scoring (:func:`murk.report.heldout.score_heldout`) as ``bench_arms.py`` prints it."""
    data = make_heldout(64, seed=HELDOUT_SEED, size_hw=(240, 320), synthesis=synthesis(config), balance_pct=0.5)
    arms = {"lite": create("lite"), "lite + R": LitePlusResidual(net)}
    heldout(arms, f"held-out scenes, {config.name}'s water (64)", data, "lite")


def score_real_pairs(net: nn.Sequential, folder: Path) -> None:
    lite = create("lite")
    per_set: dict[str, list[tuple[float, float]]] = {}
    for set_dir in sorted(p for p in folder.iterdir() if p.is_dir()):
        for src in list_images(set_dir / "input"):
            x = downscale_to(read_rgb(src), 256)
            ref = downscale_to(read_rgb(next((set_dir / "reference").glob(src.stem + ".*"))), 256)
            a = np.clip(lite(x[None]).images, 0, 1)
            per_set.setdefault(set_dir.name, []).append(
                (psnr(a[0], ref, data_range=1.0), psnr(apply(net, a)[0], ref, data_range=1.0))
            )
    means = [np.mean(np.array(v), axis=0) for v in per_set.values()]
    d = np.concatenate([np.array(v)[:, 1] - np.array(v)[:, 0] for v in per_set.values()])
    print(f"\nreal pairs ({len(d)}), mean over sets: lite {np.mean([m[0] for m in means]):.2f}, "
          f"lite + R {np.mean([m[1] for m in means]):.2f}; paired {paired(list(d), [0.0] * len(d))}")  # fmt: skip


def score_snow(net: nn.Sequential, folder: Path) -> None:
    lite, before, after = create("lite"), [], []
    for snowy_path in list_images(folder / "snowy"):
        snowy, clean = read_rgb(snowy_path), read_rgb(folder / "clean" / snowy_path.name)
        a, b = (np.clip(lite(im[None]).images, 0, 1) for im in (snowy, clean))
        sites = snow_sites(snowy, clean)
        before.append(snow_residue(sites, clean, a[0], b[0]).residue)
        after.append(snow_residue(sites, clean, apply(net, a)[0], apply(net, b)[0]).residue)
    print(f"\nsnow residue ({len(before)} pairs): lite {np.mean(before):.3f}, lite + R {np.mean(after):.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--real-pairs", type=Path)
    ap.add_argument("--snow-pairs", type=Path)
    ap.add_argument("--scenes", type=int, default=500)
    ap.add_argument("--draws", type=int, default=2)
    ap.add_argument("--steps", type=int, default=2000)
    ap.add_argument("--colour-weight", type=float, default=0.0)
    ap.add_argument("--seed", type=int, default=555)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", type=Path)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    x, y = training_images(args.scenes, args.draws, args.seed)
    print(f"training images: {x.shape[0]} at 320x240")
    net = train(x, y, args.steps, args.colour_weight, seed=0)
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        torch.save(net.state_dict(), args.out / "residual.pt")
    for config in (STUDY_WATER, SMALL_WATER):
        score_heldout(net, config)
    if args.real_pairs:
        score_real_pairs(net, args.real_pairs)
    if args.snow_pairs:
        score_snow(net, args.snow_pairs)


if __name__ == "__main__":
    main()
