"""Every refusal a user can hit says what to do: a flag, a valid value, a command (issue 49, point 2).

One case per refusal reviewed in issue 49: the command exits 2 with one line that names the problem (pinned as
before) and the way out (pinned here). The checkpoint refusals are pinned in tests/reliability (enhance, export,
train), tests/models/test_jointid_checkpoint.py (a plain pickle) and tests/cli/test_cli_export.py (murk live).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from murk.cli.main import app

runner = CliRunner()


def _image(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), np.full((24, 32, 3), 90, np.uint8))
    return path


def _glob(tmp: Path) -> list[str]:
    _image(tmp / "in" / "a.png")
    return ["enhance", str(tmp / "in" / "*.tif"), "--out", str(tmp / "o")]


def _one_image_to_a_video(tmp: Path) -> list[str]:
    return ["enhance", str(_image(tmp / "a.png")), "--out", str(tmp / "o.mp4")]


def _format_against_name(tmp: Path) -> list[str]:
    return ["enhance", str(_image(tmp / "a.png")), "--out", str(tmp / "o.jpg"), "--format", "png", "-m", "post"]


def _option_twice(tmp: Path) -> list[str]:
    return ["enhance", str(_image(tmp / "a.png")), "--out", str(tmp / "o"), "-m", "post?lam=0.3,lam=0.4"]


def _raw_with_options(tmp: Path) -> list[str]:
    _image(tmp / "in" / "a.png")
    return ["compare", str(tmp / "in"), "--out", str(tmp / "o"), "--method", "raw?x=1"]


def _compare_subfolders_only(tmp: Path) -> list[str]:
    _image(tmp / "in" / "sub" / "a.png")
    return ["compare", str(tmp / "in"), "--out", str(tmp / "o"), "--method", "post"]


def _textures_without_images(tmp: Path) -> list[str]:
    (tmp / "tex").mkdir()
    (tmp / "tex" / "notes.txt").write_text("no image")
    return ["scenes", str(tmp / "s"), "--count", "1", "--size", "64x48", "--textures", str(tmp / "tex")]


def _empty_pair_list(tmp: Path) -> list[str]:
    (tmp / "pairs.txt").write_text("# nothing yet\n")
    return ["synth", str(tmp / "o"), "--list", str(tmp / "pairs.txt")]


def _resume_nothing(tmp: Path) -> list[str]:
    _image(tmp / "rgbd" / "rgb" / "a.png")
    (tmp / "rgbd" / "depth").mkdir()
    assert cv2.imwrite(str(tmp / "rgbd" / "depth" / "a.png"), np.full((24, 32), 2000, np.uint16))
    cfg = tmp / "t.yaml"
    cfg.write_text("model:\n  kind: lite\n  variant: tiny\ndata:\n  crop_hw: [32, 32]\n")
    return ["train", "--config", str(cfg), "--data", str(tmp / "rgbd"), "--out", str(tmp / "run"), "--resume"]


CASES: dict[str, tuple[Callable[[Path], list[str]], str, str]] = {
    # case: (arguments, the problem (as before), the way out)
    "glob": (_glob, "the pattern matches no image file", "check the folder and the pattern"),
    "video": (_one_image_to_a_video, "images are written to a folder or an image file, not a video", "name a folder"),
    "format": (_format_against_name, "--format png contradicts the output file name o.jpg", "leave --format out"),
    "twice": (_option_twice, "option 'lam' given twice", "give it once"),
    "raw": (_raw_with_options, "raw (the input itself) takes no checkpoint or options", "write it as plain raw"),
    "recursive": (_compare_subfolders_only, "no images found", "(use --recursive for subfolders)"),
    "textures": (_textures_without_images, "no images found for --textures", "give a folder of images"),
    "list": (_empty_pair_list, "no pairs listed", "(expected one 'rgb_path depth_path' per line)"),
    "resume": (_resume_nothing, "nothing to resume", "leave --resume out to start a new run"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_a_refusal_names_the_way_out(tmp_path: Path, case: str) -> None:
    args, problem, way_out = CASES[case]
    res = runner.invoke(app, args(tmp_path))
    text = " ".join(res.output.split())
    assert res.exit_code == 2, res.output
    assert "Traceback" not in res.output
    assert problem in text and way_out in text, text


@pytest.mark.skipif(torch.cuda.is_available(), reason="needs a machine without CUDA")
@pytest.mark.parametrize("command", ["enhance", "compare"])
def test_cuda_on_a_cpu_machine_says_how_to_run(tmp_path: Path, command: str) -> None:
    _image(tmp_path / "in" / "a.png")
    args = [command, str(tmp_path / "in"), "--out", str(tmp_path / "o"), "--device", "cuda", "--method", "post"]
    res = runner.invoke(app, args)
    text = " ".join(res.output.split())
    assert res.exit_code == 2, res.output
    assert "CUDA is not available" in text and "leave --device out to run on the CPU" in text, text


def test_a_camera_that_does_not_open_says_what_to_check(tmp_path: Path) -> None:
    res = runner.invoke(app, ["enhance", "97", "--out", str(tmp_path / "cam.mp4")])
    text = " ".join(res.output.split())
    assert res.exit_code == 2
    assert "camera 97: cannot open camera" in text and "check the index (ls /dev/video*)" in text, text
