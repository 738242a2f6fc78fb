"""Particle banks: marine-snow particles packed for vectorised compositing, stored as one ``.npz`` file.

File format (version 1), a NumPy ``.npz`` archive readable with ``numpy.load(path, allow_pickle=False)``:

==================  =============  ==================================================================
array               dtype, shape   meaning
==================  =============  ==================================================================
``meta``            str, ()        JSON: ``format`` ("murk-particle-bank"), ``version`` (1), ``bank_id``,
                                   ``sources`` (path, width, height, frame, particles per source),
                                   ``extract`` (extraction settings), ``murk_version``
``offsets``         int64, (n+1,)  particle ``i`` owns pixels ``offsets[i]:offsets[i+1]``
``pixel_yx``        float32, (P,2) pixel centre relative to the particle's centroid (rows, cols)
``pixel_rgb``       uint8, (P, 3)  original colour of each mask pixel (M_c of Eq. 7)
``source_index``    int32, (n,)    index into ``meta.sources``
``source_xy``       int32, (n, 2)  top-left of the particle's bounding box in its source frame
``bbox_hw``         int32, (n, 2)  bounding-box height and width
==================  =============  ==================================================================

Only mask pixels are stored (B = 1), so the bank holds exactly what Eqs. (7)-(8) use. ``bank_id`` is the
first 16 hex digits of the SHA-256 of the particle arrays: two banks with the same particles have the same id.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import tokenize
import zipfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from murk._version import __version__
from murk.errors import InputFileError, OutputError
from murk.io.atomic import write_bytes_atomic
from murk.io.jobs import ErrorRecord
from murk.snow.extract import Particle

BANK_FORMAT = "murk-particle-bank"
BANK_VERSION = 1


@dataclass(frozen=True)
class ParticleBank:
    """Packed particles (see the module docstring for the arrays) plus metadata."""

    offsets: np.ndarray
    pixel_yx: np.ndarray
    pixel_rgb: np.ndarray
    source_index: np.ndarray
    source_xy: np.ndarray
    bbox_hw: np.ndarray
    meta: dict[str, Any] = field(default_factory=dict)

    def __len__(self) -> int:
        return int(len(self.offsets) - 1)

    @property
    def areas_px(self) -> np.ndarray:
        """Pixel count of each particle."""
        return np.diff(self.offsets)

    @property
    def bank_id(self) -> str:
        return str(self.meta.get("bank_id", ""))

    def sizes_px(self) -> np.ndarray:
        """Linear size of each particle, the larger bounding-box side, pixels."""
        return self.bbox_hw.max(axis=1)


def content_id(arrays: Sequence[np.ndarray]) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()[:16]


def build_bank(
    particles_per_source: Sequence[tuple[dict[str, Any], Sequence[Particle]]], *, extract: dict[str, Any] | None = None
) -> ParticleBank:
    """Pack particles into a bank. ``particles_per_source`` pairs a source description (path, width, height,
    frame) with the particles cut from it."""
    offsets = [0]
    yx: list[np.ndarray] = []
    rgb: list[np.ndarray] = []
    src_idx: list[int] = []
    src_xy: list[tuple[int, int]] = []
    bbox: list[tuple[int, int]] = []
    sources = []
    for si, (desc, particles) in enumerate(particles_per_source):
        sources.append({**desc, "particles": len(particles)})
        for p in particles:
            rows, cols = np.nonzero(p.mask)
            cy, cx = rows.mean(), cols.mean()
            yx.append(np.stack([rows - cy, cols - cx], axis=1).astype(np.float32))
            rgb.append(p.rgb[rows, cols])
            offsets.append(offsets[-1] + len(rows))
            src_idx.append(si)
            src_xy.append((p.x, p.y))
            bbox.append(p.mask.shape)
    arrays = {
        "offsets": np.asarray(offsets, np.int64),
        "pixel_yx": np.concatenate(yx) if yx else np.zeros((0, 2), np.float32),
        "pixel_rgb": np.concatenate(rgb).astype(np.uint8) if rgb else np.zeros((0, 3), np.uint8),
        "source_index": np.asarray(src_idx, np.int32),
        "source_xy": np.asarray(src_xy, np.int32).reshape(-1, 2),
        "bbox_hw": np.asarray(bbox, np.int32).reshape(-1, 2),
    }
    meta = {
        "format": BANK_FORMAT,
        "version": BANK_VERSION,
        "bank_id": content_id([arrays["offsets"], arrays["pixel_yx"], arrays["pixel_rgb"]]),
        "sources": sources,
        "extract": extract or {},
        "murk_version": __version__,
    }
    return ParticleBank(meta=meta, **arrays)


def bank_to_bytes(bank: ParticleBank) -> bytes:
    """Serialise a bank to the ``.npz`` format (no pickle)."""
    buf = io.BytesIO()
    np.savez_compressed(
        buf,
        meta=np.array(json.dumps(bank.meta, sort_keys=True)),
        offsets=bank.offsets,
        pixel_yx=bank.pixel_yx,
        pixel_rgb=bank.pixel_rgb,
        source_index=bank.source_index,
        source_xy=bank.source_xy,
        bbox_hw=bank.bbox_hw,
    )
    return buf.getvalue()


def save_bank(bank: ParticleBank, path: str | Path) -> Path:
    """Write ``bank`` atomically to ``path`` (``.npz``).

    Raises:
        InputFileError: the file cannot be written (the message names it).
    """
    path = Path(path)
    try:
        write_bytes_atomic(path, bank_to_bytes(bank))
    except OutputError:  # no space left on device: already one line naming the file
        raise
    except OSError as exc:
        raise InputFileError(path, f"cannot write the particle bank ({exc})") from None
    return path


# ---------------------------------------------------------------------------------------------------------
# loading: everything is validated before it is used (issue 13)

MAX_PARTICLE_SIDE_PX = 4096
"""Largest bounding-box side of a particle, pixels: a larger 'particle' is not marine snow, and it would make
the compositing canvas huge."""
MAX_META_BYTES = 16 * 2**20
"""Largest ``meta`` JSON string accepted, bytes (as stored: 4 bytes per character)."""

_CANONICAL: dict[str, np.dtype] = {
    "offsets": np.dtype(np.int64),
    "pixel_yx": np.dtype(np.float32),
    "pixel_rgb": np.dtype(np.uint8),
    "source_index": np.dtype(np.int32),
    "source_xy": np.dtype(np.int32),
    "bbox_hw": np.dtype(np.int32),
}
# name: (accepted dtype kinds, ndim, size of the last axis or None, what the error message calls it)
_LAYOUT: dict[str, tuple[str, int, int | None, str]] = {
    "meta": ("U", 0, None, "a JSON string"),
    "offsets": ("iu", 1, None, "integers, shape (n+1,)"),
    "pixel_yx": ("f", 2, 2, "floats, shape (P, 2)"),
    "pixel_rgb": ("u", 2, 3, "uint8, shape (P, 3)"),
    "source_index": ("iu", 1, None, "integers, shape (n,)"),
    "source_xy": ("iu", 2, 2, "integers, shape (n, 2)"),
    "bbox_hw": ("iu", 2, 2, "integers, shape (n, 2)"),
}
# What a damaged zip member or archive raises while being read.
_ZIP_ERRORS = (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, NotImplementedError, RuntimeError)


def _why(exc: BaseException) -> str:
    """An exception's message on one short line (the error message must stay one line)."""
    lines = str(exc).strip().splitlines()
    text = lines[0] if lines else type(exc).__name__
    return text if len(text) <= 160 else text[:157] + "..."


