"""Marine-snow compositing speed, Eqs. (7)-(8): ms per 640x480 image with 1600 particles, one core.

Two baselines written inside this script, both Python loops over the particles:

- ``loop-composite``: the literal reading of Eqs. (7)-(8) per particle: resize the particle's mask and
  colour with cv2.resize, blur the mask with rho, alpha-blend it into the image region;
- ``loop-paste``: a leaner loop: resize and paste every particle into one mask B and colour layer M, then
  blur B once and blend once.

murk: the vectorised splatting of :mod:`murk.snow.composite`. With CUDA present, also images/s of the
batched torch twin.

Run: PYTHONPATH=src python benchmarks/bench_snow.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import Figure, Recorder, cycler, device_sync, interleaved, machine, median_s, pin_one_core

pin_one_core()

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from murk.data import default_snow_bank  # noqa: E402
from murk.snow.bank import ParticleBank, load_bank  # noqa: E402
from murk.snow.composite import composite_snow, composite_snow_torch, sample_snow, snow_layout  # noqa: E402

H, W, N = 480, 640, 1600


def patches(bank: ParticleBank) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each particle as a (mask float32 (h, w), colour float32 (h, w, 3)) patch, as a loop implementation keeps them."""
    out = []
    for i in range(len(bank)):
        yx = bank.pixel_yx[bank.offsets[i] : bank.offsets[i + 1]]
        rgb = bank.pixel_rgb[bank.offsets[i] : bank.offsets[i + 1]]
        rows = np.rint(yx[:, 0] - yx[:, 0].min()).astype(int)
        cols = np.rint(yx[:, 1] - yx[:, 1].min()).astype(int)
        m = np.zeros((rows.max() + 1, cols.max() + 1), np.float32)
        c = np.zeros((*m.shape, 3), np.float32)
        m[rows, cols] = 1.0
        c[rows, cols] = rgb / 255.0
        out.append((m, c))
    return out


def baseline(image: np.ndarray, params, bank: ParticleBank, pats) -> np.ndarray:
    layout = snow_layout(params, len(bank), W, H)
    b = np.zeros((H, W), np.float32)
    m = np.zeros((H, W, 3), np.float32)
    for idx, s, (cx, cy) in zip(layout.index, layout.scale, layout.centre_xy, strict=True):
        pm, pc = pats[idx]
        h, w = max(1, round(pm.shape[0] * s)), max(1, round(pm.shape[1] * s))
        rm = cv2.resize(pm, (w, h), interpolation=cv2.INTER_AREA)
        rc = cv2.resize(pc, (w, h), interpolation=cv2.INTER_AREA)
        y0, x0 = round(cy - h / 2), round(cx - w / 2)
        ys, xs = max(0, y0), max(0, x0)
        ye, xe = min(H, y0 + h), min(W, x0 + w)
        if ye <= ys or xe <= xs:
            continue
        sub = rm[ys - y0 : ye - y0, xs - x0 : xe - x0]
        b[ys:ye, xs:xe] = np.maximum(b[ys:ye, xs:xe], sub)
        m[ys:ye, xs:xe][sub > 0] = rc[ys - y0 : ye - y0, xs - x0 : xe - x0][sub > 0]
    alpha = cv2.GaussianBlur(b, (0, 0), params.rho_px)
    return (1.0 - alpha[:, :, None]) * image + alpha[:, :, None] * m


def baseline_composite(image: np.ndarray, params, bank: ParticleBank, pats) -> np.ndarray:
    layout = snow_layout(params, len(bank), W, H)
    out = image.copy()
    r = max(1, int(np.ceil(4 * params.rho_px)))
    for idx, s, (cx, cy) in zip(layout.index, layout.scale, layout.centre_xy, strict=True):
        pm, pc = pats[idx]
        h, w = max(1, round(pm.shape[0] * s)), max(1, round(pm.shape[1] * s))
        rm = cv2.copyMakeBorder(cv2.resize(pm, (w, h), interpolation=cv2.INTER_AREA), r, r, r, r, cv2.BORDER_CONSTANT)
        rc = cv2.copyMakeBorder(cv2.resize(pc, (w, h), interpolation=cv2.INTER_AREA), r, r, r, r, cv2.BORDER_REPLICATE)
        a = cv2.GaussianBlur(rm, (2 * r + 1, 2 * r + 1), params.rho_px)[:, :, None]  # Eq. (8) for this particle
        y0, x0 = round(cy - h / 2) - r, round(cx - w / 2) - r
        ys, xs = max(0, y0), max(0, x0)
        ye, xe = min(H, y0 + h + 2 * r), min(W, x0 + w + 2 * r)
        if ye <= ys or xe <= xs:
            continue
        a = a[ys - y0 : ye - y0, xs - x0 : xe - x0]
        m = rc[ys - y0 : ye - y0, xs - x0 : xe - x0]
        out[ys:ye, xs:xe] = (1.0 - a) * out[ys:ye, xs:xe] + a * m  # Eq. (7) for this particle
    return out


