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
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from murk._version import __version__
from murk.errors import InputFileError
from murk.io.atomic import write_bytes_atomic
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


def _content_id(arrays: Sequence[np.ndarray]) -> str:
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
        "bank_id": _content_id([arrays["offsets"], arrays["pixel_yx"], arrays["pixel_rgb"]]),
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
    """Write ``bank`` atomically to ``path`` (``.npz``)."""
    path = Path(path)
    write_bytes_atomic(path, bank_to_bytes(bank))
    return path


def load_bank(path: str | Path) -> ParticleBank:
    """Load a bank written by :func:`save_bank` (never unpickles).

    Raises:
        InputFileError: missing file, not a murk particle bank, an unsupported version, or a corrupt file.
    """
    path = Path(path)
    if not path.is_file():
        raise InputFileError(path, "particle bank not found")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (ValueError, OSError, KeyError) as exc:
        raise InputFileError(path, f"not a readable particle bank (.npz) ({exc})") from None
    need = {"meta", "offsets", "pixel_yx", "pixel_rgb", "source_index", "source_xy", "bbox_hw"}
    if not need <= set(data):
        raise InputFileError(path, f"not a murk particle bank (missing {', '.join(sorted(need - set(data)))})")
    meta = json.loads(str(data.pop("meta")))
    if meta.get("format") != BANK_FORMAT:
        raise InputFileError(path, f"not a murk particle bank (format {meta.get('format')!r})")
    if meta.get("version") != BANK_VERSION:
        raise InputFileError(path, f"particle bank version {meta.get('version')} is not supported (expected 1)")
    bank = ParticleBank(meta=meta, **data)
    if len(bank) == 0:
        raise InputFileError(path, "the particle bank holds no particles")
    if int(bank.offsets[-1]) != len(bank.pixel_yx) or len(bank.pixel_yx) != len(bank.pixel_rgb):
        raise InputFileError(path, "corrupt particle bank (offsets do not match the pixel arrays)")
    return bank


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
    """What :func:`extract_bank` found: the bank, frames that failed (with why), and warnings."""

    bank: ParticleBank
    problems: list[tuple[str, str]]
    warnings: list[str]


def extract_bank(
    frames: Any,
    config: Any,
    *,
    scale: tuple[float, float] = (0.3, 0.6),
    on_frame: Any = None,
) -> BankReport:
    """Build a bank from ``frames``, an iterable of ``(source_description, uint8 RGB)``.

    A frame whose mask is implausible (:class:`~murk.snow.extract.CoverageError`) is reported in
    ``problems`` and skipped. ``on_frame(description, rgb, extraction_or_None)`` is called per frame (the CLI
    writes previews with it).

    Raises:
        ValueError: no particle at all was found; the message names the inputs.
    """
    from dataclasses import asdict

    from murk.snow.extract import CoverageError, extract_particles

    per_source: list[tuple[dict[str, Any], list[Particle]]] = []
    problems: list[tuple[str, str]] = []
    names: list[str] = []
    for desc, rgb in frames:
        name = str(desc.get("path", "image")) + (f"#{desc['frame']}" if "frame" in desc else "")
        names.append(name)
        try:
            ex = extract_particles(rgb, config, source=name)
        except CoverageError as exc:
            problems.append((name, str(exc)))
            if on_frame:
                on_frame(desc, rgb, None)
            continue
        if on_frame:
            on_frame(desc, rgb, ex)
        if ex.particles:
            per_source.append(({**desc, "width": rgb.shape[1], "height": rgb.shape[0]}, ex.particles))
    if not per_source:
        shown = ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
        why = f"; {len(problems)} frame(s) rejected: {problems[0][1]}" if problems else ""
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