@dataclass(frozen=True)
class _Header:
    shape: tuple[int, ...]
    dtype: np.dtype
    info: zipfile.ZipInfo


def _read_header(path: Path, zf: zipfile.ZipFile, name: str, info: zipfile.ZipInfo) -> _Header:
    """Parse the ``.npy`` header of one member without reading its data, and check it against ``_LAYOUT``."""
    kinds, ndim, last, expected = _LAYOUT[name]
    try:
        with zf.open(info) as f:
            head = io.BytesIO(f.read(min(info.file_size, 65_536 + 16)))
    except _ZIP_ERRORS as exc:
        raise InputFileError(path, f"corrupt particle bank: array {name!r} cannot be read ({_why(exc)})") from None
    try:
        version = np.lib.format.read_magic(head)
        if version == (1, 0):
            shape, _, dtype = np.lib.format.read_array_header_1_0(head)
        elif version == (2, 0):
            shape, _, dtype = np.lib.format.read_array_header_2_0(head)
        else:
            raise ValueError(f".npy format version {version[0]}.{version[1]} is not supported")
    except (ValueError, EOFError, SyntaxError, TypeError, tokenize.TokenError, RecursionError) as exc:
        raise InputFileError(
            path, f"corrupt particle bank: array {name!r} has a bad .npy header ({_why(exc)})"
        ) from None
    if any(s < 0 for s in shape):
        raise InputFileError(path, f"corrupt particle bank: array {name!r} declares a negative shape {shape}")
    if dtype.kind not in kinds or dtype.fields is not None or dtype.subdtype is not None or dtype.hasobject:
        raise InputFileError(path, f"array {name!r} has dtype {dtype}; expected {expected}")
    if name == "pixel_rgb" and dtype.itemsize != 1:
        raise InputFileError(path, f"array {name!r} has dtype {dtype}; expected {expected}")
    if len(shape) != ndim or (last is not None and shape[-1] != last):
        raise InputFileError(path, f"array {name!r} has shape {shape}; expected {expected}")
    payload = info.file_size - head.tell()
    declared = math.prod(shape) * dtype.itemsize
    if declared != payload:
        raise InputFileError(
            path,
            f"corrupt particle bank: the header of array {name!r} declares {math.prod(shape):,} elements "
            f"({declared:,} bytes) but the file holds {max(payload, 0):,} bytes for it",
        )
    return _Header(tuple(int(s) for s in shape), dtype, info)


