"""Particle banks are validated in full on load; the snow commands turn bad banks and inputs into one line.

Every bad bank here is a small generated file: real arrays written with ``np.savez`` and then edited, or a
hand-written ``.npy`` header (the 2^31-element one is a header only, not real data).
"""

from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from murk.cli.main import app
from murk.data import default_snow_bank, sample_rgbd_dir, small_snow_bank
from murk.errors import InputFileError
from murk.io import read_jsonl
from murk.snow.bank import bank_to_bytes, load_bank, save_bank

from .conftest import make_bank

runner = CliRunner()


def _arrays() -> dict[str, np.ndarray]:
    """The arrays of a valid 3-particle bank (sizes 1, 3 and 5 px), ``meta`` as its JSON string."""
    bank = make_bank()
    arrays = {k: getattr(bank, k) for k in ("offsets", "pixel_yx", "pixel_rgb", "source_index", "source_xy")}
    return {"meta": np.array(json.dumps(bank.meta)), **arrays, "bbox_hw": bank.bbox_hw}


def _npy(header: dict[str, Any], data: bytes = b"") -> bytes:
    """A ``.npy`` member with a hand-written header (v1.0) followed by ``data``."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, header)
    return buf.getvalue() + data


def _members(**arrays: np.ndarray) -> dict[str, bytes]:
    out = {}
    for name, a in arrays.items():
        buf = io.BytesIO()
        np.lib.format.write_array(buf, a, allow_pickle=a.dtype.hasobject)
        out[f"{name}.npy"] = buf.getvalue()
    return out


def _zip(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w") as z:
        for name, data in members.items():
            z.writestr(name, data)
    return path


def _edited(**changes: Any) -> Callable[[Path], Path]:
    """A writer of a bank whose arrays are replaced (``None`` drops an array)."""

    def write(path: Path) -> Path:
        arrays = {**_arrays(), **changes}
        np.savez(path, **{k: v for k, v in arrays.items() if v is not None})
        return path

    return write


def _with_members(**raw: bytes) -> Callable[[Path], Path]:
    """A writer of a bank whose ``.npy`` members are replaced by raw bytes."""

    def write(path: Path) -> Path:
        return _zip(path, {**_members(**_arrays()), **{f"{k}.npy": v for k, v in raw.items()}})

    return write


def _bytes(data: bytes) -> Callable[[Path], Path]:
    def write(path: Path) -> Path:
        path.write_bytes(data)
        return path

    return write


def _truncated(path: Path) -> Path:
    data = bank_to_bytes(make_bank())
    path.write_bytes(data[: len(data) // 2])
    return path


def _truncated_member(path: Path) -> Path:
    members = _members(**_arrays())
    members["pixel_yx.npy"] = members["pixel_yx.npy"][:-20]
    return _zip(path, members)


def _corrupt_member_data(path: Path) -> Path:
    """A compressed bank with bytes flipped in the middle of the pixel data (the zip CRC no longer matches)."""
    data = bytearray(bank_to_bytes(make_bank(sizes=(20, 20, 20))))
    with zipfile.ZipFile(io.BytesIO(bytes(data))) as z:
        info = z.getinfo("pixel_rgb.npy")
    start = info.header_offset + 30 + len(info.filename) + len(info.extra) + info.compress_size // 2
    data[start : start + 8] = b"\xff" * 8
    path.write_bytes(bytes(data))
    return path


def _meta(value: Any) -> np.ndarray:
    return np.array(value if isinstance(value, str) else json.dumps(value))


_GOOD = _arrays()
_YX = _GOOD["pixel_yx"]
_OFF = _GOOD["offsets"]
_META = json.loads(str(_GOOD["meta"]))

# name -> (writer, the problem the message must state)
BAD_BANKS: dict[str, tuple[Callable[[Path], Path], str]] = {
    "zero-byte": (_bytes(b""), r"empty file \(0 bytes\)"),
    "not a zip": (_bytes(b"junk, not a zip archive"), "not a readable particle bank"),
    "truncated file": (_truncated, "not a readable particle bank \\(not a .npz archive, or a truncated one"),
    "truncated member": (_truncated_member, "the header of array 'pixel_yx' declares 70 elements"),
    "corrupt member data": (_corrupt_member_data, "array 'pixel_rgb' cannot be read"),
    "missing array": (_edited(bbox_hw=None), r"not a murk particle bank \(missing bbox_hw\)"),
    "2^31 elements declared": (
        _with_members(offsets=_npy({"descr": "<i8", "fortran_order": False, "shape": (2**31,)}, b"\0" * 64)),
        "the header of array 'offsets' declares 2,147,483,648 elements",
    ),
    "negative shape": (
        _with_members(offsets=_npy({"descr": "<i8", "fortran_order": False, "shape": (-4,)})),
        "array 'offsets' (has a bad .npy header|declares a negative shape)",
    ),
    "garbage header": (
        _with_members(offsets=b"\x93NUMPY\x01\x00\x10\x00{'descr': nonsense"),
        "array 'offsets' has a bad .npy header",
    ),
    "complex coordinates": (_edited(pixel_yx=_YX.astype(np.complex64)), "array 'pixel_yx' has dtype complex64"),
    "object array": (
        _edited(pixel_yx=np.array([None] * 35, dtype=object).reshape(35, 1)),
        "array 'pixel_yx' has dtype object",
    ),
    "integer coordinates": (_edited(pixel_yx=_YX.astype(np.int32)), "array 'pixel_yx' has dtype int32"),
    "float colours": (_edited(pixel_rgb=_GOOD["pixel_rgb"].astype(np.float32)), "'pixel_rgb' has dtype float32"),
    "uint16 colours": (_edited(pixel_rgb=_GOOD["pixel_rgb"].astype(np.uint16)), "'pixel_rgb' has dtype uint16"),
    "float offsets": (_edited(offsets=_OFF.astype(np.float64)), "array 'offsets' has dtype float64"),
    "bool boxes": (_edited(bbox_hw=_GOOD["bbox_hw"] > 0), "array 'bbox_hw' has dtype bool"),
    "structured colours": (
        _edited(pixel_rgb=np.zeros(35, dtype=[("r", "u1"), ("g", "u1"), ("b", "u1")])),
        "array 'pixel_rgb' has dtype",
    ),
    "wrong ndim": (_edited(pixel_yx=_YX.reshape(-1)), r"array 'pixel_yx' has shape \(70,\)"),
    "wrong last axis": (_edited(pixel_rgb=np.zeros((35, 4), np.uint8)), r"'pixel_rgb' has shape \(35, 4\)"),
    "pixel counts differ": (_edited(pixel_rgb=np.zeros((34, 3), np.uint8)), "pixel_yx holds 35 pixels, pixel_rgb 34"),
    "rows per particle differ": (_edited(bbox_hw=np.ones((2, 2), np.int32)), "bbox_hw has 2 rows for 3 particles"),
    "no particles": (_edited(offsets=np.zeros(1, np.int64)), "holds no particles"),
    "negative offsets": (_edited(offsets=np.array([0, -1, 10, 35])), r"offsets holds negative values \(min -1\)"),
    "offsets past the end": (_edited(offsets=np.array([0, 1, 10, 2**40])), "offsets point past the pixel arrays"),
    "offsets not from 0": (_edited(offsets=np.array([1, 2, 10, 35])), "offsets must start at 0"),
    "offsets not monotone": (
        _edited(offsets=np.array([0, 10, 1, 35])),
        r"offsets must increase strictly \(particle 1: 10 -> 1\)",
    ),
    "offsets end early": (_edited(offsets=np.array([0, 1, 10, 30])), "offsets end at 30 but the pixel arrays hold 35"),
    "huge unsigned offsets": (
        _edited(offsets=np.array([0, 1, 2**64 - 1, 35], np.uint64)),
        "offsets point past the pixel arrays",
    ),
    "NaN coordinates": (
        _edited(pixel_yx=np.where(np.arange(35)[:, None] == 7, np.nan, _YX)),
        "2 NaN or infinite coordinates",
    ),
    "infinite coordinates": (_edited(pixel_yx=np.full_like(_YX, np.inf)), "70 NaN or infinite coordinates"),
    "coordinate far outside": (
        _edited(pixel_yx=np.where(np.arange(35)[:, None] == 34, 1e30, _YX)),
        "particle 2 has pixels outside its 5x5 bounding box",
    ),
    "zero-size box": (_edited(bbox_hw=np.array([[1, 1], [0, 3], [5, 5]], np.int32)), "expected particle sides"),
    "giant box": (_edited(bbox_hw=np.array([[1, 1], [3, 3], [5, 10**6]], np.int32)), "expected particle sides"),
    "more pixels than the box": (
        _edited(bbox_hw=np.array([[1, 1], [3, 3], [2, 5]], np.int32)),
        "particle 2 has 25 pixels in a 2x5 box",
    ),
    "negative source position": (_edited(source_xy=np.full((3, 2), -5, np.int32)), "source_xy: expected non-negative"),
    "source index out of range": (
        _edited(source_index=np.array([0, 0, 3], np.int32)),
        "source_index: meta.sources has 1 entries, got indices from 0 to 3",
    ),
    "meta not JSON": (_edited(meta=_meta("{not json")), "meta is not valid JSON"),
    "meta a list": (_edited(meta=_meta([1, 2, 3])), "meta must be a JSON object, got a JSON list"),
    "meta bytes": (_edited(meta=np.array(b"{}")), "array 'meta' has dtype"),
    "meta a number array": (_edited(meta=np.zeros(3)), "array 'meta' has dtype float64"),
    "meta deeply nested": (_edited(meta=_meta("[" * 100_000)), "meta is not valid JSON"),
    "not murk's format": (_edited(meta=_meta({**_META, "format": "other"})), "not a murk particle bank"),
    "other version": (_edited(meta=_meta({**_META, "version": 9})), "particle bank version 9 is not supported"),
    "sources not a list": (_edited(meta=_meta({**_META, "sources": {"a": 1}})), "meta.sources must be a JSON list"),
}


@pytest.mark.parametrize("case", list(BAD_BANKS))
def test_load_bank_refuses_each_bad_bank_naming_the_file(tmp_path: Path, case: str) -> None:
    write, problem = BAD_BANKS[case]
    path = write(tmp_path / "bad bank.npz")
    with pytest.raises(InputFileError, match=problem) as info:
        load_bank(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message


@pytest.mark.parametrize("case", list(BAD_BANKS))
def test_snow_info_on_a_bad_bank_is_a_one_line_usage_error(tmp_path: Path, case: str) -> None:
    write, problem = BAD_BANKS[case]
    path = write(tmp_path / "bad.npz")
    r = runner.invoke(app, ["snow", "info", str(path)])
    assert r.exit_code == 2, r.output
    assert isinstance(r.exception, SystemExit)  # a clean exit, not an escaped exception
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: ")
    assert re.search(problem, lines[0]), lines[0]
    assert "Traceback" not in r.output


def test_the_checks_pass_real_banks_and_normalise_dtypes(tmp_path: Path) -> None:
    assert len(load_bank(default_snow_bank())) == 17888
    assert len(load_bank(small_snow_bank())) == 85
    # a bank with wider (still valid) dtypes loads and comes back in the canonical dtypes, equal in value
    _edited(offsets=_OFF.astype(">u8"), pixel_yx=_YX.astype(np.float64), bbox_hw=_GOOD["bbox_hw"].astype(np.int64))(
        tmp_path / "wide.npz"
    )
    wide, reference = load_bank(tmp_path / "wide.npz"), load_bank(save_bank(make_bank(), tmp_path / "ref.npz"))
    for name, dtype in (("offsets", np.int64), ("pixel_yx", np.float32), ("bbox_hw", np.int32)):
        assert getattr(wide, name).dtype == dtype
        np.testing.assert_array_equal(getattr(wide, name), getattr(reference, name))
    assert bank_to_bytes(wide) == bank_to_bytes(reference)


def test_the_pixel_limit_applies_to_banks(tmp_path: Path) -> None:
    path = save_bank(make_bank(), tmp_path / "b.npz")  # 35 particle pixels
    r = runner.invoke(app, ["--max-pixels", "34", "snow", "info", str(path)])
    assert r.exit_code == 2
    assert f"{path}: the particle bank declares 35 particle pixels, over the limit of 34" in r.output
    assert runner.invoke(app, ["--max-pixels", "35", "snow", "info", str(path)]).exit_code == 0


def test_a_huge_header_is_refused_without_a_traceback_in_a_real_process(tmp_path: Path) -> None:
    write, _ = BAD_BANKS["2^31 elements declared"]
    path = write(tmp_path / "huge.npz")
    assert path.stat().st_size < 10_000  # a header, not real data
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    env.pop("MURK_DEBUG", None)
    proc = subprocess.run(
        [sys.executable, "-m", "murk", "snow", "info", str(path)], capture_output=True, text=True, env=env, timeout=120
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.strip() == (
        f"error: {path}: corrupt particle bank: the header of array 'offsets' declares 2,147,483,648 elements "
        "(17,179,869,184 bytes) but the file holds 64 bytes for it"
    )


@pytest.mark.parametrize("case", ["truncated file", "offsets not monotone", "NaN coordinates", "meta a list"])
def test_synth_with_a_bad_snow_bank_fails_before_writing_anything(tmp_path: Path, case: str) -> None:
    write, problem = BAD_BANKS[case]
    bank, out = write(tmp_path / "bad.npz"), tmp_path / "out"
    args = ["synth", str(sample_rgbd_dir()), str(out), "--variants", "1", "--size", "32x24", "--snow-bank", str(bank)]
    r = runner.invoke(app, [*args, "--stages", "basic,marine_snow"])
    assert r.exit_code == 2 and isinstance(r.exception, SystemExit), r.output
    lines = r.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {bank}: ")
    assert re.search(problem, lines[0]) and not out.exists()


# ----------------------------------------------------------------------------------------------------------
# snow extract: empty and partly unreadable inputs


def _dots_png(path: Path) -> Path:
    img = np.full((64, 96, 3), 20, np.uint8)
    img[10:14, 20:24] = 230
    img[40:44, 60:64] = 230
    cv2.imwrite(str(path), img)
    return path


EXTRACT = ["--open-px", "0", "--close-px", "0", "--no-preview"]


def test_extract_from_an_empty_folder_names_the_folder(tmp_path: Path) -> None:
    empty = tmp_path / "footage"
    empty.mkdir()
    r = runner.invoke(app, ["snow", "extract", str(empty), "--out", str(tmp_path / "b.npz"), *EXTRACT])
    assert r.exit_code == 2, r.output
    assert r.output.strip() == (
        f"error: {empty}: folder holds no images (no image or video frame left to extract particles from)"
    )
    assert not (tmp_path / "b.npz").exists()


def test_extract_skips_corrupt_and_unreadable_images_and_writes_the_bank(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    folder = tmp_path / "footage"
    folder.mkdir()
    good = [_dots_png(folder / "a_good.png"), _dots_png(folder / "d_good.png")]
    whole = good[0].read_bytes()
    (folder / "b_truncated.png").write_bytes(whole[: len(whole) // 2])
    (folder / "c_empty.jpg").write_bytes(b"")
    (folder / "e_locked.png").write_bytes(whole)

    import murk.io.images as images

    real = images.read_image

    def read_image(path: Any) -> Any:  # an unreadable file (permissions, I/O error): OSError, not ValueError
        if Path(path).name == "e_locked.png":
            raise PermissionError(13, "Permission denied", str(path))
        return real(path)

    monkeypatch.setattr(images, "read_image", read_image)
    bank = tmp_path / "bank.npz"
    r = runner.invoke(app, ["snow", "extract", str(folder), "--out", str(bank), *EXTRACT])
    assert r.exit_code == 1, r.output
    b = load_bank(bank)
    assert [s["path"] for s in b.meta["sources"]] == [str(p) for p in good] and len(b) == 4
    errors = read_jsonl(tmp_path / "bank_errors.jsonl")
    assert [e["input"] for e in errors] == [str(folder / n) for n in ("b_truncated.png", "c_empty.jpg", "e_locked.png")]
    assert (
        errors[0]["error"] == f"{folder / 'b_truncated.png'}: cannot decode image (unsupported format or corrupt file)"
    )
    assert (
        errors[2]["error"].startswith(f"{folder / 'e_locked.png'}: cannot read image (")
        and "denied" in errors[2]["error"]
    )
    assert "3 failed (see" in r.output and "Traceback" not in r.output
    # a clean rerun (the bad files gone) removes the stale errors file
    for name in ("b_truncated.png", "c_empty.jpg", "e_locked.png"):
        (folder / name).unlink()
    r = runner.invoke(app, ["snow", "extract", str(folder), "--out", str(bank), *EXTRACT])
    assert r.exit_code == 0, r.output
    assert not (tmp_path / "bank_errors.jsonl").exists()


def test_extract_with_only_unreadable_inputs_lists_them(tmp_path: Path) -> None:
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not a png")
    r = runner.invoke(app, ["snow", "extract", str(bad), str(tmp_path / "gone"), "--out", str(tmp_path / "b.npz")])
    assert r.exit_code == 2
    assert r.output.strip() == (
        f"error: {bad}: cannot decode image (unsupported format or corrupt file); {tmp_path / 'gone'}: not found "
        "(no image or video frame left to extract particles from)"
    )


def test_extract_names_the_bank_it_cannot_write(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    out = tmp_path / "file" / "bank.npz"
    r = runner.invoke(app, ["snow", "extract", str(_dots_png(tmp_path / "a.png")), "--out", str(out), *EXTRACT])
    assert r.exit_code == 2
    assert (
        r.output.strip() == f"error: {tmp_path / 'file'}: cannot create the output folder: a file of this name exists"
    )