def larger_particle_bank() -> ParticleBank:
    """A bank with larger particles (median area ~10 px, up to ~240 px), cut from a shipped reef frame with the
    top-hat method: stands for banks cut from high-resolution footage."""
    from murk.data import sample_underwater_dir
    from murk.io import read_image
    from murk.snow.bank import extract_bank
    from murk.snow.extract import ExtractConfig

    rgb, _ = read_image(sample_underwater_dir() / "suim" / "n_l_52_.jpg")
    return extract_bank([({"path": "n_l_52_.jpg"}, rgb)], ExtractConfig(method="tophat")).bank


def main() -> None:
    g = np.random.default_rng(0)
    image = g.random((H, W, 3)).astype(np.float32)
    print(f"# bench_snow  {time.strftime('%Y-%m-%d')}  {machine()}  {W}x{H}, {N} particles, 1 thread")
    for label, bank in (
        ("shipped default bank (builtin:snow)", load_bank(default_snow_bank())),
        ("the default before 2026-12-03 (builtin:snow-small)", load_bank("builtin:snow-small")),
        ("larger particles", larger_particle_bank()),
    ):
        areas = bank.areas_px
        print(f"## {label}: {len(bank)} particles, area median {np.median(areas):.0f} px, max {areas.max()} px")
        run(image, bank)
    gpu(image, load_bank(default_snow_bank()))


def run(image: np.ndarray, bank: ParticleBank) -> None:
    pats = patches(bank)
    params = [sample_snow(s, bank, n_particles=(N, N)) for s in range(8)]
    nxt = cycler(params)

    ms = interleaved(
        {
            "loop-composite": lambda: baseline_composite(image, nxt(), bank, pats),
            "loop-paste": lambda: baseline(image, nxt(), bank, pats),
            "murk": lambda: composite_snow(image, nxt(), bank),
        },
        rounds=9,
        inner=3,
    )
    print(f"murk (vectorised)          {ms['murk']:7.2f} ms/image")
    for k in ("loop-composite", "loop-paste"):
        print(f"baseline {k:17s} {ms[k]:7.2f} ms/image   murk speed-up x{ms[k] / ms['murk']:.1f}")


def gpu_figures(
    rec: Recorder,
    device: str | torch.device,
    image: np.ndarray,
    bank: ParticleBank,
    *,
    n_particles: int = N,
    batches: tuple[int, ...] = (64, 256),
    repeats: int = 5,
) -> None:
    """Images/s of ``composite_snow_torch`` on ``device`` (``n_particles`` per image), against murk's numpy
    ``composite_snow`` on one core in the same run (the caller pins one core)."""
    dev = torch.device(device)
    sync = device_sync(dev)
    h, w = image.shape[:2]
    params = [sample_snow(s, bank, n_particles=(n_particles, n_particles)) for s in range(max(batches))]
    nxt = cycler(params[:8])
    cpu_s = median_s(lambda: composite_snow(image, nxt(), bank), repeats=max(8, repeats), warmup=2)
    base = f"murk numpy composite_snow, 1 core, {w}x{h}, {n_particles} particles"
    rec.add(Figure("cpu_img_s", base, 1 / cpu_s, "img/s"))
    for bsz in batches:
        x = torch.from_numpy(image).permute(2, 0, 1)[None].repeat(bsz, 1, 1, 1).to(dev)
        ps = params[:bsz]
        t = rec.attempt(
            f"composite_snow_torch batch {bsz}",
            lambda x=x, ps=ps: median_s(
                lambda: composite_snow_torch(x, ps, bank), repeats=repeats, warmup=1, sync=sync
            ),
        )
        if t is not None:
            label = f"composite_snow_torch {dev.type}, {w}x{h}, {n_particles} particles, batch {bsz}"
            rec.add(Figure(f"torch_b{bsz}_img_s", label, bsz / t, "img/s", base, 1 / cpu_s))


def gpu(image: np.ndarray, bank: ParticleBank) -> None:
    if torch.cuda.is_available():
        gpu_figures(Recorder(echo=True), "cuda", image, bank)
    else:
        print("torch GPU path: not measured (no CUDA device)")


if __name__ == "__main__":
    main()
