"""The ``detail`` method (a learned local residual added to the image it gets), with a small network made here (the
shipped one is tested in tests/models/test_detail.py)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_underwater_images
from murk.enhance.restorer import create
from murk.io import read_rgb, write_rgb
from murk.models.detail import DetailNet, save_detail


@pytest.fixture(scope="module")
def net_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    torch.manual_seed(0)
    net = DetailNet(4)
    torch.nn.init.normal_(net.convs[-1].weight, std=0.05)  # a residual that is not zero
    return save_detail(net, tmp_path_factory.mktemp("detail") / "detail.npz", {"test": True})


@pytest.fixture(scope="module")
def image() -> np.ndarray:
    return cv2.resize(read_rgb(sample_underwater_images()[0]), (97, 71), interpolation=cv2.INTER_AREA)


def test_detail_adds_the_residual_times_strength(net_file: Path, image: np.ndarray) -> None:
    from murk.models.detail import load_detail

    net, meta = load_detail(net_file)
    assert meta == {"test": True, "channels": 4}
    x = torch.from_numpy(image).permute(2, 0, 1)[None]
    with torch.no_grad():
        residual = net(x)[0].permute(1, 2, 0).numpy()
    assert np.abs(residual).max() > 0.01
    for strength in (0.0, 0.5, 1.0, 2.0):
        out = create("detail", weights=str(net_file), strength=strength).restore(image[None])
        np.testing.assert_allclose(out.images[0], np.clip(image + strength * residual, 0, 1), atol=2e-6)
        assert out.depth_m is None


def test_detail_after_a_restorer_works_on_its_output_and_keeps_its_depth(net_file: Path, image: np.ndarray) -> None:
    base = create("jointid").restore(image[None])
    chained = create(f"jointid+detail?weights={net_file}").restore(image[None])
    alone = create("detail", weights=str(net_file)).restore(np.clip(base.images, 0, 1))
    np.testing.assert_allclose(chained.images, alone.images, atol=1e-5)
    np.testing.assert_array_equal(chained.depth_m, base.depth_m)


def test_detail_runs_the_same_one_image_at_a_time(net_file: Path, image: np.ndarray) -> None:
    batch = np.stack([image, image[::-1].copy()])
    r = create("detail", weights=str(net_file))
    together = r.restore(batch).images
    for i in (0, 1):
        np.testing.assert_allclose(together[i], r.restore(batch[i : i + 1]).images[0], atol=1e-6)


def test_murk_enhance_runs_lite_detail_and_checks_its_options(
    net_file: Path, image: np.ndarray, tmp_path: Path
) -> None:
    write_rgb(tmp_path / "in.png", image)
    args = ["enhance", str(tmp_path / "in.png"), "-o"]
    res = CliRunner().invoke(app, [*args, str(tmp_path / "out.png"), "-m", f"lite+detail?weights={net_file}"])
    assert res.exit_code == 0, res.output
    assert read_rgb(tmp_path / "out.png").shape == image.shape
    bad = CliRunner().invoke(app, [*args, str(tmp_path / "x.png"), "-m", "lite+detail?strength=3"])
    assert bad.exit_code == 2 and "strength" in bad.output
    gone = CliRunner().invoke(app, [*args, str(tmp_path / "x.png"), "-m", "lite+detail?weights=/no/d.npz"])
    assert gone.exit_code == 2 and "/no/d.npz" in gone.output and "not found" in gone.output
    (tmp_path / "junk.npz").write_bytes(b"not a network")
    junk = CliRunner().invoke(app, [*args, str(tmp_path / "x.png"), "-m", f"detail?weights={tmp_path / 'junk.npz'}"])
    assert junk.exit_code != 0 and "junk.npz" in junk.output and "not a murk detail network" in junk.output
    assert not (tmp_path / "x.png").exists()


def test_the_weights_line_names_the_detail_network_after_the_restorer(net_file: Path) -> None:
    from murk.data import shipped_lite_weights
    from murk.enhance.restorer import weights_used
    from murk.enhance.run import weights_line

    chained = create(f"lite+detail?weights={net_file}")
    used = weights_used(chained)
    assert used.weights == str(shipped_lite_weights()) and [r.weights for r in used.later] == [str(net_file)]
    line = weights_line(chained, shipped=True)
    assert line is not None and line.endswith(f"; then detail weights: {net_file}")


def test_murk_compare_records_the_detail_networks_weights(net_file: Path, image: np.ndarray, tmp_path: Path) -> None:
    import json

    write_rgb(tmp_path / "in" / "a.png", image)
    res = CliRunner().invoke(
        app,
        [
            "compare",
            str(tmp_path / "in"),
            "--out",
            str(tmp_path / "rep"),
            "--method",
            f"lite+detail?weights={net_file}",
        ],
    )
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    (method,) = [m for m in doc["methods"] if m["spec"].startswith("lite+detail")]
    assert method["weights"].endswith("lite.pt") and method["later_weights"] == str(net_file)
