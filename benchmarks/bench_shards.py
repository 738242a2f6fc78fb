"""Tar shards vs loose PNG folders (issue 19): samples/s writing a dataset, and training-loader images/s reading it,
with 1 and 2 worker processes. Baselines measured in the same run: the loose-file writer (``murk synth``) and
the map-style folder loader (``PairDataset`` + the loop's batch sampler).

Small on purpose (a dev box whose 2 cores are shared): the 3 shipped RGB-D pairs x 80 variants = 240 samples at
160x120, shards of 30; the loaders read one epoch with batch 8 and crop 96x160. Rounds alternate between the
variants and the median is printed.

Run: PYTHONPATH=src python benchmarks/bench_shards.py [--variants 80] [--size 160x120] [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine, pin_one_core

pin_one_core()  # one thread per process: the workers are the parallelism measured

from torch.utils.data import DataLoader  # noqa: E402

from murk._config import merge  # noqa: E402
from murk.data import default_snow_bank, sample_rgbd_dir  # noqa: E402
from murk.io import discover  # noqa: E402
from murk.synth.config import SynthConfig  # noqa: E402
from murk.synth.runner import run_synthesis  # noqa: E402
from murk.synth.shards import write_shards  # noqa: E402
from murk.train.config import TrainConfig  # noqa: E402
from murk.train.data import PairDataset, items_from_synth_folder  # noqa: E402
from murk.train.loop import epoch_batches  # noqa: E402
from murk.train.shard_data import build_shard_data  # noqa: E402


def write_rate(kind: str, workers: int, sources, cfg: SynthConfig, tmp: Path, per_shard: int) -> float:
    out = tmp / f"w-{kind}-{workers}"
    shutil.rmtree(out, ignore_errors=True)
    c = merge(cfg, {"workers": workers})
    bank = str(default_snow_bank()) if "marine_snow" in c.stages else None
    t0 = time.perf_counter()
    if kind == "files":
        s = run_synthesis(sources, out, c, bank_path=bank)
        n = s.variants_written
    else:
        n = write_shards(sources, out, c, samples_per_shard=per_shard, bank_path=bank).processed
    return n / (time.perf_counter() - t0)


def read_rate(kind: str, workers: int, folder: Path, batch: int, crop: tuple[int, int]) -> float:
    t0 = time.perf_counter()
    n = 0
    if kind == "files":
        ds = PairDataset(items_from_synth_folder(folder), crop)
        idx = epoch_batches(len(ds), batch, 0, 0, 0, 1)
        for b in DataLoader(ds, batch_sampler=idx, num_workers=workers):
            n += b["input"].shape[0]
    else:
        cfg = merge(
            TrainConfig(),
            {"batch": batch, "data": {"source": str(folder), "workers": workers, "val_fraction": 0.0,
                                      "crop_hw": list(crop)}},
        )  # fmt: skip
        train_set, _ = build_shard_data(cfg, world=1)
        for b in train_set.epoch_loader(0, 0, rank=0):
            n += b["input"].shape[0]
    return n / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--variants", type=int, default=80)
    ap.add_argument("--size", default="160x120")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--samples-per-shard", type=int, default=30)
    ap.add_argument("--stages", default="basic,forward_scatter")
    ap.add_argument("--write-only", action="store_true", help="skip the loader figures")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    sources, _ = discover(sample_rgbd_dir())
    cfg = merge(SynthConfig(), {"variants": args.variants, "input": {"size": [w, h]}, "stages": args.stages.split(",")})
    n = len(sources) * args.variants
    load = os.getloadavg()[0]
    print(f"# bench_shards  {time.strftime('%Y-%m-%d %H:%M')}  {machine()}  load average {load:.2f}")
    print(
        f"# {len(sources)} pairs x {args.variants} variants = {n} samples at {w}x{h}, {args.samples_per_shard}/shard, "
        f"stages {args.stages}"
    )
    tmp = Path(tempfile.mkdtemp(prefix="bench-shards-"))
    try:
        writes: dict[tuple[str, int], list[float]] = {}
        for _ in range(args.rounds):
            for kind in ("files", "shards"):
                for workers in (1, 2):
                    r = write_rate(kind, workers, sources, cfg, tmp, args.samples_per_shard)
                    writes.setdefault((kind, workers), []).append(r)
        wr = {k: statistics.median(v) for k, v in writes.items()}
        # start-up of a 2-process pool (spawn: each worker imports murk, torch, OpenCV): 3 samples in 3 shards
        tiny = merge(cfg, {"variants": 1})
        start_s = {
            kind: statistics.median(n_tiny / write_rate(kind, 2, sources, tiny, tmp, 1) for _ in range(2))
            for kind, n_tiny in (("files", len(sources)), ("shards", len(sources)))
        }
        for workers in (1, 2):
            f, s = wr[("files", workers)], wr[("shards", workers)]
            print(
                f"write  {workers} worker(s): loose PNGs {f:7.1f} samples/s   shards {s:7.1f} samples/s   x{s / f:.2f}"
            )
        print(f"write  2 vs 1 worker: loose x{wr[('files', 2)] / wr[('files', 1)]:.2f}   "
              f"shards x{wr[('shards', 2)] / wr[('shards', 1)]:.2f}")  # fmt: skip
        print(f"write  2-worker pool start-up (a {len(sources)}-sample run): loose {start_s['files']:.1f} s   "
              f"shards {start_s['shards']:.1f} s")  # fmt: skip
        folders = {"files": tmp / "w-files-1", "shards": tmp / "w-shards-1"}
        sizes = {k: sum(p.stat().st_size for p in v.rglob("*") if p.is_file()) for k, v in folders.items()}
        files = {k: sum(1 for p in v.rglob("*") if p.is_file()) for k, v in folders.items()}
        print(f"disk   per sample: shards {sizes['shards'] / n / 1e6:.3f} MB, loose {sizes['files'] / n / 1e6:.3f} MB")
        print(f"disk   loose: {files['files']} files, {sizes['files'] / 1e6:.1f} MB   "
              f"shards: {files['shards']} files, {sizes['shards'] / 1e6:.1f} MB")  # fmt: skip
        if args.write_only:
            return
        crop = ((h // 32) * 32, (w // 32) * 32)
        reads: dict[tuple[str, int], list[float]] = {}
        for _ in range(args.rounds):
            for kind in ("files", "shards"):
                for workers in (1, 2):
                    reads.setdefault((kind, workers), []).append(read_rate(kind, workers, folders[kind], 8, crop))
        rr = {k: statistics.median(v) for k, v in reads.items()}
        for workers in (1, 2):
            f, s = rr[("files", workers)], rr[("shards", workers)]
            print(
                f"load   {workers} worker(s): folders {f:7.1f} images/s   shards {s:7.1f} images/s   x{s / f:.2f}"
                f"   (batch 8, crop {crop[1]}x{crop[0]})"
            )
        print(f"load   2 vs 1 worker: folders x{rr[('files', 2)] / rr[('files', 1)]:.2f}   "
              f"shards x{rr[('shards', 2)] / rr[('shards', 1)]:.2f}")  # fmt: skip
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
