"""Depth maps at the I/O edge: file formats, units, validity masks and invalid-pixel handling.

Inside murk a depth map is float32 metres, shape (H, W). A pixel is *valid* when it is finite and > 0;
sensors mark holes with 0 (Kinect, RealSense, TUM, Redwood, KITTI), NaN or inf.

Supported encodings:

- uint16 PNG/TIFF: metres = value / ``depth_scale`` (1000 = millimetres, the default; 5000 for TUM RGB-D;
  256 for KITTI).
- ``.npy``: float metres (or integers taken as metres), 2-D.
- 8-bit images: *relative* depth (larger = farther), accepted only with ``relative=True``, mapped linearly to
  0.3-15 m (:data:`RELATIVE_NEAR_M`, :data:`RELATIVE_FAR_M`); only the normalised distance mode of the
  synthesis can use it meaningfully.
- NYU-v2 ``nyu_depth_v2_labeled.mat`` (HDF5; arrays stored transposed), see :func:`read_nyu_mat`.

Encodings of integer depth images (``encoding``):

- ``linear`` (default): metres = value / ``depth_scale``.
- ``sun``: SUN RGB-D's bit-rotated PNGs: metres = ((v >> 3) | (v << 13) & 0xFFFF) / 1000.
- ``kinect-disparity``: raw Kinect v1 disparity as in NYU-v2's raw dumps: metres = 351.3 / (1092.5 - raw),
  raw >= 2047 invalid. NYU's raw ``.pgm`` files store the samples little-endian although the PGM header
  implies big-endian, so PGM input is byte-swapped. Raw NYU depth is NOT registered to the colour image:
  use it for loader checks or with registered data only.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import cv2
import numpy as np

from murk.errors import InputFileError
from murk.io.atomic import write_bytes_atomic
from murk.io.images import check_declared_size, encode_image, encode_png, max_pixels, read_input_bytes
from murk.io.listing import describe_unusable

InvalidDepthMode = Literal["fill", "far", "fail"]
DepthEncoding = Literal["linear", "sun", "kinect-disparity"]
DEPTH_ENCODINGS: tuple[str, ...] = ("linear", "sun", "kinect-disparity")
RELATIVE_NEAR_M = 0.3
RELATIVE_FAR_M = 15.0


def read_depth(
    path: str | Path, *, depth_scale: float = 1000.0, relative: bool = False, encoding: DepthEncoding = "linear"
) -> np.ndarray:
    """Read a depth file as float32 metres, shape (H, W). Invalid pixels keep their raw value (0, NaN, inf).

    Args:
        path: a uint16 PNG/TIFF, an 8-bit image (with ``relative=True``) or a ``.npy`` file in metres.
        depth_scale: raw units per metre for integer images (1000 = millimetres).
        relative: accept 8-bit relative depth (larger = farther) and map it linearly to 0.3-15 m.
        encoding: how integer samples map to metres (see the module docstring).

    Raises:
        InputFileError: missing/undecodable file, more pixels than :func:`murk.io.images.max_pixels`
            (checked in the header, before decoding), wrong number of channels, 8-bit depth without
            ``relative=True``, or a ``.npy`` file refused by :func:`read_npy_depth`.
    """
    path = Path(path)
    why = describe_unusable(path)
    if why is not None:
        raise InputFileError(path, f"depth {why}" if why.startswith("file not found") else why)
    if not (np.isfinite(depth_scale) and depth_scale > 0):
        raise ValueError(f"depth_scale: expected a finite number > 0, got {depth_scale}")
    if encoding not in DEPTH_ENCODINGS:
        raise ValueError(f"depth_encoding: expected one of {', '.join(DEPTH_ENCODINGS)}, got {encoding!r}")
    if path.suffix.lower() == ".npy":
        return read_npy_depth(path)
    data = read_input_bytes(path, "depth file")
    check_declared_size(path, data)
    raw = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if raw is None:
        raise InputFileError(path, "cannot decode depth image (unsupported format or corrupt file)")
    if raw.ndim == 3:
        if raw.shape[2] >= 3 and not (
            np.array_equal(raw[:, :, 0], raw[:, :, 1]) and np.array_equal(raw[:, :, 0], raw[:, :, 2])
        ):
            raise InputFileError(
                path,
                f"depth must be single-channel, got {raw.shape[2]} different channels (a colour-mapped depth "
                "picture is not depth: give the raw 16-bit PNG or a .npy of depth values)",
            )
        raw = raw[:, :, 0]
    if relative:
        integer = np.issubdtype(raw.dtype, np.integer)
        peak = float(np.iinfo(raw.dtype).max) if integer else 1.0  # type: ignore[type-var]  # integer dtype here
        u = raw.astype(np.float32) / np.float32(peak)
        return (RELATIVE_NEAR_M + u * (RELATIVE_FAR_M - RELATIVE_NEAR_M)).astype(np.float32)
    if raw.dtype == np.uint8:
        raise InputFileError(
            path,
            "8-bit depth cannot be metric (expected a uint16 PNG in millimetres or a .npy in metres); 8-bit "
            "relative depth (larger = farther) is read by murk synth with --depth-relative",
        )
    if np.issubdtype(raw.dtype, np.floating):
        return raw.astype(np.float32)  # float TIFF/EXR: metres
    if encoding == "sun":
        v = raw.astype(np.uint32)
        return ((((v >> 3) | (v << 13)) & 0xFFFF).astype(np.float64) / 1000.0).astype(np.float32)
    if encoding == "kinect-disparity":
        r = raw.byteswap() if path.suffix.lower() == ".pgm" else raw
        r = r.astype(np.float64)
        with np.errstate(divide="ignore"):
            m = np.where(r < 2047, 351.3 / (1092.5 - r), 0.0)
        return np.where(m > 0, m, 0.0).astype(np.float32)
    return (raw.astype(np.float64) / depth_scale).astype(np.float32)


def read_npy_depth(path: str | Path) -> np.ndarray:
    """Read a ``.npy`` depth map (metres) as float32 (H, W), checking its header before reading any data.

    Accepted: integer or float samples, shape (H, W) or (H, W, 1), at most :func:`murk.io.images.max_pixels`
    elements. The data is read with a bounded read of exactly the declared size, so a header declaring a
    gigantic array is refused without allocating it.

    Raises:
        InputFileError: not a ``.npy`` file, an unsupported format version, too many elements, a shape other
            than (H, W) / (H, W, 1), an empty array, a dtype other than integer/float (object, complex,
            structured, strings, ...), or a file too short for the data its header declares.
    """
    path = Path(path)
    why = describe_unusable(path)
    if why is not None:
        raise InputFileError(path, why)
    try:
        f = open(path, "rb")  # closed by the with below; the open itself names the file on failure
    except OSError as exc:
        raise InputFileError(path, f"cannot read this depth file ({exc.strerror or exc})") from None
    with f:
        readers = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
        try:
            version = np.lib.format.read_magic(f)
            header = readers[version](f) if version in readers else None
        except ValueError as exc:  # bad magic or an unparsable header
            raise InputFileError(path, f"not a valid .npy file ({exc})") from None
        if header is None:
            raise InputFileError(path, f".npy format version {version[0]}.{version[1]} is not supported")
        shape, fortran, dtype = header
        what = f"{dtype} {shape}"
        if dtype.fields is not None or dtype.kind not in "iuf":
            raise InputFileError(path, f"expected a 2-D numeric array in metres (integer or float), got {what}")
        if not (len(shape) == 2 or (len(shape) == 3 and shape[2] == 1)):
            raise InputFileError(path, f"expected a 2-D numeric array in metres, got {what}")
        count = math.prod(shape)
        limit = max_pixels()
        if count > limit:
            raise InputFileError(
                path,
                f"declares {what} = {count:,} elements, over the pixel limit of {limit:,} "
                "(raise it with 'murk --max-pixels N' or MURK_MAX_PIXELS)",
            )
        if count == 0:
            raise InputFileError(path, f"empty depth array ({what})")
        n_bytes = count * dtype.itemsize
        have = os.fstat(f.fileno()).st_size - f.tell()
        if have < n_bytes:
            raise InputFileError(
                path, f"truncated: the header declares {what} = {n_bytes:,} bytes, the file holds {have:,}"
            )
        try:
            raw = np.fromfile(f, dtype=dtype, count=count)
        except MemoryError:
            raise InputFileError(path, f"not enough memory to read {what}") from None
    raw = raw.reshape(shape[:2], order="F" if fortran else "C")
    return raw.astype(np.float32)


def validity_mask(depth_m: np.ndarray) -> np.ndarray:
    """Boolean mask of valid depth pixels: finite and > 0."""
    return np.isfinite(depth_m) & (depth_m > 0)


def resolve_invalid(
    depth_m: np.ndarray, mode: InvalidDepthMode = "fill", *, source: str | Path = "depth"
) -> tuple[np.ndarray, np.ndarray]:
    """Replace invalid depth pixels and return ``(depth_m, valid_mask)``.

    Modes: ``fill`` copies the nearest valid pixel (by a 5x5 chamfer distance: at most 4 % farther than the
    Euclidean nearest); ``far`` sets invalid pixels to the farthest valid depth (holes read as open water);
    ``fail`` raises.

    Raises:
        InputFileError: no valid pixel at all, or invalid pixels with ``mode="fail"``.
    """
    if mode not in ("fill", "far", "fail"):
        raise ValueError(f"invalid_depth: expected 'fill', 'far' or 'fail', got {mode!r}")
    valid = validity_mask(depth_m)
    n_bad = int(valid.size - np.count_nonzero(valid))
    if n_bad == 0:
        return depth_m.astype(np.float32, copy=False), valid
    if n_bad == valid.size:
        raise InputFileError(source, "depth has no valid pixel (all 0, NaN, inf or negative)")
    if mode == "fail":
        raise InputFileError(
            source,
            f"{n_bad} invalid depth pixels ({100.0 * n_bad / valid.size:.1f} %: 0, NaN, inf or negative); "
            "use --invalid-depth fill or far to repair them",
        )
    out = depth_m.astype(np.float32, copy=True)
    if mode == "far":
        out[~valid] = out[valid].max()
        return out, valid
    return _copy_nearest_valid(out, valid), valid


def _copy_nearest_valid(depth_m: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Each invalid pixel takes the value of its nearest valid pixel by OpenCV's 5x5 chamfer distance transform
    (``cv2.distanceTransformWithLabels``, one label per valid pixel). The pixel it copies is at most 4 % farther
    than the Euclidean nearest (tests/io/test_depth.py against scipy's exact transform on random masks: at most
    3.6 %; on the Redwood sample 462 of 40,071 holes copy another pixel than the exact transform would, at most
    2.9 % farther). It is 6x faster than scipy's exact transform at 640x480 and spares every synthesis worker
    scipy's import (0.1 s per process)."""
    src = np.where(valid, 0, 255).astype(np.uint8)
    _, labels = cv2.distanceTransformWithLabels(src, cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL)
    value_of = np.empty(int(labels.max()) + 1, depth_m.dtype)
    value_of[labels[valid]] = depth_m[valid]  # a valid pixel's own label names it (any label order)
    return value_of[labels]


