from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.data import sample_rgbd_dir
from murk.errors import InputFileError
from murk.io import DepthOptions, discover, load_pair, read_list


def test_discover_matches_by_stem_and_reports_orphans(small_rgbd: Path) -> None:
    cv2.imwrite(str(small_rgbd / "rgb" / "lonely.png"), np.zeros((4, 4, 3), np.uint8))
    cv2.imwrite(str(small_rgbd / "depth" / "nodepth_rgb.png"), np.ones((4, 4), np.uint16))
    sources, problems = discover(small_rgbd)
    assert [s.stem for s in sources] == ["a", "b"]
    assert {Path(p.path).name for p in problems} == {"lonely.png", "nodepth_rgb.png"}


def test_discover_errors(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="not found"):
        discover(tmp_path / "nothing")
    with pytest.raises(InputFileError, match="expected subfolders rgb/"):
        discover(tmp_path)


def test_shipped_sample_pairs_load() -> None:
    sources, problems = discover(sample_rgbd_dir())
    assert len(sources) == 3 and problems == []
    for s in sources:
        rgb, depth, valid = load_pair(s, DepthOptions())
        assert rgb.shape[:2] == depth.shape == valid.shape
        assert np.isfinite(depth).all() and depth.min() > 0.2 and depth.max() < 15


def test_size_mismatch_names_both_files(small_rgbd: Path) -> None:
    cv2.imwrite(str(small_rgbd / "depth" / "a.png"), np.ones((10, 10), np.uint16))
    sources, _ = discover(small_rgbd)
    with pytest.raises(InputFileError, match=r"a\.png: size 64x48 does not match depth .*a\.png \(10x10\)"):
        load_pair(sources[0], DepthOptions())


def test_crop_trims_both(small_rgbd: Path) -> None:
    sources, _ = discover(small_rgbd)
    rgb, depth, _ = load_pair(sources[0], DepthOptions(crop_px=8))
    assert rgb.shape == (32, 48, 3) and depth.shape == (32, 48)
    with pytest.raises(InputFileError, match="--crop 30 leaves nothing"):
        load_pair(sources[0], DepthOptions(crop_px=30))


def test_read_list(small_rgbd: Path) -> None:
    lst = small_rgbd / "pairs.txt"
    lst.write_text("# comment\nrgb/a.png depth/a.png\n\nrgb/b.png depth/b.png  # trailing\n")
    sources = read_list(lst)
    assert [s.stem for s in sources] == ["a", "b"]
    assert Path(sources[0].depth_path).is_file()
    lst.write_text("rgb/a.png\n")
    with pytest.raises(InputFileError, match=r"pairs\.txt: line 1: expected 'rgb_path depth_path'"):
        read_list(lst)
