"""Clean photographs mixed into the procedural training scenes (data.photos, murk.train.photo_source)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
import yaml
from torch.utils.data import DataLoader
from typer.testing import CliRunner

from murk._config import from_dict
from murk.cli.main import app
from murk.io.pairs import DepthOptions, discover
from murk.train.config import DataConfig, TrainConfig
from murk.train.photo_source import INDEX_OFFSET, PhotoDataset, ScenesAndPhotos, photo_repeats, photo_window
from murk.train.scenes_source import SceneDataset
from murk.train.setup import build_data
from tests.train._cli import train_cli


def _photos(folder: Path, count: int = 3, hw: tuple[int, int] = (90, 120)) -> Path:
    folder.mkdir(parents=True)
    g = np.random.default_rng(1)
    for i in range(count):
        cv2.imwrite(str(folder / f"p{i}.png"), (g.random((*hw, 3)) * 255).astype(np.uint8))
    return folder


def test_repeats_reach_the_share() -> None:
    assert photo_repeats(300, 100, 0.5) == 3
    assert photo_repeats(300, 100, 0.25) == 1
    assert photo_repeats(10, 100, 0.5) == 1  # at least once
    with pytest.raises(ValueError, match="photos_share"):
        photo_repeats(10, 10, 1.0)


def test_windows_cover_the_crop_and_differ_between_repeats() -> None:
    sizes = set()
    for r in range(20):
        (w, h), (y0, x0) = photo_window(0, "p", r, (90, 120), (32, 64), (1.0, 2.5))
        assert w >= 64 and h >= 32 and 0 <= y0 <= h - 32 and 0 <= x0 <= w - 64
        sizes.add((w, h))
    assert len(sizes) > 10
    assert photo_window(0, "p", 3, (90, 120), (32, 64), (1.0, 2.5)) == photo_window(
        0, "p", 3, (90, 120), (32, 64), (1.0, 2.5)
    )
    (w, h), _ = photo_window(0, "p", 0, (90, 120), (32, 64), (1.0, 1.0))
    assert (w, h) == (64, 48)  # scale 1: resized by 64 / 120 > 32 / 90, it just covers the crop


def test_photo_windows_are_crop_sized_and_fixed_per_repeat(tmp_path: Path) -> None:
    sources = discover(_photos(tmp_path / "p"), "layout")[0]
    ds = PhotoDataset(sources, (32, 64), DepthOptions(depth_from="layout"), seed=0, repeats=2, scale=(1.0, 2.0))
    assert len(ds) == 6
    a = ds[1]
    again = PhotoDataset(sources, (32, 64), DepthOptions(depth_from="layout"), seed=0, repeats=2, scale=(1.0, 2.0))
    assert a["clean"].shape == (3, 32, 64) and a["depth"].shape == (1, 32, 64) and a["failed"] == ""
    assert a["index"] == INDEX_OFFSET + 1 and torch.all(a["depth_filled"] > 0)
    assert torch.equal(again[1]["clean"], a["clean"]) and torch.equal(again[1]["depth_filled"], a["depth_filled"])
    assert float(a["depth"].abs().sum()) == 0.0  # the layout prior drives the water but is no depth target
    assert not torch.equal(ds[1]["clean"], ds[4]["clean"])  # repeat 1 of the same photograph: another window
    cached = PhotoDataset(
        sources, (32, 64), DepthOptions(depth_from="layout"), seed=0, repeats=2, scale=(1.0, 2.0), cache=True
    )
    first = cached[4]["clean"]
    assert torch.equal(cached[4]["clean"], first) and torch.equal(first, ds[4]["clean"])  # from the cache, the same


def test_an_unreadable_photograph_is_replaced_but_keeps_its_own_index(tmp_path: Path) -> None:
    folder = _photos(tmp_path / "p")
    (folder / "p0.png").write_bytes(b"not a png")
    sources = discover(folder, "layout")[0]
    ds = PhotoDataset(sources, (32, 64), DepthOptions(depth_from="layout"), seed=0)
    sample = ds[0]
    assert "p0.png" in sample["failed"] and sample["index"] == INDEX_OFFSET  # its own water, not p1's
    assert torch.equal(sample["clean"], ds[1]["clean"]) and ds[1]["index"] == INDEX_OFFSET + 1


def test_scenes_and_photos_collate_into_one_batch(tmp_path: Path) -> None:
    sources = discover(_photos(tmp_path / "p"), "layout")[0]
    mixed = ScenesAndPhotos(
        [
            SceneDataset([0, 1], (32, 64), seed=0),
            PhotoDataset(sources, (32, 64), DepthOptions(depth_from="layout"), seed=0, balance_pct=0.5),
        ]
    )
    batch = next(iter(DataLoader(mixed, batch_size=5)))
    assert batch["clean"].shape == (5, 3, 32, 64) and list(batch["failed"]) == [""] * 5
    assert batch["index"].tolist() == [0, 1, INDEX_OFFSET, INDEX_OFFSET + 1, INDEX_OFFSET + 2]
    balanced = batch["clean"][2].reshape(3, -1)
    assert float(balanced.min()) == 0.0 and float(balanced.max()) == 1.0  # the simplest balance stretched it


def test_bad_photo_options_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="photos_share"):
        DataConfig(source="scenes", crop_hw=(32, 64), photos="x", photos_share=0.0)
    with pytest.raises(ValueError, match="photos_scale"):
        DataConfig(source="scenes", crop_hw=(32, 64), photos_scale=(0.5, 1.0))
    with pytest.raises(ValueError, match="depth_from"):
        DataConfig(source="scenes", crop_hw=(32, 64), depth_from="guess")  # type: ignore[arg-type]


def test_murk_train_mixes_photographs_into_scenes(tmp_path: Path) -> None:
    photos = _photos(tmp_path / "photos", count=2)
    config = {
        "model": {"kind": "lite", "variant": "tiny"},
        "data": {
            "source": "scenes",
            "scenes_count": 6,
            "crop_hw": [32, 64],
            "val_fraction": 0.2,
            "workers": 0,
            "photos": str(photos),
            "depth_from": "layout",
            "photos_share": 0.5,
            "synthesis": {"stages": ["basic"]},
        },
        "eval": {"every": 2, "val_batches": 1, "real": None},
        "steps": 2,
        "batch": 4,
        "device": "cpu",
    }
    data = build_data(from_dict(TrainConfig, config))
    assert isinstance(data.train, ScenesAndPhotos) and len(data.train) == 5 + 2 * photo_repeats(5, 2, 0.5)
    without = dict(config, data={k: v for k, v in config["data"].items() if k != "photos"})
    (tmp_path / "t.yaml").write_text(yaml.safe_dump(without))
    r = CliRunner().invoke(
        app,
        ["train", "--config", str(tmp_path / "t.yaml"), "--photos", str(photos), "--out", str(tmp_path / "run"), "-q"],
    )
    assert r.exit_code == 0, r.output
    run = tmp_path / "run"
    summary = json.loads((run / "summary.json").read_text())
    assert summary["failed"] == 0 and (run / "latest.pt").is_file()
    assert yaml.safe_load((run / "config.yaml").read_text())["data"]["photos"] == str(photos)  # --photos was used
    bad = dict(config, data=dict(config["data"], source=str(photos)))
    (tmp_path / "bad").mkdir()
    with pytest.raises(AssertionError, match=r"data\.photos"):
        train_cli(tmp_path / "bad", bad)