def _check_sizes(path: Path, h: dict[str, _Header]) -> None:
    """Counts from the headers agree with each other and stay within the limits (before any data is read)."""
    from murk.io.images import max_pixels

    if h["meta"].dtype.itemsize > MAX_META_BYTES:
        raise InputFileError(path, f"meta is {h['meta'].dtype.itemsize:,} bytes, over the limit of {MAX_META_BYTES:,}")
    if h["offsets"].shape[0] < 1:
        raise InputFileError(path, "corrupt particle bank: offsets is empty (expected n+1 values)")
    n = h["offsets"].shape[0] - 1
    if n == 0:
        raise InputFileError(path, "the particle bank holds no particles")
    n_px = h["pixel_yx"].shape[0]
    if h["pixel_rgb"].shape[0] != n_px:
        raise InputFileError(
            path, f"corrupt particle bank: pixel_yx holds {n_px:,} pixels, pixel_rgb {h['pixel_rgb'].shape[0]:,}"
        )
    limit = max_pixels()
    if n_px > limit:
        raise InputFileError(
            path,
            f"the particle bank declares {n_px:,} particle pixels, over the limit of {limit:,} "
            "(raise it with 'murk --max-pixels N' or MURK_MAX_PIXELS)",
        )
    if n > n_px:
        raise InputFileError(path, f"corrupt particle bank: {n:,} particles but only {n_px:,} pixels")
    for name in ("source_index", "source_xy", "bbox_hw"):
        if h[name].shape[0] != n:
            raise InputFileError(
                path, f"corrupt particle bank: {name} has {h[name].shape[0]:,} rows for {n:,} particles"
            )


def _read_arrays(path: Path, zf: zipfile.ZipFile, headers: dict[str, _Header]) -> dict[str, np.ndarray]:
    out = {}
    for name, h in headers.items():
        try:
            with zf.open(h.info) as f:
                a = np.lib.format.read_array(f, allow_pickle=False)
        except (*_ZIP_ERRORS, MemoryError) as exc:
            raise InputFileError(path, f"corrupt particle bank: array {name!r} cannot be read ({_why(exc)})") from None
        if a.shape != h.shape or a.dtype != h.dtype:  # pragma: no cover - read_array parses the same header
            raise InputFileError(path, f"corrupt particle bank: array {name!r} changed while being read")
        out[name] = a
    return out


def _parse_meta(path: Path, raw: np.ndarray) -> dict[str, Any]:
    try:
        meta = json.loads(str(raw[()]))
    except (ValueError, RecursionError) as exc:
        raise InputFileError(path, f"meta is not valid JSON ({_why(exc)})") from None
    if not isinstance(meta, dict):
        raise InputFileError(path, f"meta must be a JSON object, got a JSON {type(meta).__name__}")
    if meta.get("format") != BANK_FORMAT:
        raise InputFileError(path, f"not a murk particle bank (format {meta.get('format')!r})")
    if meta.get("version") != BANK_VERSION:
        raise InputFileError(path, f"particle bank version {meta.get('version')!r} is not supported (expected 1)")
    for key, kind in (("sources", list), ("extract", dict), ("bank_id", str)):
        if key in meta and not isinstance(meta[key], kind):
            raise InputFileError(path, f"meta.{key} must be a JSON {kind.__name__}, got {type(meta[key]).__name__}")
    if any(not isinstance(s, dict) for s in meta.get("sources", [])):
        raise InputFileError(path, "meta.sources must be a list of JSON objects")
    return meta


