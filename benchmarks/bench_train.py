"""Training throughput of Joint-ID and the cost of online synthesis, measured side by side.

Per configuration: images/s of a full training step (forward, the original loss, backward, AdamW), the time of
the online degradation of the same batch with the torch twins of Eqs. (1)-(8) (three stages, default snow
bank), and its share of the step. With CUDA: the base model at 288x512 (the paper's size), fp32 and bf16,
batch 7 (the original's) and larger, with peak memory; compare with the official trainer's 24.3 img/s
(fp32, batch 7, 45 GiB on an H200). Without CUDA: the tiny and base models on the CPU.

Run: PYTHONPATH=src python benchmarks/bench_train.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np
import torch
from _common import Figure, Recorder, machine

from murk.models.jointid import JointIDConfig, build_jointid, normalize_input, unused_parameter_names
from murk.synth.config import SynthConfig
from murk.train.data import OnlineDegrader
from murk.train.losses import jointid_loss


def sync(device: torch.device) -> None:
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def measure(
    variant: str | JointIDConfig,
    hw: tuple[int, int],
    batch: int,
    precision: str,
    device: torch.device,
    steps: int,
    *,
    wrap: Callable[[torch.nn.Module], torch.nn.Module] | None = None,
    warmup: int = 2,
) -> dict:
    """One configuration: median step and online-synthesis times over ``steps`` steps after ``warmup`` steps.
    ``wrap`` wraps the model for the step (e.g. DistributedDataParallel); the optimiser sees the bare model."""
    torch.manual_seed(0)
    model = build_jointid(variant).to(device)
    for n, p in model.named_parameters():
        if n in set(unused_parameter_names(model)):
            p.requires_grad_(False)
    if device.type == "cuda":
        model = model.to(memory_format=torch.channels_last)
    opt = torch.optim.AdamW(model.parameters(), lr=2e-4, weight_decay=0.01, fused=device.type == "cuda")
    net = wrap(model) if wrap is not None else model
    h, w = hw
    clean = torch.rand(batch, 3, h, w, device=device)
    yy, xx = torch.meshgrid(torch.arange(h, device=device), torch.arange(w, device=device), indexing="ij")
    depth = (1.0 + 0.02 * xx + 0.01 * yy).float()[None, None].repeat(batch, 1, 1, 1)
    degrader = OnlineDegrader(SynthConfig(stages=("basic", "forward_scatter", "marine_snow")), seed=0)
    autocast = torch.autocast(device.type, dtype=torch.bfloat16) if precision == "bf16" else None

    def synth(i: int) -> torch.Tensor:
        with torch.no_grad():
            return degrader(clean, depth, 0, list(range(i * batch, (i + 1) * batch)))

    def step(x: torch.Tensor) -> float:
        inp = normalize_input(x)
        if device.type == "cuda":
            inp = inp.contiguous(memory_format=torch.channels_last)
        if autocast is not None:
            with autocast:
                out = net(inp)
        else:
            out = net(inp)
        loss = jointid_loss(out.enhanced.float(), clean, out.depth_m.float(), depth).total
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        return float(loss.detach())

    x = synth(0)
    for _ in range(warmup):
        step(x)
    if device.type == "cuda":
        torch.cuda.reset_peak_memory_stats(device)
    sync(device)
    t_syn, t_step = [], []
    for i in range(steps):
        t0 = time.perf_counter()
        x = synth(i + 1)
        sync(device)
        t1 = time.perf_counter()
        step(x)
        sync(device)
        t2 = time.perf_counter()
        t_syn.append(t1 - t0)
        t_step.append(t2 - t1)
    syn, st = float(np.median(t_syn)), float(np.median(t_step))
    return {
        "variant": variant if isinstance(variant, str) else "custom",
        "size": f"{h}x{w}",
        "batch": batch,
        "precision": precision,
        "img_s": batch / st,
        "step_ms": st * 1e3,
        "synth_ms": syn * 1e3,
        "synth_share": syn / (syn + st),
        "peak_gib": torch.cuda.max_memory_allocated(device) / 2**30 if device.type == "cuda" else None,
    }


def gpu_figures(
    rec: Recorder,
    device: str | torch.device,
    *,
    variant: str | JointIDConfig = "base",
    hw: tuple[int, int] = (288, 512),
    configs: tuple[tuple[int, str], ...] = ((7, "fp32"), (7, "bf16"), (32, "bf16")),
    steps: int = 20,
    need_s: float = 0.0,
    targets: bool = True,
    warmup: int = 2,
) -> None:
    """Training images/s, peak memory and online-synthesis share per (batch, precision) in ``configs``; the first
    configuration (fp32 batch 7: the official trainer's) is the same-run baseline of the others. A configuration
    is skipped when less than ``need_s`` of the recorder's budget is left."""
    dev = torch.device(device)
    name = variant if isinstance(variant, str) else "custom"
    size = f"{hw[0]}x{hw[1]}"
    base: tuple[str, float] | None = None
    for i, (batch, precision) in enumerate(configs):
        label = f"{name} {size} {precision} batch {batch}"
        r = rec.attempt(
            f"train {label}",
            lambda b=batch, p=precision: measure(variant, hw, b, p, dev, steps, warmup=warmup),
            need_s=need_s,
        )
        if r is None:
            continue
        if i == 0:
            official = name == "base" and batch == 7 and precision == "fp32"
            base = (label + (" (the official trainer's configuration)" if official else ""), r["img_s"])
        target = ">= 100 img/s (official trainer: 24.3 img/s, H200)" if targets and precision == "bf16" else None
        ref_label, ref = (None, None) if base is None or i == 0 else base
        rec.add(
            Figure(
                f"train_{precision}_b{batch}_img_s",
                f"training step, {label}",
                r["img_s"],
                "img/s",
                ref_label,
                ref,
                target,
            )
        )
        share = "<= 10 %" if targets else None
        rec.add(
            Figure(
                f"train_{precision}_b{batch}_synth_pct",
                f"online synthesis share of step+synthesis, {label}",
                100 * r["synth_share"],
                "%",
                target=share,
            )
        )
        if r["peak_gib"] is not None:
            rec.add(Figure(f"train_{precision}_b{batch}_peak_gib", f"peak memory, {label}", r["peak_gib"], "GiB"))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer steps")
    args = ap.parse_args()
    cuda = torch.cuda.is_available()
    device = torch.device("cuda" if cuda else "cpu")
    steps = 3 if args.quick else (20 if cuda else 4)
    print(
        f"# bench_train  {time.strftime('%Y-%m-%d')}  {machine()}  device {device}"
        + (f" ({torch.cuda.get_device_name()})" if cuda else f", {torch.get_num_threads()} threads")
    )
    if cuda:
        gpu_figures(Recorder(echo=True), device, steps=steps)
        return
    configs = [("tiny", (288, 512), 4, "fp32"), ("base", (288, 512), 1, "fp32")]
    for variant, hw, batch, precision in configs:
        r = measure(variant, hw, batch, precision, device, steps)
        mem = f", peak {r['peak_gib']:.1f} GiB" if r["peak_gib"] is not None else ""
        print(
            f"{r['variant']:5s} {r['size']} batch {r['batch']:3d} {r['precision']}: {r['img_s']:8.2f} img/s "
            f"(step {r['step_ms']:.0f} ms; online synthesis {r['synth_ms']:.1f} ms = {100 * r['synth_share']:.1f} % "
            f"of step+synthesis{mem})"
        )
    print("GPU figures: not measured (no CUDA device); the official trainer's reference is 24.3 img/s on an H200")


if __name__ == "__main__":
    main()
