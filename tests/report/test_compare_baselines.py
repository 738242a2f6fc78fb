"""The paper's comparison on small images: ``murk compare`` and ``murk enhance`` with the full-size UDAformer and
URSCT-SESR loaded from fake official files (random weights; the architectures are proven exact by the golden
tests in tests/models), both input policies, and the --trust-checkpoint refusal of UDAformer's official file."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import pytest
import torch
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_underwater_dir
from murk.models.udaformer import UDAformer
from murk.models.ursct_sesr import URSCT
from murk.models.ursct_sesr.network import relative_position_index

runner = CliRunner()


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("baselines")
    torch.manual_seed(0)
    uda = UDAformer()
    uda_path = root / "checkpoint_489_epoch.pkl"  # the official layout: the Adam object is pickled too
    torch.save({"model": uda.state_dict(), "optimizer": torch.optim.Adam(uda.parameters()), "epoch": 489}, uda_path)
    ursct = URSCT()
    state = {f"module.{k}": v for k, v in ursct.state_dict().items()}
    state |= {f"module.{k}": relative_position_index() for k, _ in ursct.named_buffers() if k.endswith("index")}
    ursct_path = root / "model_bestSSIM.pth"
    torch.save({"epoch": 700, "state_dict": state, "PSNR": 20.0, "SSIM": 0.8}, ursct_path)
    real = root / "real"
    real.mkdir()
    img = cv2.imread(str(sample_underwater_dir() / "suim" / "d_r_47_.jpg"))
    cv2.imwrite(str(real / "site.png"), cv2.resize(img, (96, 64), interpolation=cv2.INTER_AREA))
    return {"uda": uda_path, "ursct": ursct_path, "real": real}


def test_compare_runs_the_paper_baselines(files: dict[str, Path], tmp_path: Path) -> None:
    methods = [
        "raw",
        "post",
        f"udaformer:{files['uda']}",
        f"ursct:{files['ursct']}",
        f"ursct-official=ursct:{files['ursct']}?policy=official",
    ]
    args = ["compare", str(files["real"]), "--out", str(tmp_path / "rep")]
    for m in methods:
        args += ["--method", m]
    refused = runner.invoke(app, args)
    assert refused.exit_code == 2
    assert "--trust-checkpoint" in refused.output and "Adam optimiser" in refused.output
    res = runner.invoke(app, [*args, "--trust-checkpoint"])
    assert res.exit_code == 0, res.output
    doc = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    labels = ["raw", "post", "udaformer:", "ursct:", "ursct-official"]
    labels[2] = next(m["label"] for m in doc["methods"] if m["method"] == "udaformer")
    labels[3] = next(m["label"] for m in doc["methods"] if m["method"] == "ursct" and "official" not in m["spec"])
    assert [r["method"] for r in doc["rows"]] == labels and not doc["errors"]
    for label in labels:
        assert doc["summary"][label]["uiqm"]["n"] == 1
    weights = {m["label"]: m["weights"] for m in doc["methods"]}
    assert weights[labels[2]] == str(files["uda"]) and weights["ursct-official"] == str(files["ursct"])
    html = (tmp_path / "rep" / "report.html").read_text()
    assert "ursct-official (256x256)" in html  # the official policy's output size is reported
    grid = cv2.imread(str(tmp_path / "rep" / "grids" / "site.jpg"))
    assert grid is not None and grid.shape[1] >= 5 * 300


def test_enhance_cli_with_both_policies(files: dict[str, Path], tmp_path: Path) -> None:
    image = files["real"] / "site.png"
    base = ["enhance", str(image), "--method", "ursct", "--checkpoint", str(files["ursct"]), "--quiet"]
    res = runner.invoke(app, [*base, "--out", str(tmp_path / "native.png")])
    assert res.exit_code == 0, res.output
    assert cv2.imread(str(tmp_path / "native.png")).shape == (64, 96, 3)
    res = runner.invoke(app, [*base, "--policy", "official", "--out", str(tmp_path / "official.png")])
    assert res.exit_code == 0, res.output
    assert cv2.imread(str(tmp_path / "official.png")).shape == (256, 256, 3)
    res = runner.invoke(app, ["enhance", str(image), "--method", "udaformer", "--out", str(tmp_path / "x.png")])
    assert res.exit_code == 2 and "does not bundle or download" in res.output