def write_depth_png(path: str | Path, depth_m: np.ndarray, *, depth_scale: float = 1000.0) -> Path:
    """Write metres as a uint16 PNG (value = round(metres * depth_scale), clipped to 0-65535; invalid -> 0)."""
    path = Path(path)
    d = np.where(validity_mask(depth_m), depth_m, 0.0).astype(np.float64) * depth_scale
    raw = np.clip(np.rint(d), 0, 65535).astype(np.uint16)
    data = encode_png(raw, path=path) if path.suffix.lower() == ".png" else encode_image(path, raw)
    write_bytes_atomic(path, data, fsync=False)
    return path


def nyu_mat_count(path: str | Path) -> int:
    """Number of frames in a NYU-v2 labeled ``.mat`` file."""
    with _open_nyu(path) as f:
        return int(f["images"].shape[0])


def read_nyu_mat(path: str | Path, index: int) -> tuple[np.ndarray, np.ndarray]:
    """Frame ``index`` of a NYU-v2 labeled ``.mat`` as (uint8 RGB (H, W, 3), float32 metres (H, W)).

    The file is HDF5 (MATLAB v7.3): ``images`` is (N, 3, W, H) uint8 and ``depths`` (N, W, H) float32
    metres, i.e. both transposed with respect to the usual (H, W) layout.
    """
    with _open_nyu(path) as f:
        n = f["images"].shape[0]
        if not 0 <= index < n:
            raise IndexError(f"index: expected 0 <= index < {n}, got {index}")
        rgb = np.ascontiguousarray(np.asarray(f["images"][index]).transpose(2, 1, 0))
        depth = np.ascontiguousarray(np.asarray(f["depths"][index]).T).astype(np.float32)
    return rgb, depth


def iter_nyu_mat(path: str | Path) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """Yield (index, rgb_uint8, depth_m) for every frame of a NYU-v2 labeled ``.mat`` file."""
    for i in range(nyu_mat_count(path)):
        rgb, depth = read_nyu_mat(path, i)
        yield i, rgb, depth


def _open_nyu(path: str | Path):
    import h5py

    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "file not found")
    try:
        f = h5py.File(path, "r")
    except OSError:
        raise InputFileError(path, "not an HDF5 (MATLAB v7.3) file; expected NYU-v2 nyu_depth_v2_labeled.mat") from None
    if "images" not in f or "depths" not in f:
        keys = sorted(f.keys())
        f.close()
        raise InputFileError(path, f"expected datasets 'images' and 'depths' (NYU-v2 labeled), found {keys}")
    return f
