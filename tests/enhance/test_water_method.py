"""The ``water`` method (Eq. (1) inverted with the estimated water and Joint-ID's distance, in the base's colour)
and ``murk water estimate``, with a small estimator made here (the shipped one is tested in
tests/models/test_water_estimator.py)."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from torch import nn
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_underwater_images
from murk.enhance.restorer import create, weights_used
from murk.io import read_rgb, write_rgb
from murk.metrics import affine_fit
from murk.models.water import WaterEstimator, load_water_estimator
from murk.restore_ops.water import FEATURES, invert_eq1
from murk.train.water import water_network


@pytest.fixture(scope="module")
def estimator_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    torch.manual_seed(0)
    layers = [m for m in water_network() if isinstance(m, nn.Linear)]
    arrays = {"mu": np.zeros(FEATURES), "sd": np.ones(FEATURES)}
    for k, layer in enumerate(layers, 1):
        arrays[f"w{k}"] = layer.weight.detach().numpy().T.astype(np.float64)
        arrays[f"b{k}"] = layer.bias.detach().numpy().astype(np.float64)
    arrays["b3"][3:] = -1.0  # attenuation about exp(-1) = 0.37 /m: a visible inversion
    path = tmp_path_factory.mktemp("water") / "water.npz"
    WaterEstimator(arrays, meta={"test": True}).save(path)
    return path


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    img = read_rgb(sample_underwater_images()[0])
    return cv2.resize(img, (96, 72), interpolation=cv2.INTER_AREA)


def test_water_inverts_eq1_in_the_base_colour(estimator_file: Path, image: np.ndarray) -> None:
    base = create("jointid").restore(image[None])
    est = load_water_estimator(estimator_file)
    for strength in (0.0, 0.25, 1.0):
        out = create("water", estimator=str(estimator_file), strength=strength).restore(image[None])
        water = est.estimate(image, base.depth_m[0])
        inverted = invert_eq1(image, base.depth_m[0], np.asarray(water.veil), np.asarray(water.attenuation_per_m))
        mixed = image + np.float32(strength) * (inverted - image)
        expect = np.clip(affine_fit(mixed, np.clip(base.images[0], 0, 1)), 0, 1)
        np.testing.assert_allclose(out.images[0], expect, atol=1e-6)
        np.testing.assert_array_equal(out.depth_m, base.depth_m)
    zero = create("water", estimator=str(estimator_file), strength=0.0).restore(image[None]).images[0]
    np.testing.assert_allclose(zero, np.clip(affine_fit(image, np.clip(base.images[0], 0, 1)), 0, 1), atol=1e-6)
    assert (
        np.abs(zero - create("water", estimator=str(estimator_file), strength=1.0).restore(image[None]).images[0]).max()
        > 0.02
    )


def test_water_keeps_the_estimate_and_refuses_a_base_without_depth(estimator_file: Path, image: np.ndarray) -> None:
    r = create("water", estimator=str(estimator_file))
    r.restore(np.stack([image, image[::-1]]))
    assert len(r.last_water) == 2 and r.last_water[0].visibility_m > 0
    with pytest.raises(ValueError, match="no distance map"):
        create("water", estimator=str(estimator_file), base="lite").restore(image[None])


def test_water_passes_depth_area_to_its_base(estimator_file: Path) -> None:
    from murk.enhance.choices import DEFAULT_DEPTH_AREA_PX

    def net(r):  # the jointid_net inside water's base (jointid: jointid_net|lite@0.5)
        return r.base.left if hasattr(r.base, "left") else r.base

    assert net(create("water", estimator=str(estimator_file))).depth_area == DEFAULT_DEPTH_AREA_PX
    assert net(create("water", estimator=str(estimator_file), depth_area=0)).depth_area == 0
    assert net(create("water", estimator=str(estimator_file), base="jointid_net", depth_area=4096)).depth_area == 4096


def test_murk_enhance_runs_water_and_checks_its_options(
    estimator_file: Path, image: np.ndarray, tmp_path: Path
) -> None:
    write_rgb(tmp_path / "in.png", image)
    spec = f"water?strength=0.5,estimator={estimator_file}"
    res = CliRunner().invoke(app, ["enhance", str(tmp_path / "in.png"), "-o", str(tmp_path / "out.png"), "-m", spec])
    assert res.exit_code == 0, res.output
    assert read_rgb(tmp_path / "out.png").shape == image.shape
    # the weights line names the estimator as water's weights, then the Joint-ID it builds on
    line = next(x for x in res.output.splitlines() if "weights:" in x)
    assert line.startswith(f"water weights: {estimator_file}; distance and colour from the weights "), line
    assert line.endswith("jointid-small.pt"), line
    used = weights_used(create(spec))
    assert used.weights == str(estimator_file) and str(used.base_weights).endswith("jointid-small.pt")
    bad = CliRunner().invoke(
        app, ["enhance", str(tmp_path / "in.png"), "-o", str(tmp_path / "x.png"), "-m", "water?strength=2"]
    )
    assert bad.exit_code == 2 and "strength" in bad.output
    gone = CliRunner().invoke(
        app, ["enhance", str(tmp_path / "in.png"), "-o", str(tmp_path / "x.png"), "-m", "water?estimator=/no/w.npz"]
    )
    assert gone.exit_code == 2 and "/no/w.npz" in gone.output


def test_murk_enhance_records_the_estimated_water_of_each_image(
    estimator_file: Path, image: np.ndarray, tmp_path: Path
) -> None:
    from murk.workflows.water_estimate import estimate_water

    write_rgb(tmp_path / "in" / "a.png", image)
    write_rgb(tmp_path / "in" / "b.png", np.ascontiguousarray(image[::-1]))
    spec = f"water?estimator={estimator_file}"

    def enhance(method: str, out: str) -> list[dict]:
        res = CliRunner().invoke(app, ["enhance", str(tmp_path / "in"), "--out", str(tmp_path / out), "-m", method])
        assert res.exit_code == 0, res.output
        path = tmp_path / out / "estimates.jsonl"
        return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []

    rows = enhance(spec, "out")
    assert [Path(r["image"]).name for r in rows] == ["a.png", "b.png"]
    alone = estimate_water([tmp_path / "in" / "a.png"], estimator=estimator_file)[0]
    assert rows[0]["veil_rgb"] == alone.as_dict()["veil_rgb"]  # the same water as murk water estimate gives
    assert rows[0]["visibility_m"] == alone.as_dict()["visibility_m"] and "visibility_measurable" in rows[0]
    assert len(enhance(spec, "out")) == 2  # a rerun skips the done images: no new lines
    assert (
        len(enhance(f"water+post?estimator={estimator_file}", "chained")) == 2
    )  # a chain keeps what its stages estimated
    assert enhance("lite", "plain") == []  # a method that estimates nothing writes no file


def test_murk_enhance_records_the_estimated_water_of_each_video_frame(estimator_file: Path, tmp_path: Path) -> None:
    """A video out gets ``<stem>_estimates.jsonl`` beside it, a folder of frames ``estimates.jsonl``: one line per
    written frame, with the figures the method gives that decoded frame; a rerun of the video replaces the file."""
    from murk.enhance.frames_u8 import restore_frames
    from testkit.video import make_video, read_video

    clip = make_video(tmp_path / "clip.avi", 3, h=72, w=96)
    spec = f"water?estimator={estimator_file}"

    def enhance(out: Path, *extra: str) -> None:
        res = CliRunner().invoke(app, ["enhance", str(clip), "--out", str(out), "-m", spec, *extra])
        assert res.exit_code == 0, res.output

    def rows(path: Path) -> list[dict]:
        return [json.loads(line) for line in path.read_text().splitlines()]

    enhance(tmp_path / "out.avi")
    got = rows(tmp_path / "out_estimates.jsonl")
    assert [r["frame"] for r in got] == [0, 1, 2]
    assert {r["output"] for r in got} == {str(tmp_path / "out.avi")} and got[0]["input"].endswith("clip.avi")
    first = read_video(clip)[0]
    alone = restore_frames(create(spec), first[None]).facts
    assert alone is not None and got[0]["veil_rgb"] == alone[0]["veil_rgb"]
    enhance(tmp_path / "out.avi", "--overwrite")  # the video written anew: its estimates too, not appended
    assert len(rows(tmp_path / "out_estimates.jsonl")) == 3
    enhance(tmp_path / "frames")
    folder = rows(tmp_path / "frames" / "estimates.jsonl")
    assert [Path(r["output"]).exists() for r in folder] == [True, True, True]
    enhance(tmp_path / "frames")  # a rerun skips the written frames: no new lines
    assert len(rows(tmp_path / "frames" / "estimates.jsonl")) == 3
    res = CliRunner().invoke(app, ["enhance", str(clip), "--out", str(tmp_path / "plain.avi"), "-m", "lite"])
    assert res.exit_code == 0 and not (tmp_path / "plain_estimates.jsonl").exists()


def test_murk_water_estimate_reports_every_image_and_names_a_broken_one(
    estimator_file: Path, image: np.ndarray, tmp_path: Path
) -> None:
    write_rgb(tmp_path / "a.png", image)
    (tmp_path / "broken.png").write_bytes(b"no image")
    out = tmp_path / "new" / "water.jsonl"  # its folder is made
    res = CliRunner().invoke(
        app,
        ["water", "estimate", str(tmp_path / "a.png"), str(tmp_path / "broken.png"), "--json", str(out),
         "--estimator", str(estimator_file)],
    )  # fmt: skip
    assert res.exit_code == 1
    assert "broken.png" in res.stderr and "broken.png" not in res.stdout
    (line,) = res.stdout.splitlines()  # one line per image on stdout, however long
    assert line.startswith(str(tmp_path / "a.png")) and "visibility" in line
    rows = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(rows) == 1 and rows[0]["image"].endswith("a.png")
    before = (tmp_path / "a.png").read_bytes()
    for named in (tmp_path / "a.png", tmp_path):  # the image itself, or an image of a folder given
        res = CliRunner().invoke(app, ["water", "estimate", str(named), "--json", str(tmp_path / "a.png")])
        assert res.exit_code == 2 and "writing it would destroy it" in " ".join(res.stderr.split())
    assert (tmp_path / "a.png").read_bytes() == before
    assert len(rows[0]["veil_rgb"]) == 3 and rows[0]["visibility_m"] > 0


def test_murk_water_train_never_overwrites_an_estimator(estimator_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / "water.npz").write_bytes(estimator_file.read_bytes())
    config = Path(__file__).parents[2] / "configs" / "train-small-cpu.yaml"
    res = CliRunner().invoke(app, ["water", "train", "--config", str(config), "--out", str(out), "--scenes", "10"])
    assert res.exit_code == 2 and "never overwritten" in res.output
    assert (out / "water.npz").read_bytes() == estimator_file.read_bytes()


def test_murk_water_train_keys_its_samples_by_the_depth_networks_weights(tmp_path: Path) -> None:
    config = Path(__file__).parents[2] / "configs" / "train-small-cpu.yaml"
    out = tmp_path / "run"
    args = ["water", "train", "--config", str(config), "--out", str(out), "--scenes", "10", "--steps", "2"]
    res = CliRunner().invoke(app, args)
    assert res.exit_code == 0, res.output
    meta = load_water_estimator(out / "water.npz").meta or {}
    # Joint-ID's network (jointid_net, no lite blended in) gives the distance maps: named by content
    assert [name for name, _ in meta["base_weights"]] == ["jointid-small.pt"]
    with np.load(out / "samples.npz") as z:
        assert "jointid-small.pt" in str(z["key"])
