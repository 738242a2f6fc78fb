"""Benchmark of the scene renderer: scenes per second on one CPU core, against a naive baseline.

Run:  PYTHONPATH=src python benchmarks/bench_scenes.py [--count 24] [--size 640x480]

Both renderers use the same analytic kernels and shading formula and give the same image (the script checks
it); they differ in how the work is organised:

- baseline (written here): every primitive is intersected with every pixel, its surface attributes are
  computed for every pixel, and the whole frame is shaded with per-pixel material coefficients;
- murk: each primitive is intersected only inside the screen rectangles of its bounding spheres, the seabed
  runs on row bands, and surfaces/shading run on pixels compacted by (material, primitive kind).

Everything runs on one thread (OMP/MKL/OpenBLAS = 1, cv2.setNumThreads(1), torch.set_num_threads(1)).
With a CUDA GPU, the batched torch renderer is timed as well.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cv2  # noqa: E402
import numpy as np  # noqa: E402
from _common import Figure, Recorder, device_sync, median_s  # noqa: E402

from murk.rng import derive_seed  # noqa: E402
from murk.scenes import geometry as geo  # noqa: E402
from murk.scenes import render_scenes_torch, sample_scene  # noqa: E402
from murk.scenes.render import (  # noqa: E402
    T_CAP_FACTOR,
    _rays_numpy,
    _surface_kernel,
    _t_kernel,
    pack_scene,
    render_packed_numpy,
)
from murk.scenes.shading import MATERIAL_FIELDS, shade  # noqa: E402
from murk.scenes.textures import lookup_numpy, noise_tile  # noqa: E402


def naive_render(packed) -> tuple[np.ndarray, np.ndarray]:
    """Baseline: per-primitive loops over the full frame, full-frame surfaces and shading."""
    frame = packed.frame
    d, cos_axis = _rays_numpy(frame)
    t_cap = T_CAP_FACTOR * packed.far_m
    sb = packed.seabed.tolist()
    t_buf = geo.seabed_t(np, d, sb, t_cap)
    id_buf = np.where(np.isfinite(t_buf), 0, -1)
    for gid, (kind, row) in enumerate(packed.prims, start=1):
        t = _t_kernel(kind, np, d, row.tolist(), frame.px_angle)
        closer = t < t_buf
        t_buf = np.where(closer, t, t_buf)
        id_buf = np.where(closer, gid, id_buf)
    t_fin = np.minimum(t_buf, np.float32(t_cap))
    cam_xy = (float(frame.position[0]), float(frame.position[1]))
    attrs = list(geo.seabed_surface(np, d, t_fin, sb, cam_xy))
    for gid, (kind, row) in enumerate(packed.prims, start=1):
        vals = _surface_kernel(kind, np, d, t_fin, row.tolist())
        mine = id_buf == gid
        attrs = [np.where(mine, v, a) for v, a in zip(vals, attrs, strict=True)]
    mat_id = packed.material_of_id[np.maximum(id_buf, 0)]
    table = packed.materials.astype(np.float32)
    mat = [table[:, j][mat_id] for j in range(MATERIAL_FIELDS)]
    tile = noise_tile()
    light = packed.light.tolist()
    rgb = shade(
        np, t_buf, d, tuple(attrs[:3]), tuple(attrs[3:]), cos_axis, mat, light, lambda x, y: lookup_numpy(tile, x, y)
    )
    return np.stack(rgb, axis=-1), np.clip(t_buf, packed.near_m, packed.far_m)


def gpu_figures(
    rec: Recorder,
    device: object,
    *,
    count: int = 16,
    size: tuple[int, int] = (640, 480),
    batches: tuple[int, ...] = (16, 64),
    reps: int = 5,
    seed: int = 0,
) -> None:
    """Scenes/s of ``render_scenes_torch`` on ``device`` at ``size`` (width, height), against murk's numpy
    renderer on one core in the same run (the first ``count`` scenes of ``seed``; the caller pins one core)."""
    import torch

    dev = torch.device(device)  # type: ignore[arg-type]
    sync = device_sync(dev)
    w, h = size
    noise_tile()
    scenes = [sample_scene(derive_seed(seed, i)) for i in range(count)]
    render_packed_numpy(pack_scene(scenes[0], size))  # warm-up
    cpu = statistics.median(
        median_s(lambda p=p: render_packed_numpy(pack_scene(p, size)), repeats=1, warmup=0) for p in scenes
    )
    base = f"murk numpy render_scene, 1 core, {w}x{h}"
    rec.add(Figure("cpu_scenes_s", base, 1 / cpu, "scenes/s"))
    for batch in batches:
        chunk = (scenes * ((batch + len(scenes) - 1) // len(scenes)))[:batch]
        t = rec.attempt(
            f"render_scenes_torch batch {batch}",
            lambda chunk=chunk: median_s(
                lambda: render_scenes_torch(chunk, size, dev), repeats=reps, warmup=1, sync=sync
            ),
        )
        if t is not None:
            label = f"render_scenes_torch {dev.type}, {w}x{h}, batch {batch}"
            rec.add(Figure(f"torch_b{batch}_scenes_s", label, batch / t, "scenes/s", base, 1 / cpu))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=24)
    ap.add_argument("--size", default="640x480")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    cv2.setNumThreads(1)
    try:
        import torch

        torch.set_num_threads(1)
    except ImportError:  # pragma: no cover
        torch = None

    noise_tile()  # built once per process; not part of a scene's cost
    t0 = time.perf_counter()
    scenes = [sample_scene(derive_seed(args.seed, i)) for i in range(args.count)]
    sample_ms = (time.perf_counter() - t0) / args.count * 1e3
    prims = [len(p.primitives()) for p in scenes]
    print(f"machine: {platform.machine()} {platform.processor() or ''} | load average {os.getloadavg()}")
    print(f"{args.count} scenes at {w}x{h}, primitives per scene: median {int(np.median(prims))}, max {max(prims)}")
    print(f"sampling: {sample_ms:.2f} ms/scene")

    fast, slow, diff_rgb, diff_d = [], [], [], []
    render_packed_numpy(pack_scene(scenes[0], (w, h)))  # warm-up
    naive_render(pack_scene(scenes[0], (w, h)))
    for p in scenes:  # interleaved, so that machine noise hits both alike
        a = time.perf_counter()
        packed = pack_scene(p, (w, h))
        rgb, dist = render_packed_numpy(packed)
        b = time.perf_counter()
        rgb0, dist0 = naive_render(pack_scene(p, (w, h)))
        c = time.perf_counter()
        fast.append(b - a)
        slow.append(c - b)
        diff_rgb.append(float(np.abs(rgb - rgb0).max()))
        diff_d.append(float(np.abs(dist - dist0).max()))
    med_fast, med_slow = statistics.median(fast), statistics.median(slow)
    print(f"same output: max |rgb diff| {max(diff_rgb):.2e}, max |dist diff| {max(diff_d):.2e} m")
    print(f"baseline (naive, full frame): median {med_slow * 1e3:.1f} ms/scene, mean {statistics.mean(slow) * 1e3:.1f}")
    print(
        f"murk numpy (culled, compacted): median {med_fast * 1e3:.1f} ms/scene, mean {statistics.mean(fast) * 1e3:.1f},"
        f" max {max(fast) * 1e3:.1f} -> {1.0 / med_fast:.1f} scenes/s on one core"
    )
    print(f"speed-up vs baseline: {med_slow / med_fast:.2f}x (median), {sum(slow) / sum(fast):.2f}x (total)")

    if torch is not None and torch.cuda.is_available():
        print(f"torch CUDA ({torch.cuda.get_device_name()}):")
        gpu_figures(Recorder(echo=True), "cuda", count=args.count, size=(w, h), seed=args.seed)
    else:
        print("torch CUDA: not measured (no GPU on this machine)")


if __name__ == "__main__":
    main()
