"""Data shipped inside the package (licences: ``DATA_LICENSES.md`` beside this file).

- ``underwater/``: 13 real underwater photographs (MIT-licensed sources) for demos, marine-snow extraction
  and metric checks.
- ``rgbd/``: 3 clean RGB-D pairs (``rgb/``, ``depth/`` as uint16 millimetre PNGs), the ``murk synth`` input
  layout.
- ``snow/``: marine-snow particle banks: ``real_footage_bank.npz`` (``builtin:snow-real``, cut from 20 frames of
  real ROV and reef footage), ``default_bank.npz`` (``builtin:snow``, the same particles relit) and
  ``small_bank.npz`` (``builtin:snow-small``, the default before 2026-12-03, cut from two shipped frames); sources
  and commands in ``DATA_LICENSES.md`` and docs/snow.md.
- ``models/jointid-small.pt``: the Joint-ID weights murk trained itself (variant ``small``, fp16 storage; model
  card: ``docs/models.md``), used by ``jointid`` when no checkpoint is given.
- ``models/lite.pt``: the ``lite`` real-time restorer's weights (model card: ``docs/models.md``), used by ``lite``
  when no checkpoint is given.
"""

from __future__ import annotations

from pathlib import Path

_HERE = Path(__file__).resolve().parent


def data_dir() -> Path:
    """Folder of the shipped data."""
    return _HERE


def sample_underwater_dir() -> Path:
    """Folder of the shipped real underwater images (subfolders per source)."""
    return _HERE / "underwater"


def sample_underwater_images() -> list[Path]:
    """Paths of the shipped real underwater images, sorted."""
    return sorted(p for p in sample_underwater_dir().rglob("*") if p.suffix.lower() in (".jpg", ".png"))


def sample_rgbd_dir() -> Path:
    """Folder with ``rgb/`` and ``depth/`` (millimetre PNG) clean RGB-D pairs: a ``murk synth`` input."""
    return _HERE / "rgbd"


SHIPPED_JOINTID = "jointid-small.pt"


def shipped_jointid_weights() -> Path:
    """Path of the Joint-ID weights shipped with murk (``small`` variant; model card ``docs/models.md``)."""
    return _HERE / "models" / SHIPPED_JOINTID


SHIPPED_LITE = "lite.pt"


def shipped_lite_weights() -> Path:
    """Path of the ``lite`` restorer weights shipped with murk (model card ``docs/models.md``); the file may be
    missing from an installation that predates them (the ``lite`` restorer then asks for ``--checkpoint``)."""
    return _HERE / "models" / SHIPPED_LITE


def shipped_water_weights() -> Path:
    """Path of the water estimator shipped with murk (``water.npz``, :mod:`murk.models.water`; model card
    ``docs/models/water.md``), read by the ``water`` method and ``murk water``."""
    return _HERE / "models" / "water.npz"


def shipped_detail_weights() -> Path:
    """Path of the detail network shipped with murk (``detail.npz``, :mod:`murk.models.detail`; model card
    ``docs/models/detail.md``), read by the ``detail`` method."""
    return _HERE / "models" / "detail.npz"


def default_snow_bank() -> Path:
    """Path of the default marine-snow particle bank shipped with murk (``builtin:snow``): the particles of
    :func:`real_footage_snow_bank` relit to a mean luma of 120-230 (``murk snow relight``; docs/snow.md)."""
    return _HERE / "snow" / "default_bank.npz"


def small_snow_bank() -> Path:
    """Path of the default bank before 2026-12-03 (``builtin:snow-small``): 85 small particles cut from two
    shipped frames (docs/snow.md); the configs of the models trained with it name it."""
    return _HERE / "snow" / "small_bank.npz"


def real_footage_snow_bank() -> Path:
    """Path of the larger bank cut from real ROV and reef footage (17,888 particles, 20 frames; docs/snow.md):
    ``builtin:snow-real``. Its particles are dim (cut from dark water): use it with
    ``marine_snow.particle_luma``."""
    return _HERE / "snow" / "real_footage_bank.npz"


BUILTIN_PREFIX = "builtin:"


def resolve_builtin(path: str) -> str:
    """Map ``builtin:underwater`` / ``builtin:rgbd`` / ``builtin:snow`` (``-real``, ``-small``) to the shipped data;
    other paths unchanged."""
    if not path.startswith(BUILTIN_PREFIX):
        return path
    name = path[len(BUILTIN_PREFIX) :].strip("/")
    targets = {
        "underwater": sample_underwater_dir(),
        "rgbd": sample_rgbd_dir(),
        "snow": default_snow_bank(),
        "snow-real": real_footage_snow_bank(),
        "snow-small": small_snow_bank(),
    }
    if name not in targets:
        raise ValueError(
            f"{path}: unknown built-in data; expected one of {', '.join(BUILTIN_PREFIX + k for k in targets)}"
        )
    return str(targets[name])
