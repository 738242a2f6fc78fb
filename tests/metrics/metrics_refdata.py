"""Fixtures for the metric tests: the reference values of the original codes and the images they were run on.

``tests/data/metrics_reference.json`` is a copy of the project's ``spec/metrics_reference.json``: UIQM/UCIQE
values produced (2026-11-23) by running the ORIGINAL third-party code outside this repository, see its
``meta`` (repositories, commits, git blobs, exact calls, library versions):

- ``funie_py3``: rowantseng/FUnIE-GAN-PyTorch ``evaluation/uqim_utils.py`` @ d2c8064 (python-3 fork of
  xahidbuffon/FUnIE-GAN), ``getUIQM(rgb_uint8)``;
- ``jointid``: sparolab/Joint_ID ``core/evaluate/evaluate_utils/underwater/uiqm_utils.py`` @ 1e8e7a2,
  ``uiqm_compute(rgb_uint8)``;
- ``uciqe_m``: JOU-UIP/UCIQE ``UCIQE.m`` @ 02a3cf3 run unmodified in GNU Octave 7.3.0 (Lab from OpenCV's
  8-bit ``COLOR_RGB2LAB``).

Images: Pillow ``Image.open(p).convert("RGB")``; the ``640x480`` size is Pillow's bicubic resize, as the
reference run did. Real images ship in ``murk/data/underwater``; the synthetic ones are in
``tests/data/metric_edge_cases``.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any

import numpy as np

from murk.data import sample_underwater_dir

TESTS_DATA = Path(__file__).resolve().parents[1] / "data"
REFERENCE = json.loads((TESTS_DATA / "metrics_reference.json").read_text())
EDGE_DIR = TESTS_DATA / "metric_edge_cases"


def records(metric: str, implementation: str) -> list[dict[str, Any]]:
    """Reference records of one implementation, with a readable id."""
    return [r for r in REFERENCE["records"] if r["metric"] == metric and r["implementation"] == implementation]


def record_id(r: dict[str, Any]) -> str:
    return f"{Path(r['image']).name}-{r['size']}"


def image_path(name: str) -> Path:
    """Where a reference record's image lives in this repository."""
    if name.startswith("data/underwater/"):
        return sample_underwater_dir() / name[len("data/underwater/") :]
    if name.startswith("spec/metric_edge_cases/"):
        return EDGE_DIR / Path(name).name
    raise KeyError(name)


@functools.cache
def load_reference_image(name: str, size: str) -> np.ndarray:
    """The uint8 (H, W, 3) array the reference run scored (read-only, cached)."""
    from PIL import Image

    with Image.open(image_path(name)) as im:
        rgb = im.convert("RGB")
        if size == "640x480":
            rgb = rgb.resize((640, 480), Image.BICUBIC)
        arr = np.asarray(rgb).copy()
    arr.setflags(write=False)
    return arr


def edge_image(file_name: str) -> np.ndarray:
    return load_reference_image(f"spec/metric_edge_cases/{file_name}", "native")
