"""murk's PNG settings (issue 29): the fast path at levels 1-3 is lossless and readable everywhere; the level keeps
its meaning (0 stores, 9 compresses hardest)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from PIL import Image

from murk.io.images import png_params, write_uint


@pytest.mark.parametrize("level", [0, 1, 3, 6, 9])
@pytest.mark.parametrize("shape_dtype", [((48, 64, 3), np.uint8), ((48, 64), np.uint16), ((31, 17, 3), np.uint16)])
def test_every_level_is_lossless_and_standard(tmp_path: Path, level: int, shape_dtype) -> None:  # type: ignore[no-untyped-def]
    shape, dtype = shape_dtype
    rng = np.random.default_rng(level)
    smooth = np.cumsum(rng.integers(0, 3, shape), axis=1) % np.iinfo(dtype).max
    image = smooth.astype(dtype)
    path = write_uint(tmp_path / "x.png", image, png_compression=level)
    back = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    expected = image[:, :, ::-1] if image.ndim == 3 else image
    assert back.dtype == dtype and np.array_equal(back, expected)
    with Image.open(path) as im:  # a second decoder reads it too
        assert im.size == (shape[1], shape[0])
    first = path.read_bytes()
    write_uint(tmp_path / "x.png", image, png_compression=level)
    assert path.read_bytes() == first  # deterministic bytes


def test_levels_keep_their_meaning(tmp_path: Path) -> None:
    rng = np.random.default_rng(0)
    image = (np.cumsum(rng.integers(0, 2, (120, 160, 3)), axis=1) % 255).astype(np.uint8)
    size = {lvl: len(cv2.imencode(".png", image, png_params(lvl))[1]) for lvl in (0, 3, 9)}
    assert size[0] > size[3] >= size[9] * 0.9 and size[0] >= image.size  # 0 stores; 3 and 9 compress
    assert cv2.IMWRITE_PNG_STRATEGY in png_params(3) and cv2.IMWRITE_PNG_STRATEGY not in png_params(9)
    for bad in (-1, 10, 2.5, True):
        with pytest.raises(ValueError, match="png_compression: expected an integer 0-9"):
            png_params(bad)  # type: ignore[arg-type]
