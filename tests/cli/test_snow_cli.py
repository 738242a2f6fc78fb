from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import sample_underwater_dir
from murk.snow.bank import load_bank

runner = CliRunner()
UW = sample_underwater_dir() / "ufen_gan"


def test_extract_with_tophat_writes_bank_and_previews(tmp_path: Path) -> None:
    bank = tmp_path / "bank.npz"
    r = runner.invoke(
        app,
        [
            "snow",
            "extract",
            str(UW),
            "--out",
            str(bank),
            "--method",
            "tophat",
            "--threshold",
            "8",
            "--tophat-px",
            "9",
            "--open-px",
            "0",
            "--min-area",
            "3",
        ],
    )
    assert r.exit_code == 0, r.output
    b = load_bank(bank)
    assert len(b) > 20 and b.meta["extract"]["method"] == "tophat"
    previews = sorted(p.name for p in (tmp_path / "bank_preview").iterdir())
    assert previews == ["EASI.jpg", "Lake.jpg"]
    assert cv2.imread(str(tmp_path / "bank_preview" / "Lake.jpg")).shape == (480, 1280, 3)  # source | mask
    info = runner.invoke(app, ["snow", "info", str(bank)])
    assert info.exit_code == 0 and json.loads(info.stdout)["particles"] == len(b)


def test_extract_fixed_threshold_on_bright_frames_fails_clearly(tmp_path: Path) -> None:
    r = runner.invoke(app, ["snow", "extract", str(UW / "Lake.jpg"), "--out", str(tmp_path / "b.npz")])
    assert r.exit_code == 2
    assert "no marine-snow particles found" in r.output and "covers 99.8 %" in r.output
    assert "--method tophat" in r.output and not (tmp_path / "b.npz").exists()
    # The preview of the rejected frame stays, for diagnosis, and the message says where it is.
    assert "their masks are in" in r.output and "b_preview" in r.output and "(no bank written)" in r.output
    assert [p.name for p in (tmp_path / "b_preview").iterdir()] == ["Lake.jpg"]


def test_extract_video_every_nth_frame_and_partial_failure(tmp_path: Path) -> None:
    video = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10, (96, 64))
    for i in range(6):
        f = np.full((64, 96, 3), 20, np.uint8)
        f[10 + i : 14 + i, 20:24] = 230
        f[40:44, 60:64] = 230
        w.write(f)
    w.release()
    (tmp_path / "bad.png").write_bytes(b"not a png")
    r = runner.invoke(
        app,
        [
            "snow",
            "extract",
            str(video),
            str(tmp_path / "bad.png"),
            "--out",
            str(tmp_path / "b.npz"),
            "--every",
            "2",
            "--open-px",
            "0",
            "--close-px",
            "0",
            "--no-preview",
        ],
    )
    assert r.exit_code == 1, r.output  # the bank was written but one input failed
    b = load_bank(tmp_path / "b.npz")
    assert [s["frame"] for s in b.meta["sources"]] == [0, 2, 4] and len(b) == 6
    assert "bad.png: cannot decode image" in r.output


def test_extract_refuses_a_bank_over_an_input_and_skips_earlier_banks_previews(tmp_path: Path) -> None:
    footage = tmp_path / "f"
    footage.mkdir()
    image = footage / "x.jpg"
    image.write_bytes((UW / "EASI.png").read_bytes())  # (a PNG under another suffix reads the same)
    before = image.read_bytes()
    args = ["--method", "tophat", "--threshold", "8", "--tophat-px", "9", "--open-px", "0", "--min-area", "3"]
    for out in (image, footage / "b.bank"):
        r = runner.invoke(app, ["snow", "extract", str(image), "--out", str(out), *args])
        assert r.exit_code == 2 and image.read_bytes() == before
        assert "a particle bank is a .npz file" in " ".join(r.output.split())
    first = runner.invoke(app, ["snow", "extract", str(footage), "--out", str(footage / "b1.npz"), *args])
    assert first.exit_code == 0 and (footage / "b1_preview" / "x.jpg").is_file()
    second = runner.invoke(app, ["snow", "extract", str(footage), "--out", str(footage / "b2.npz"), *args])
    assert second.exit_code == 0
    assert len(load_bank(footage / "b2.npz")) == len(load_bank(footage / "b1.npz"))  # no preview read as footage
    assert sorted(p.name for p in (footage / "b2_preview").iterdir()) == ["x.jpg"]


def test_extract_refuses_a_scale_range_given_largest_first(tmp_path: Path) -> None:
    for scale in ("0.6,0.3", "0,0.5", "0.3"):
        r = runner.invoke(app, ["snow", "extract", str(UW), "--out", str(tmp_path / "b.npz"), "--scale", scale])
        assert r.exit_code == 2 and "--scale: expected" in " ".join(r.output.split()), (scale, r.output)
    assert not (tmp_path / "b.npz").exists()