def _int_range(a: np.ndarray) -> tuple[int, int]:
    return (int(a.min()), int(a.max())) if a.size else (0, 0)


def _check_values(path: Path, a: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
    """Offsets, coordinates, boxes and indices are consistent, in range and finite."""
    n_px = len(a["pixel_yx"])
    lo, hi = _int_range(a["offsets"])
    if lo < 0:
        raise InputFileError(path, f"corrupt particle bank: offsets holds negative values (min {lo})")
    if hi > n_px:
        raise InputFileError(
            path, f"corrupt particle bank: offsets point past the pixel arrays (max {hi:,}, {n_px:,} pixels)"
        )
    off = a["offsets"].astype(np.int64)
    if off[0] != 0:
        raise InputFileError(path, f"corrupt particle bank: offsets must start at 0, got {off[0]}")
    steps = np.diff(off)
    if (steps <= 0).any():
        i = int(np.argmax(steps <= 0))
        raise InputFileError(
            path,
            f"corrupt particle bank: offsets must increase strictly (particle {i}: {off[i]} -> {off[i + 1]})",
        )
    if off[-1] != n_px:
        raise InputFileError(
            path, f"corrupt particle bank: offsets end at {off[-1]:,} but the pixel arrays hold {n_px:,} pixels"
        )
    bad = int(np.count_nonzero(~np.isfinite(a["pixel_yx"])))
    if bad:
        raise InputFileError(path, f"corrupt particle bank: pixel_yx holds {bad:,} NaN or infinite coordinates")
    lo, hi = _int_range(a["bbox_hw"])
    if lo < 1 or hi > MAX_PARTICLE_SIDE_PX:
        raise InputFileError(path, f"bbox_hw: expected particle sides of 1-{MAX_PARTICLE_SIDE_PX} px, got {lo}-{hi}")
    box = a["bbox_hw"].astype(np.int64)
    if (steps > box[:, 0] * box[:, 1]).any():
        i = int(np.argmax(steps > box[:, 0] * box[:, 1]))
        raise InputFileError(
            path, f"corrupt particle bank: particle {i} has {steps[i]} pixels in a {box[i, 0]}x{box[i, 1]} box"
        )
    reach = np.maximum.reduceat(np.abs(a["pixel_yx"]), off[:-1], axis=0)
    outside = (reach > box).any(axis=1)
    if outside.any():
        i = int(np.argmax(outside))
        raise InputFileError(
            path, f"corrupt particle bank: particle {i} has pixels outside its {box[i, 0]}x{box[i, 1]} bounding box"
        )
    lo, hi = _int_range(a["source_xy"])
    if lo < 0 or hi > np.iinfo(np.int32).max:
        raise InputFileError(path, f"source_xy: expected non-negative int32 positions, got values from {lo} to {hi}")
    lo, hi = _int_range(a["source_index"])
    n_src = len(meta.get("sources", []))
    if lo < 0 or ("sources" in meta and hi >= n_src) or hi > np.iinfo(np.int32).max:
        raise InputFileError(path, f"source_index: meta.sources has {n_src} entries, got indices from {lo} to {hi}")


def load_bank(path: str | Path) -> ParticleBank:
    """Load a bank written by :func:`save_bank` (never unpickles), validating all of it first.

    Checked in this order, so nothing is used before it is known to be sound: the file opens as a zip archive;
    every array is present and its ``.npy`` header declares the documented dtype kind and shape, with exactly
    as many elements as its member holds; the counts agree across arrays and stay within
    :func:`murk.io.images.max_pixels` (all from the headers, before any data is read); ``meta`` is a JSON
    object naming this format and version; offsets start at 0, increase strictly and end at the pixel count;
    coordinates are finite and inside each particle's bounding box (sides 1 to :data:`MAX_PARTICLE_SIDE_PX`);
    positions and source indices are in range. Arrays come back in the canonical dtypes of the module
    docstring.

    ``builtin:snow`` (the default bank: ``builtin:snow-real`` relit), ``builtin:snow-real`` (the bank cut from
    real ROV and reef footage) and ``builtin:snow-small`` (the default before 2026-12-03) name the banks shipped
    with murk.

    Raises:
        InputFileError: the message is one line, ``"PATH: problem"``.
    """
    if str(path).startswith("builtin:"):
        from murk.data import resolve_builtin

        path = resolve_builtin(str(path))
    path = Path(path)
    if not path.exists():
        raise InputFileError(path, "particle bank not found")
    if not path.is_file():
        raise InputFileError(path, "not a file (expected a particle bank .npz)")
    if path.stat().st_size == 0:
        raise InputFileError(path, "empty file (0 bytes), not a particle bank")
    try:
        zf = zipfile.ZipFile(path)
    except _ZIP_ERRORS as exc:
        raise InputFileError(
            path, f"not a readable particle bank (not a .npz archive, or a truncated one: {_why(exc)})"
        ) from None
    with zf:
        members = {i.filename: i for i in zf.infolist()}
        missing = [k for k in _LAYOUT if f"{k}.npy" not in members]
        if missing:
            raise InputFileError(path, f"not a murk particle bank (missing {', '.join(missing)})")
        headers = {k: _read_header(path, zf, k, members[f"{k}.npy"]) for k in _LAYOUT}
        _check_sizes(path, headers)
        meta = _parse_meta(path, _read_arrays(path, zf, {"meta": headers.pop("meta")})["meta"])
        arrays = _read_arrays(path, zf, headers)
    _check_values(path, arrays, meta)
    canonical = {k: np.ascontiguousarray(v, dtype=_CANONICAL[k]) for k, v in arrays.items()}
    return ParticleBank(meta=meta, **canonical)


def subpixel_report(bank: ParticleBank, scale: tuple[float, float]) -> tuple[float, str]:
    """Fraction of particles smaller than one pixel even at the largest scale, and a sentence saying so."""
    sizes = bank.sizes_px().astype(np.float64)
    lo, hi = scale
    vanish = float(np.mean(sizes * hi < 1.0)) if len(sizes) else 0.0
    msg = (
        f"{100 * vanish:.0f} % of the {len(sizes)} particles are smaller than 1 px even at the largest scale "
        f"{hi:g} (particle size median {np.median(sizes):.1f} px, so {np.median(sizes) * lo:.2f}-"
        f"{np.median(sizes) * hi:.2f} px after the {lo:g}-{hi:g} resize); extract from higher-resolution frames "
        "or raise the scale range"
    )
    return vanish, msg


@dataclass(frozen=True)
class BankReport:
    """What :func:`extract_bank` found: the bank, frames that failed (error records, stage ``"extract"``), and
    warnings."""

    bank: ParticleBank
    problems: list[ErrorRecord]
    warnings: list[str]


def extract_bank(
    frames: Any,
    config: Any,
    *,
    scale: tuple[float, float] = (0.3, 0.6),
    on_frame: Any = None,
) -> BankReport:
    """Build a bank from ``frames``, an iterable of ``(source_description, uint8 RGB)``.

    A frame that cannot be used (an implausible mask, :class:`~murk.snow.extract.CoverageError`, or any other
    ``ValueError`` of the extraction) is reported in ``problems`` and skipped.
    ``on_frame(description, rgb, extraction_or_None)`` is called per frame (the CLI writes previews with it).

    Raises:
        ValueError: no particle at all was found; the message names the inputs.
    """
    from dataclasses import asdict

    from murk.snow.extract import extract_particles

    per_source: list[tuple[dict[str, Any], list[Particle]]] = []
    problems: list[ErrorRecord] = []
    names: list[str] = []
    for desc, rgb in frames:
        name = str(desc.get("path", "image")) + (f"#{desc['frame']}" if "frame" in desc else "")
        names.append(name)
        try:
            ex = extract_particles(rgb, config, source=name)
        except ValueError as exc:  # CoverageError or an unusable frame
            why = str(exc) if str(exc).startswith(name) else f"{name}: {exc}"
            problems.append(ErrorRecord(str(desc.get("path", "image")), "extract", why, frame=desc.get("frame")))
            if on_frame:
                on_frame(desc, rgb, None)
            continue
        if on_frame:
            on_frame(desc, rgb, ex)
        if ex.particles:
            per_source.append(({**desc, "width": rgb.shape[1], "height": rgb.shape[0]}, ex.particles))
    if not per_source:
        shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
        why = f"; {len(problems)} frame(s) rejected: {problems[0].error}" if problems else ""
        raise ValueError(
            f"no marine-snow particles found in {shown or 'the inputs'} (method {config.method}, threshold "
            f"{config.effective_threshold}, area {config.min_area_px}-{config.max_area_px} px){why}"
        )
    bank = build_bank(per_source, extract=asdict(config))
    warnings = []
    vanish, msg = subpixel_report(bank, scale)
    if vanish > 0.5:
        warnings.append(msg)
    return BankReport(bank, problems, warnings)
