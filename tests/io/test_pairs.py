from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from murk.data import sample_rgbd_dir
from murk.errors import InputFileError
from murk.io import DepthOptions, discover, load_pair, read_list

from ._bombs import npy_bomb


def test_discover_matches_by_stem_and_reports_orphans(small_rgbd: Path) -> None:
    cv2.imwrite(str(small_rgbd / "rgb" / "lonely.png"), np.zeros((4, 4, 3), np.uint8))
    cv2.imwrite(str(small_rgbd / "depth" / "nodepth_rgb.png"), np.ones((4, 4), np.uint16))
    sources, problems = discover(small_rgbd)
    assert [s.stem for s in sources] == ["a", "b"]
    assert {Path(p.input).name for p in problems} == {"lonely.png", "nodepth_rgb.png"}


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
    lst.write_text("rgb/a.png depth/a.png\nx/a.png d/a.png\nrgb/a_1.png depth/a_1.png\ny/a.png d/a.png\n")
    assert [s.stem for s in read_list(lst)] == ["a", "a_1", "a_1_1", "a_2"]  # every output name distinct
    lst.write_text("rgb/a.png\n")
    with pytest.raises(InputFileError, match=r"pairs\.txt: line 1: expected 'rgb_path depth_path'"):
        read_list(lst)


def test_same_stem_twice_is_reported_as_ambiguous_and_the_rest_still_loads(small_rgbd: Path) -> None:
    rgb, depth = small_rgbd / "rgb", small_rgbd / "depth"
    cv2.imwrite(str(rgb / "dup.png"), np.zeros((48, 64, 3), np.uint8))
    cv2.imwrite(str(rgb / "dup.jpg"), np.zeros((48, 64, 3), np.uint8))
    cv2.imwrite(str(depth / "dup.png"), np.ones((48, 64), np.uint16))
    cv2.imwrite(str(rgb / "x.png"), np.zeros((48, 64, 3), np.uint8))
    np.save(depth / "x.npy", np.ones((48, 64), np.float32))
    cv2.imwrite(str(depth / "x.png"), np.ones((48, 64), np.uint16))
    sources, problems = discover(small_rgbd)
    assert [s.stem for s in sources] == ["a", "b"]
    by_stem = {Path(p.input).stem: p.error for p in problems}
    assert set(by_stem) == {"dup", "x"} and {Path(p.input).name for p in problems} == {"dup.jpg", "x.npy"}
    assert by_stem["dup"].startswith(f"ambiguous stem 'dup': {rgb / 'dup.jpg'}, {rgb / 'dup.png'} share it; ")
    assert by_stem["x"].startswith(f"ambiguous stem 'x': {depth / 'x.npy'}, {depth / 'x.png'} share it; ")
    for s in sources:
        assert load_pair(s, DepthOptions())[1].shape == (48, 64)


def test_ambiguous_depth_without_rgb_is_an_orphan(small_rgbd: Path) -> None:
    np.save(small_rgbd / "depth" / "z.npy", np.ones((4, 4), np.float32))
    cv2.imwrite(str(small_rgbd / "depth" / "z.png"), np.ones((4, 4), np.uint16))
    sources, problems = discover(small_rgbd)
    assert len(sources) == 2
    assert [(Path(p.input).name, p.error) for p in problems] == [
        ("z.npy", f"no RGB image with stem 'z' in {small_rgbd / 'rgb'}")
    ]


def test_a_bomb_depth_fails_its_pair_only(small_rgbd: Path) -> None:
    cv2.imwrite(str(small_rgbd / "rgb" / "c.png"), np.zeros((48, 64, 3), np.uint8))
    npy_bomb(small_rgbd / "depth" / "c.npy")
    sources, problems = discover(small_rgbd)
    assert [s.stem for s in sources] == ["a", "b", "c"] and problems == []
    with pytest.raises(InputFileError, match=r"c\.npy: declares float64 \(100000, 100000\) = 10,000,000,000 elements"):
        load_pair(sources[2], DepthOptions())
    for s in sources[:2]:
        assert load_pair(s, DepthOptions())[0].shape == (48, 64, 3)
