"""Training the detail network (murk.train.detail.fit_detail) on a task with a known answer: blurred images whose
sharp originals are the targets; and ``murk detail train`` end to end, small."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from typer.testing import CliRunner

import murk
from murk.cli.main import app
from murk.models.detail import DetailNet, load_detail
from murk.models.detail.network import RADIUS_PX
from murk.train.config import TrainConfig
from murk.train.detail import DetailSamples, DetailTrainSettings, detail_loss, fit_detail
from murk.train.losses import local_mse
from murk.workflows.detail_train import sample_parts

CONFIG = Path(__file__).parents[2] / "configs" / "train-small-cpu.yaml"


def _samples(n: int = 40, seed: int = 0) -> DetailSamples:
    """Sharp random blocks (the truth) and a 'restoration' that kept half of their detail beyond a Gaussian blur, with
    a colour shift."""
    rng = np.random.default_rng(seed)
    clean = np.stack([cv2.resize(rng.uniform(0, 1, (8, 8, 3)).astype(np.float32), (40, 40),
                                 interpolation=cv2.INTER_NEAREST) for _ in range(n)])  # fmt: skip
    blurred = np.stack([cv2.GaussianBlur(c, (0, 0), 1.0) for c in clean])
    return DetailSamples(((blurred + 0.5 * (clean - blurred)) * 0.8 + 0.1).astype(np.float32), clean)


def test_fit_detail_learns_what_no_colour_map_can_and_is_seeded() -> None:
    samples = _samples()
    rows: list[dict[str, float]] = []
    settings = DetailTrainSettings(steps=300, batch=8, crop_px=32, channels=8, lr=3e-3, log_every=60, seed=1)
    net = fit_detail(samples, settings, rows.append)
    assert rows[-1]["val_loss"] < 0.8 * rows[0]["val_loss"], rows
    torch.manual_seed(123)
    state = torch.random.get_rng_state()
    again = fit_detail(samples, settings)
    assert torch.equal(torch.random.get_rng_state(), state)  # the caller's generator is left alone
    for a, b in zip(net.parameters(), again.parameters(), strict=True):
        torch.testing.assert_close(a, b, rtol=0, atol=0)
    # the colour term keeps the residual's mean per image and channel near zero: the restoration's colour stays
    x = torch.from_numpy(samples.restored).permute(0, 3, 1, 2)
    with torch.no_grad():
        means = net(x).mean(dim=(2, 3)).abs()
    assert float(means.max()) < 0.02


def test_frame_crops_see_what_inference_sees_and_own_crops_do_not() -> None:
    samples = _samples(20)
    net = DetailNet(4)
    torch.nn.init.normal_(net.convs[-1].weight, std=0.05)
    x = torch.from_numpy(samples.restored[:1]).permute(0, 3, 1, 2)
    y = torch.from_numpy(samples.clean[:1]).permute(0, 3, 1, 2)
    r = RADIUS_PX
    padded = torch.nn.functional.pad(x, (r,) * 4, mode="replicate")
    with torch.no_grad():
        whole = (x + net(x))[..., 5:21, 7:23]  # what inference gives inside the frame
        framed = detail_loss(net, padded[..., 5 : 21 + 2 * r, 7 : 23 + 2 * r], y[..., 5:21, 7:23], 0.0, margin=True)
        own = detail_loss(net, x[..., 5:21, 7:23], y[..., 5:21, 7:23], 0.0)
    assert float(framed) == pytest.approx(float(local_mse(whole, y[..., 5:21, 7:23])), rel=1e-5)
    assert abs(float(own) - float(framed)) > 1e-6 * float(framed)
    settings = DetailTrainSettings(steps=40, batch=4, crop_px=16, channels=4, log_every=40, seed=2)
    a, b = fit_detail(samples, settings), fit_detail(samples, replace(settings, crops="own"))
    assert any(not torch.equal(p, q) for p, q in zip(a.parameters(), b.parameters(), strict=True))


def test_the_colour_term_is_what_keeps_the_colour() -> None:
    net = DetailNet(4)
    torch.nn.init.constant_(net.convs[-1].bias, 0.1)  # a residual that shifts every channel by 0.1
    x = torch.rand(2, 3, 32, 32)
    with torch.no_grad():
        with_term, without = detail_loss(net, x, x, 10.0), detail_loss(net, x, x, 0.0)
    assert float(without) < 1e-8  # a global shift is forgiven by the affine fit ...
    assert float(with_term) == pytest.approx(10 * 0.1**2, rel=1e-4)  # ... but not by the colour term


def test_settings_and_samples_are_checked() -> None:
    with pytest.raises(ValueError, match="crop_px"):
        DetailTrainSettings(crop_px=8)
    with pytest.raises(ValueError, match="colour_weight"):
        DetailTrainSettings(colour_weight=-1.0)
    with pytest.raises(ValueError, match="channels"):
        DetailTrainSettings(channels=0)
    with pytest.raises(ValueError, match="crops: expected one of frame, own"):
        DetailTrainSettings(crops="edge")
    s = _samples(12)
    with pytest.raises(ValueError, match="samples"):
        DetailSamples(s.restored, s.clean[:, :20])
    with pytest.raises(ValueError, match="smaller than crop_px"):
        fit_detail(s, DetailTrainSettings(crop_px=64))


def test_murk_detail_train_writes_a_network_and_never_overwrites_it(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["detail", "train", "--config", str(CONFIG), "--out", str(out), "--scenes", "10", "--steps", "2",
            "--channels", "4"]  # fmt: skip
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    net, meta = load_detail(out / "detail.npz")
    assert net.channels == 4 and meta["scenes"] == 10 and meta["base"] == "lite" and meta["settings"]["steps"] == 2
    # the samples' key and the meta name the base's weights by content, and murk's version
    assert meta["murk"] == murk.__version__ and [name for name, _ in meta["base_weights"]] == ["lite.pt"]
    assert all(len(h) == 16 for _, h in meta["base_weights"])
    assert (out / "log.jsonl").read_text().count("val_loss") == 1
    before = (out / "detail.npz").read_bytes()
    again = CliRunner().invoke(app, args)
    assert again.exit_code == 2 and "never overwritten" in again.output
    assert (out / "detail.npz").read_bytes() == before
    (out / "detail.npz").unlink()  # the cached samples are read back: the same network again
    assert CliRunner().invoke(app, args).exit_code == 0
    assert (out / "detail.npz").read_bytes() == before


def test_murk_detail_train_takes_the_stages_of_every_config_and_refuses_unknown_ones(tmp_path: Path) -> None:
    args = ["detail", "train", "--config", str(CONFIG), "--scenes", "10", "--steps", "1", "--channels", "4"]
    bad = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "bad"), "--stages", "basic,fog"])
    assert bad.exit_code == 2 and "unknown stage(s) 'fog'" in bad.output
    assert not (tmp_path / "bad" / "detail.npz").exists()
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "basic"), "--stages", "basic"])
    assert res.exit_code == 0, res.output
    with np.load(tmp_path / "basic" / "samples.npz") as z:
        assert "stages=('basic',)" in str(z["key"])
    _, meta = load_detail(tmp_path / "basic" / "detail.npz")
    assert meta["configs"] == [str(CONFIG)] and meta["stages"] == [["basic"]]


def test_eq1_share_takes_scatter_and_snow_out_of_that_share_of_each_config() -> None:
    from murk._config import load_yaml, merge

    water = load_yaml(TrainConfig, CONFIG).data.synthesis
    assert [(s.stages, n) for s, n in sample_parts([water, water], 11, 0.0)] == [(water.stages, 6), (water.stages, 5)]
    parts = sample_parts([water, water], 11, 0.5)
    assert [n for _, n in parts] == [3, 3, 2, 3] and sum(n for _, n in parts) == 11  # halves rounded up
    assert water.stages == ("basic", "forward_scatter", "marine_snow")
    assert [s.stages for s, _ in parts] == [water.stages, ("basic",), water.stages, ("basic",)]
    assert parts[1][0].medium == water.medium  # the same water, without its blur and snow
    assert [(s.stages, n) for s, n in sample_parts([water], 10, 1.0)] == [(("basic",), 10)]
    with pytest.raises(ValueError, match="eq1_share: expected a share in"):
        sample_parts([water], 10, 1.5)
    scatter_only = merge(water, {"stages": ["forward_scatter"]}, where="stages")
    assert [n for _, n in sample_parts([scatter_only], 10, 0.0)] == [10]  # no Eq. (1) part asked: none made
    with pytest.raises(ValueError, match="eq1_share: the stages forward_scatter keep none"):
        sample_parts([scatter_only], 10, 0.5)


def test_murk_detail_train_eq1_share_and_crops_are_recorded(tmp_path: Path) -> None:
    args = ["detail", "train", "--config", str(CONFIG), "--scenes", "10", "--steps", "1", "--channels", "4",
            "--eq1-share", "0.3", "--crops", "own"]  # fmt: skip
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "mix")])
    assert res.exit_code == 0, res.output
    _, meta = load_detail(tmp_path / "mix" / "detail.npz")
    assert meta["eq1_share"] == 0.3 and meta["settings"]["crops"] == "own"
    assert meta["parts"] == [{"stages": ["basic", "forward_scatter", "marine_snow"], "scenes": 7},
                             {"stages": ["basic"], "scenes": 3}]  # fmt: skip
    bad = CliRunner().invoke(app, [*args[:-4], "--out", str(tmp_path / "bad"), "--eq1-share", "2"])
    assert bad.exit_code == 2 and "eq1_share" in bad.output
    crops = CliRunner().invoke(app, [*args[:-2], "--out", str(tmp_path / "bad"), "--crops", "edge"])
    assert crops.exit_code == 2 and "crops: expected one of frame, own" in crops.output


def test_samples_made_by_other_base_weights_are_made_again(tmp_path: Path) -> None:
    from murk.data import shipped_lite_weights
    from murk.enhance.choices import DEFAULT_DEPTH_AREA_PX
    from murk.enhance.restorer import create
    from murk.workflows.small_train import base_fingerprint

    shipped = base_fingerprint(create("lite"))
    copy = tmp_path / "elsewhere" / "lite.pt"
    copy.parent.mkdir()
    copy.write_bytes(shipped_lite_weights().read_bytes())
    assert base_fingerprint(create(f"lite?checkpoint={copy}")) == shipped  # by name and content, not by folder ...
    copy.write_bytes(copy.read_bytes() + b"\0")  # ... so a changed file is another key
    assert base_fingerprint(create(f"lite?checkpoint={copy}")) != shipped
    assert base_fingerprint(create("colorbalance"))["base_weights"] == []
    # a method built on a base restorer (water on Joint-ID, which blends lite in): every file, once
    names = [name for name, _ in base_fingerprint(create("water+detail"))["base_weights"]]
    assert names == ["water.npz", "jointid-small.pt", "lite.pt", "detail.npz"]
    # the exposure step changed what the same files give (2026-12-06): samples made without it are made again
    assert base_fingerprint(create("lite"))["exposure"] == [True]
    assert base_fingerprint(create("lite?exposure=network"))["exposure"] == [False]
    assert base_fingerprint(create("water?exposure=network"))["exposure"] == [False, False]  # Joint-ID and its lite
    assert base_fingerprint(create("water"))["depth_area"] == [DEFAULT_DEPTH_AREA_PX]  # Joint-ID's depth pass
    assert base_fingerprint(create("water?depth_area=0"))["depth_area"] == [0]
    assert base_fingerprint(create("lite"))["depth_area"] == []


def test_murk_detail_train_learns_from_photographs_in_every_parts_water(tmp_path: Path) -> None:
    from murk.io import write_rgb

    photos = tmp_path / "photos"
    photos.mkdir()
    rng = np.random.default_rng(0)
    for name in ("a.png", "b.jpg"):
        write_rgb(photos / name, rng.uniform(0, 1, (90, 120, 3)).astype(np.float32))
    args = ["detail", "train", "--config", str(CONFIG), "--scenes", "10", "--steps", "1", "--channels", "4",
            "--eq1-share", "0.5"]  # fmt: skip
    res = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "run"), "--photos", str(photos)])
    assert res.exit_code == 0, res.output
    assert "samples: 4 from 2 photographs" in res.output  # 2 photographs x 2 waters (snowy, Eq. (1) only)
    assert "(14 samples," in res.output  # and the 10 scenes
    _, meta = load_detail(tmp_path / "run" / "detail.npz")
    assert meta["photos"]["folder"] == str(photos) and [f for f, _ in meta["photos"]["files"]] == ["a.png", "b.jpg"]
    with np.load(tmp_path / "run" / "samples.npz") as z:
        assert z["restored"].shape == (14, 240, 320, 3) and "b.jpg" in str(z["key"])
    (photos / "c.jpg").write_text("not an image")
    bad = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "bad"), "--photos", str(photos)])
    assert bad.exit_code == 2 and "c.jpg" in bad.output, bad.output
    gone = CliRunner().invoke(app, [*args, "--out", str(tmp_path / "gone"), "--photos", str(tmp_path / "none")])
    assert gone.exit_code != 0 and "none" in gone.output, gone.output
    assert not (tmp_path / "bad" / "detail.npz").exists() and not (tmp_path / "gone" / "detail.npz").exists()


def test_murk_detail_train_specks_are_painted_on_the_scenes_and_key_the_samples(tmp_path: Path) -> None:
    args = ["detail", "train", "--config", str(CONFIG), "--scenes", "10", "--steps", "1", "--channels", "4",
            "--out", str(tmp_path / "run")]  # fmt: skip
    assert CliRunner().invoke(app, args).exit_code == 0
    with np.load(tmp_path / "run" / "samples.npz") as z:
        plain_clean, plain_key = z["clean"], str(z["key"])
    (tmp_path / "run" / "detail.npz").unlink()
    res = CliRunner().invoke(app, [*args, "--specks", "3000"])
    assert res.exit_code == 0, res.output
    _, meta = load_detail(tmp_path / "run" / "detail.npz")
    assert meta["specks_per_mpx"] == 3000.0
    with np.load(tmp_path / "run" / "samples.npz") as z:  # the old samples are not taken for these
        assert "specks_per_mpx" in str(z["key"]) and "specks_per_mpx" not in plain_key
        assert not np.array_equal(z["clean"], plain_clean) and z["clean"].shape == plain_clean.shape
    bad = CliRunner().invoke(app, [*args[:-1], str(tmp_path / "bad"), "--specks", "-1"])
    assert bad.exit_code == 2 and "specks" in bad.output
