from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from murk.data import default_snow_bank, sample_underwater_dir
from murk.errors import InputFileError
from murk.io import read_image
from murk.snow.bank import bank_to_bytes, build_bank, extract_bank, load_bank, save_bank, subpixel_report
from murk.snow.extract import CoverageError, ExtractConfig, elongation, extract_particles, particle_mask

from .conftest import make_bank


def _dots(h: int = 120, w: int = 160, background: int = 30) -> np.ndarray:
    """A dark frame with 12 bright 3x3 dots and one bright line (a structure edge, not snow)."""
    img = np.full((h, w, 3), background, np.uint8)
    for i in range(12):
        y, x = 10 + (i // 4) * 35, 10 + (i % 4) * 38
        img[y : y + 3, x : x + 3] = (200, 210, 190)
    img[100, 20:120] = 220
    return img


def test_threshold_extraction_finds_the_dots_and_drops_the_line() -> None:
    ex = extract_particles(_dots(), ExtractConfig(open_px=0, close_px=0), source="dots")
    assert len(ex.particles) == 12
    assert all(p.area_px == 9 and p.rgb[p.mask].tolist()[0] == [200, 210, 190] for p in ex.particles)
    assert ex.mask[100, 50]  # the line is in the mask but filtered as elongated
    assert elongation(ex.mask[100:101, 20:120]) > 20


@pytest.mark.parametrize("method", ["adaptive", "tophat"])
def test_other_methods_find_dots_on_a_bright_background(method: str) -> None:
    img = _dots(background=150)
    with pytest.raises(CoverageError):
        extract_particles(img, ExtractConfig(), source="bright")
    ex = extract_particles(img, ExtractConfig(method=method, open_px=0, close_px=0))  # type: ignore[arg-type]
    assert len(ex.particles) == 12


def test_bright_lake_frame_with_fixed_threshold_is_explained() -> None:
    rgb, _ = read_image(sample_underwater_dir() / "ufen_gan" / "Lake.jpg")
    with pytest.raises(CoverageError, match=r"Lake\.jpg: the particle mask covers 99\.8 % .*--method tophat"):
        extract_particles(rgb, ExtractConfig(), source="Lake.jpg")


def test_morphology_removes_single_pixel_noise() -> None:
    img = np.zeros((40, 40), np.uint8)
    img[5, 5] = 255
    img[20:24, 20:24] = 255
    m = particle_mask(img, ExtractConfig(open_px=2, close_px=0))
    assert not m[5, 5] and m[21, 21]


def test_zero_particles_error_names_the_inputs() -> None:
    frames = [
        ({"path": "a.png"}, np.zeros((30, 30, 3), np.uint8)),
        ({"path": "b.png"}, np.zeros((30, 30, 3), np.uint8)),
    ]
    with pytest.raises(ValueError, match=r"no marine-snow particles found in a\.png, b\.png \(method threshold"):
        extract_bank(frames, ExtractConfig())


def test_extract_bank_reports_rejected_frames_and_keeps_the_rest() -> None:
    frames = [({"path": "good.png"}, _dots()), ({"path": "bright.png"}, _dots(background=150))]
    rep = extract_bank(frames, ExtractConfig(open_px=0, close_px=0))
    assert len(rep.bank) == 12 and (rep.problems[0].input, rep.problems[0].stage) == ("bright.png", "extract")
    assert rep.bank.meta["sources"][0]["particles"] == 12 and rep.bank.meta["extract"]["method"] == "threshold"


def test_subpixel_warning_has_the_numbers() -> None:
    frames = [({"path": "tiny.png"}, _tiny_dots())]
    rep = extract_bank(frames, ExtractConfig(open_px=0, close_px=0, min_area_px=1))
    assert (
        rep.warnings
        and "100 % of the 12 particles are smaller than 1 px even at the largest scale 0.6" in rep.warnings[0]
    )
    vanish, _ = subpixel_report(make_bank(sizes=(5,)), (0.3, 0.6))
    assert vanish == 0.0


def _tiny_dots() -> np.ndarray:
    img = np.zeros((60, 60, 3), np.uint8)
    for i in range(12):
        img[5 + (i // 4) * 15, 5 + (i % 4) * 15] = 255
    return img


def test_bank_round_trip_and_id(tmp_path: Path, solid_bank) -> None:
    path = save_bank(solid_bank, tmp_path / "b.npz")
    back = load_bank(path)
    assert back.bank_id == solid_bank.bank_id and len(back) == 3
    for name in ("offsets", "pixel_yx", "pixel_rgb", "source_index", "source_xy", "bbox_hw"):
        np.testing.assert_array_equal(getattr(back, name), getattr(solid_bank, name))
    assert bank_to_bytes(back) == bank_to_bytes(solid_bank)
    assert make_bank(colour=(1, 1, 1)).bank_id != solid_bank.bank_id
    np.testing.assert_array_equal(back.areas_px, [1, 9, 25])


def test_load_bank_errors(tmp_path: Path) -> None:
    with pytest.raises(InputFileError, match="particle bank not found"):
        load_bank(tmp_path / "none.npz")
    (tmp_path / "junk.npz").write_bytes(b"junk")
    with pytest.raises(InputFileError, match=r"junk\.npz: not a readable particle bank"):
        load_bank(tmp_path / "junk.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(InputFileError, match="not a murk particle bank \\(missing"):
        load_bank(tmp_path / "other.npz")
    with pytest.raises(InputFileError, match="holds no particles"):
        save_bank(build_bank([]), tmp_path / "empty.npz")
        load_bank(tmp_path / "empty.npz")


def test_shipped_small_bank() -> None:
    from murk.data import small_snow_bank

    bank = load_bank("builtin:snow-small")
    assert bank.bank_id == load_bank(small_snow_bank()).bank_id
    assert len(bank) == 85
    assert {Path(s["path"]).name for s in bank.meta["sources"]} == {"EASI.png", "Lake.jpg"}
    assert bank.meta["extract"]["method"] == "tophat"


def test_shipped_default_bank_is_the_real_footage_bank_relit() -> None:
    bank, real = load_bank(default_snow_bank()), load_bank("builtin:snow-real")
    assert load_bank("builtin:snow").bank_id == bank.bank_id != real.bank_id
    assert len(bank) >= 1000  # the real-snow issue's floor, from the same 20 frames (test below)
    np.testing.assert_array_equal(bank.offsets, real.offsets)  # the same particles, shapes and sizes
    np.testing.assert_array_equal(bank.pixel_yx, real.pixel_yx)
    assert bank.meta["sources"] == real.meta["sources"]
    assert bank.meta["relight"] == {"luma": [120.0, 230.0], "seed": 0, "from_bank_id": real.bank_id}


def test_shipped_real_footage_bank() -> None:
    from murk.data import real_footage_snow_bank

    bank = load_bank("builtin:snow-real")
    assert bank.bank_id == load_bank(real_footage_snow_bank()).bank_id
    assert len(bank) >= 1000  # the real-snow issue's floor
    names = [Path(s["path"]).name for s in bank.meta["sources"]]
    assert len(names) >= 20 and len({n.split("_")[0] for n in names}) >= 2  # frames of several sources
    evaluation = {p.name for p in sample_underwater_dir().rglob("*") if p.is_file()}
    assert not set(names) & evaluation  # none of murk's own real evaluation images
    assert bank.meta["extract"]["method"] == "tophat"
