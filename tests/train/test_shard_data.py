"""Streaming training data from tar shards: split over ranks x workers, seeded shuffle, exact resume (issue 19)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from murk._config import merge
from murk.io import discover, read_jsonl
from murk.synth.config import SynthConfig
from murk.synth.shards import write_shards
from murk.train.config import TrainConfig
from murk.train.loop import detect_kind, train
from murk.train.networks import read_network_checkpoint
from murk.train.shard_data import build_shard_data, resolve_shards, shuffle_buffer_order
from tests.train._rgbd import write_rgbd

pytest.importorskip("webdataset", reason="the webdataset package is needed to read tar shards")

TINY = {
    "model": {"kind": "lite", "variant": "tiny"},  # the fastest network: the data path is under test
    "data": {"crop_hw": [32, 64], "workers": 0, "val_fraction": 0.0, "shuffle_buffer": 3},
    "eval": {"every": 1000, "val_batches": 1},
    "batch": 2,
    "log_every": 1,
}


@pytest.fixture(scope="module")
def shard_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """4 clean 48x64 images x 4 variants = 16 samples in 8 shards of 2."""
    root = write_rgbd(tmp_path_factory.mktemp("rgbd"))
    out = tmp_path_factory.mktemp("shards")
    sources, _ = discover(root)
    write_shards(sources, out, SynthConfig(variants=4), samples_per_shard=2)
    return out


def _config(source: str, tmp: Path | None = None, **over: object) -> TrainConfig:
    cfg = merge(TrainConfig(), TINY)
    cfg = merge(cfg, {"data": {"source": source}, "out": str(tmp or "unused")})
    return merge(cfg, dict(over))


def _batches(train_set, epoch: int, rank: int, start: int = 0) -> list[dict]:
    return list(train_set.epoch_loader(epoch, start, rank=rank))


def test_every_sample_once_per_epoch_over_2_ranks_x_2_workers(shard_folder: Path) -> None:
    cfg = _config(str(shard_folder), data={"workers": 2})
    seen_orders = []
    for epoch in (0, 1):
        ids: list[int] = []
        for rank in (0, 1):
            train_set, val = build_shard_data(cfg, world=2)
            assert val is None and len(train_set) == 16
            batches = _batches(train_set, epoch, rank)
            assert len(batches) == 16 // 2 // 2 and all(b["input"].shape == (2, 3, 32, 64) for b in batches)
            ids += [i for b in batches for i in b["index"].tolist()]
        assert sorted(ids) == list(range(16))  # exactly once across 2 ranks x 2 workers
        seen_orders.append(ids)
    assert seen_orders[0] != seen_orders[1]  # reshuffled every epoch (by seed)
    # the same seed gives the same order; another seed another one
    again = [i for r in (0, 1) for b in _batches(build_shard_data(cfg, 2)[0], 0, r) for i in b["index"].tolist()]
    assert again == seen_orders[0]
    other = build_shard_data(merge(cfg, {"seed": 1}), 2)[0]
    assert [i for r in (0, 1) for b in _batches(other, 0, r) for i in b["index"].tolist()] != seen_orders[0]


def test_samples_decode_to_the_written_images(shard_folder: Path) -> None:
    import webdataset as wds

    from murk.train.shard_data import decode_sample

    train_set, _ = build_shard_data(_config(str(shard_folder)), world=1)
    b = _batches(train_set, 0, 0)[0]
    gid = int(b["index"][0])
    raw = list(wds.WebDataset(str(shard_folder / "shards/{000000..000007}.tar"), shardshuffle=False))[gid]
    ref = decode_sample(raw, (32, 64), gid, "ref")
    assert torch.equal(b["input"][0], ref["input"]) and torch.equal(b["depth"][0], ref["depth"])
    d = b["depth"][0]
    assert d.min() > 0.8 and d.max() < 4.6  # metres (the fixture writes 800-4560 mm)


def test_uneven_split_gives_each_sample_at_most_once(shard_folder: Path) -> None:
    cfg = _config(str(shard_folder), batch=3, data={"workers": 0})  # 3 streams x 1 worker x batch 3: 5 per stream
    train_set, _ = build_shard_data(cfg, world=3)
    assert len(train_set) == 3 * 3  # 16 // 3 = 5 -> 3 per stream (a whole batch); the rest waits for a later epoch
    ids = [i for r in range(3) for b in _batches(train_set, 0, r) for i in b["index"].tolist()]
    assert len(ids) == 9 and len(set(ids)) == 9


@pytest.mark.parametrize("workers", [0, 2])
def test_resume_mid_epoch_gives_the_same_batches(shard_folder: Path, workers: int) -> None:
    cfg = _config(str(shard_folder), data={"workers": workers}, batch=1)
    train_set, _ = build_shard_data(cfg, world=2)
    full = _batches(train_set, 3, 1)
    assert len(full) == 8
    for start in (1, 2, 3, 5):
        resumed = _batches(train_set, 3, 1, start)
        assert [b["index"].tolist() for b in resumed] == [b["index"].tolist() for b in full[start:]]
        assert all(torch.equal(a["input"], b["input"]) for a, b in zip(resumed, full[start:], strict=True))


def test_sources_index_pattern_and_bare_tars_agree(shard_folder: Path, tmp_path: Path) -> None:
    by_index = resolve_shards(str(shard_folder))
    by_file = resolve_shards(str(shard_folder / "index.json"))
    by_pattern = resolve_shards(str(shard_folder / "shards/{000000..000007}.tar"))
    bare = tmp_path / "bare"
    shutil.copytree(shard_folder / "shards", bare)  # no index anywhere: keys come from the tar headers
    by_headers = resolve_shards(str(bare / "{000000..000007}.tar"))
    assert by_index.keys == by_file.keys == by_pattern.keys == by_headers.keys
    assert by_index.keys[0] == ("s0_v0", "s0_v1") and len(by_pattern.urls) == 8
    assert detect_kind(str(shard_folder)) == "shards" and detect_kind("x/{000000..000003}.tar") == "shards"
    from murk.errors import InputFileError

    with pytest.raises(InputFileError, match=r"000008\.tar: shard not found"):
        resolve_shards(str(shard_folder / "shards/{000000..000009}.tar"))
    with pytest.raises(ValueError, match="cannot give 4 rank"):
        build_shard_data(_config(str(shard_folder), batch=4, data={"workers": 2}), world=4)
    assert sorted(shuffle_buffer_order(range(50), 8, np.random.default_rng(0))) == list(range(50))
    assert shuffle_buffer_order(range(5), 1, np.random.default_rng(0)) == [0, 1, 2, 3, 4]


def test_train_on_shards_resumes_exactly(shard_folder: Path, tmp_path: Path) -> None:
    source = str(shard_folder / "shards/{000000..000007}.tar")
    full = _config(source, tmp_path / "full", steps=5, data={"val_fraction": 0.25})
    train(full)
    part = _config(source, tmp_path / "part", steps=5, data={"val_fraction": 0.25})
    train(part, stop_after=2)
    train(part, resume=True)
    a = read_network_checkpoint("lite", tmp_path / "full" / "latest.pt")[0]
    b = read_network_checkpoint("lite", tmp_path / "part" / "latest.pt")[0]
    assert all(torch.equal(a[k], b[k]) for k in a)
    la = [r["loss"] for r in read_jsonl(tmp_path / "full" / "log.jsonl") if r["kind"] == "train"]
    lb = [r["loss"] for r in read_jsonl(tmp_path / "part" / "log.jsonl") if r["kind"] == "train"]
    assert la == lb and len(la) == 5  # 12 training samples, batch 2: 6 steps per epoch
    ev = [r for r in read_jsonl(tmp_path / "full" / "log.jsonl") if r["kind"] == "eval"]
    assert ev and np.isfinite(ev[-1]["val_psnr"])  # the held-out stem (4 samples) is read by random access


def test_torchrun_two_gloo_ranks_stream_shards(shard_folder: Path, tmp_path: Path) -> None:
    import json
    import os
    import socket
    import subprocess
    import sys

    from murk._config import dump_yaml

    cfg = _config(str(shard_folder), tmp_path / "ddp", steps=3, data={"workers": 1})
    (tmp_path / "c.yaml").write_text(dump_yaml(cfg))
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nproc_per_node", "2", "--master_port", str(port)]
    cmd += ["-m", "murk", "train", "--config", str(tmp_path / "c.yaml"), "-q"]
    src = str(Path(__file__).resolve().parents[2] / "src")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "PYTHONPATH": os.pathsep.join([src, os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    doc = json.loads((tmp_path / "ddp" / "summary.json").read_text())
    assert doc["steps_done"] == 3 and len(doc["replica_checksums"]) == 2
    assert doc["replica_checksums"][0] == doc["replica_checksums"][1]
