"""Post-processing of Sec. 4.3: histogram equalisation, then Laplacian-of-Gaussian edge enhancement (Eq. 9).

Reference: S. Yun, G. Yang, J. Lee, C. Park, J. Choi, Y. Cho, "Robust Image Processing Techniques for
Construction Environment Monitoring Using Underwater Robots" (no DOI in the source text), Sec. 4.3, Eq. (9):
``I_out = I_HE - lambda * (LoG_sigma * I_HE)`` with sigma = 1.0 px and lambda = 0.3.

Everything works on float32 RGB in [0, 1]. The float pipeline is defined exactly, so that the OpenCV path
(:func:`post_process`, one image) and the torch twin (:func:`post_process_torch`, batches on any device)
agree to float rounding (the LoG sums are accumulated in a different order; see ``tests/enhance/test_post.py``).
This module holds Eq. (9) and the ``post`` method (:class:`PostRestorer`, :func:`make_post`); its two operations
have modules of their own, each with its numpy/OpenCV and torch twins:

1. Histogram equalisation ``I_HE`` (``he``: the luma, each channel, or CLAHE on the luma):
   :mod:`murk.enhance.equalize`.
2. The Laplacian of Gaussian, per channel, border reflect-101: :mod:`murk.enhance.log_filter`.
3. ``I_out = clip(I_HE - lambda * LoG(I_HE), 0, 1)`` (Eq. 9), here.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from murk._checks import check_positive, check_range, check_rgb
from murk.enhance.choices import HE_MODES, HEMode
from murk.enhance.declare import Checked
from murk.enhance.equalize import (
    CLAHE_CLIP,
    CLAHE_TILES,
    TableHook,
    apply_lut,
    checked_tables,
    clahe_grid,
    equalize,
    equalize_lut,
    equalize_torch,
    level_histogram,
    luma,
)
from murk.enhance.log_filter import SIGMA_PX, laplacian_of_gaussian_torch, log_kernels
from murk.enhance.restorer import Restored, RestoredTensor, Restorer, as_batch, device_type
from murk.enhance.temporal import FrameEMA

if TYPE_CHECKING:  # the torch twin imports it when called: post on the CPU runs without torch
    import torch

LAMBDA = 0.3
"""Edge-enhancement weight of the paper (Sec. 5.1)."""


@dataclass(frozen=True)
class PostParams:
    """Parameters of Eq. (9). ``clahe_tiles`` is an int (square grid) or (columns, rows)."""

    sigma_px: float = SIGMA_PX
    lam: float = LAMBDA
    he: HEMode = "y"
    clahe_clip: float = CLAHE_CLIP
    clahe_tiles: int | tuple[int, int] = CLAHE_TILES
    he_strength: float = 1.0
    """Share of the equalisation applied: ``I + s (I_HE - I)`` (1 = Eq. 9 as written)."""

    def __post_init__(self) -> None:
        check_range("he_strength", self.he_strength, 0.0, 1.0)
        check_positive("sigma_px", self.sigma_px)
        check_positive("lam", self.lam, allow_zero=True)
        if self.he not in HE_MODES:
            raise ValueError(f"he: expected one of {', '.join(HE_MODES)}, got {self.he!r}")
        check_positive("clahe_clip", self.clahe_clip)
        clahe_grid(self.clahe_tiles)

    def __call__(self, image: np.ndarray) -> np.ndarray:
        return post_process(image, **self._kwargs())

    def _kwargs(self) -> dict[str, Any]:
        """The fields as keyword arguments of :func:`post_process` and :func:`post_process_torch`."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


# ----------------------------------------------------------------------------------------------------------
# Eq. (9)
# ----------------------------------------------------------------------------------------------------------


def post_process(
    image: np.ndarray,
    *,
    sigma_px: float = SIGMA_PX,
    lam: float = LAMBDA,
    he: HEMode = "y",
    clahe_clip: float = CLAHE_CLIP,
    clahe_tiles: int | tuple[int, int] = CLAHE_TILES,
    tables: TableHook | None = None,
    he_strength: float = 1.0,
) -> np.ndarray:
    """Post-process one image: histogram equalisation, then LoG edge enhancement. Implements Eq. (9).

    Args:
        image: float RGB (H, W, 3) in [0, 1].
        sigma_px: LoG standard deviation in pixels (paper: 1.0).
        lam: edge-enhancement weight lambda >= 0 (paper: 0.3; 0 gives pure equalisation).
        he: equalisation mode, see :func:`equalize`.
        clahe_clip: CLAHE clip limit (``he="clahe"``).
        clahe_tiles: CLAHE grid (``he="clahe"``).
        tables: replaces the equalisation tables (``he="y"``/``"rgb"``; see :func:`equalize`).
        he_strength: share ``s`` of the equalisation, ``I_HE <- I + s (I_HE - I)`` (1, the paper's: Eq. 9 as
            written; murk's ``real`` preset uses 0.3).

    Returns:
        float32 (H, W, 3) in [0, 1].

    Raises:
        TypeError: ``image`` is not a float numpy array.
        ShapeError: ``image`` is not (H, W, 3).
        ValueError: a parameter is out of range.
    """
    params = PostParams(sigma_px, lam, he, clahe_clip, clahe_tiles, he_strength)
    i_he = equalize(image, params.he, clahe_clip=params.clahe_clip, clahe_tiles=params.clahe_tiles, tables=tables)
    if params.he_strength != 1.0:
        x = np.clip(np.asarray(image, np.float32), 0.0, 1.0)
        i_he = cv2.addWeighted(i_he, params.he_strength, x, 1.0 - params.he_strength, 0.0, dtype=cv2.CV_32F)
    if params.lam == 0.0:
        return i_he
    # Eq. (9): I_HE - lambda (LoG * I_HE), with -lambda folded into the second-derivative taps (one pass each
    # for the two separable terms and two adds; the same sum as the unscaled LoG to float rounding).
    g, g2 = log_kernels(params.sigma_px)
    g2 = g2 * np.float32(-params.lam)
    out = cv2.sepFilter2D(i_he, cv2.CV_32F, g2, g, borderType=cv2.BORDER_REFLECT_101)
    cv2.add(out, cv2.sepFilter2D(i_he, cv2.CV_32F, g, g2, borderType=cv2.BORDER_REFLECT_101), dst=out)
    cv2.add(out, i_he, dst=out)
    return np.clip(out, 0.0, 1.0, out=out)


POST_STRIP_ROWS = 64
"""Rows per strip of :func:`post_process_strips` (plus the LoG's radius above and below)."""


def post_process_strips(
    image: np.ndarray, params: PostParams, tables: TableHook | None = None, out: np.ndarray | None = None
) -> np.ndarray:
    """:func:`post_process` with ``he="y"`` in two passes over the frame: the luma and its histogram, then strip by
    strip (:data:`POST_STRIP_ROWS` rows and the LoG's radius around them, in the cache) the equalisation, the share
    ``he_strength``, the two LoG filters and the clip (every step the same OpenCV operation on the same values, so
    the output equals :func:`post_process`'s to float rounding; pinned by ``tests/enhance/test_post_strips.py``).
    At 1920x1080 a pass over a float32 frame leaves the cache; strips keep the cost per pixel of a 640x480 frame.

    Args:
        image: float32 RGB (H, W, 3).
        params: the parameters; ``params.he`` must be ``"y"``.
        tables: as :func:`post_process`'s.
        out: float32 (H, W, 3) to write into (a new array when None); may not be ``image``.

    Raises:
        ValueError: ``params.he`` is not ``"y"``.
    """
    if params.he != "y":
        raise ValueError(f"params.he: the strip path equalises the luma ('y'), got {params.he!r}")
    image = check_rgb("image", image)
    h = image.shape[0]
    rows = POST_STRIP_ROWS
    y = np.empty(image.shape[:2], np.float32)
    for r0 in range(0, h, rows):  # pass 1: the luma of the clipped frame, and its histogram
        y[r0 : r0 + rows] = luma(np.clip(image[r0 : r0 + rows], 0.0, 1.0))
    y255 = np.clip(y, 0.0, 1.0)
    y255 *= np.float32(255.0)
    luts = equalize_lut(level_histogram(y255))[None]
    if tables is not None:
        luts = checked_tables(tables(luts), luts.shape)
    lut = luts[0]
    g, g2 = log_kernels(params.sigma_px)
    g2 = g2 * np.float32(-params.lam)
    radius = (g.size - 1) // 2 if params.lam != 0.0 else 0
    s = params.he_strength
    result = np.empty(image.shape, np.float32) if out is None else out
    for r0 in range(0, h, rows):  # pass 2, strip by strip, with the LoG's radius of rows around each
        a0, a1 = max(0, r0 - radius), min(h, r0 + rows + radius)
        x = np.clip(image[a0:a1], 0.0, 1.0)
        y_he = apply_lut(y255[a0:a1], lut)
        y_he -= y[a0:a1]  # the luma shift, added to every channel (chroma kept)
        i_he = cv2.add(x, cv2.merge((y_he, y_he, y_he)))
        np.clip(i_he, 0.0, 1.0, out=i_he)
        if s != 1.0:
            i_he = cv2.addWeighted(i_he, s, x, 1.0 - s, 0.0, dtype=cv2.CV_32F)
        keep = slice(r0 - a0, r0 - a0 + min(rows, h - r0))
        if params.lam == 0.0:
            result[r0 : r0 + rows] = i_he[keep]
            continue
        res = cv2.sepFilter2D(i_he, cv2.CV_32F, g2, g, borderType=cv2.BORDER_REFLECT_101)  # Eq. (9)
        cv2.add(res, cv2.sepFilter2D(i_he, cv2.CV_32F, g, g2, borderType=cv2.BORDER_REFLECT_101), dst=res)
        cv2.add(res, i_he, dst=res)
        np.clip(res[keep], 0.0, 1.0, out=result[r0 : r0 + rows])
    return result


def post_process_torch(
    images: torch.Tensor,
    *,
    sigma_px: float = SIGMA_PX,
    lam: float = LAMBDA,
    he: HEMode = "y",
    clahe_clip: float = CLAHE_CLIP,
    clahe_tiles: int | tuple[int, int] = CLAHE_TILES,
    tables: TableHook | None = None,
    he_strength: float = 1.0,
) -> torch.Tensor:
    """Torch twin of :func:`post_process` on a batch (B, 3, H, W) in [0, 1], on the input's device.
    Implements Eq. (9)."""
    params = PostParams(sigma_px, lam, he, clahe_clip, clahe_tiles, he_strength)
    i_he = equalize_torch(
        images, params.he, clahe_clip=params.clahe_clip, clahe_tiles=params.clahe_tiles, tables=tables
    )
    if params.he_strength != 1.0:
        s = float(np.float32(params.he_strength))
        i_he = i_he * s + images.float().clamp(0.0, 1.0) * (1.0 - s)
    if params.lam == 0.0:
        return i_he
    return (i_he - float(np.float32(params.lam)) * laplacian_of_gaussian_torch(i_he, params.sigma_px)).clamp(
        0.0, 1.0
    )  # Eq. (9)


# ----------------------------------------------------------------------------------------------------------
# The "post" restorer
# ----------------------------------------------------------------------------------------------------------


class PostRestorer(Restorer):
    """Eq. (9) as a :class:`~murk.enhance.restorer.Restorer`: OpenCV per image on CPU, the torch twin in
    batches on CUDA (and always for :meth:`restore_tensor`). Returns no depth. On the CPU, :meth:`restore` does not
    import torch.

    With ``temporal`` > 0, frames restored inside :meth:`sequence` are equalised with their tables averaged over
    time (:class:`murk.enhance.temporal.FrameEMA`); images restored outside it are each equalised on their own.

    Raises:
        ValueError: ``temporal`` outside [0, 1), or set with ``he="clahe"``.
    """

    name = "post"

    def __init__(
        self, params: PostParams | None = None, device: str | torch.device = "cpu", temporal: float = 0.0
    ) -> None:
        self.params = params or PostParams()
        if not (isinstance(device, str) and device == "cpu"):  # "cpu" keeps the default, built when first read
            import torch

            self.device = torch.device(device)
        ema = FrameEMA(temporal)
        if ema.weight > 0 and self.params.he == "clahe":
            raise ValueError("temporal: applies to he 'y' and 'rgb' (CLAHE has a table per tile)")
        self.temporal_state = ema if ema.weight > 0 else None

    def restore(self, images: np.ndarray) -> Restored:
        batch = _check_numpy_batch(images)
        if device_type(self) != "cpu":
            return super().restore(batch)
        if self.params.he == "y":  # the strip path: the same output, the cost per pixel of a small frame
            out = np.empty(batch.shape, np.float32)
            for i, im in enumerate(batch):
                post_process_strips(im, self.params, self.temporal_hook(), out=out[i])
            return Restored(out)
        kw = self.params._kwargs()
        out = np.stack([post_process(im, **kw, tables=self.temporal_hook()) for im in batch])
        return Restored(out)

    def restore_tensor(self, images: torch.Tensor) -> RestoredTensor:
        return RestoredTensor(post_process_torch(images, **self.params._kwargs(), tables=self.temporal_hook()))


def make_post(o: Checked) -> PostRestorer:
    """Implementation of the ``post`` method (declared in :mod:`murk.enhance.methods`): histogram equalisation
    then LoG edge enhancement (see :func:`post_process`), with the settings of ``preset`` (:data:`POST_PRESETS`:
    ``real``, murk's default, or ``paper``, Eq. 9 exactly); any parameter given explicitly overrides the preset's.
    ``temporal`` averages the equalisation tables over the frames of a video (:mod:`murk.enhance.temporal`; 0 = per
    frame, the paper's)."""
    preset = o.preset
    if preset not in POST_PRESETS:
        raise ValueError(f"preset: expected one of {', '.join(POST_PRESETS)}, got {preset!r}")
    base = POST_PRESETS[preset]
    given = {k: o[k] for k in ("sigma_px", "lam", "he", "clahe_clip", "clahe_tiles", "he_strength")}
    params = dataclasses.replace(base, **{k: v for k, v in given.items() if v is not None})
    return PostRestorer(params, device=o.device, temporal=o.temporal)


def _check_numpy_batch(images: Any) -> np.ndarray:
    return as_batch(images).astype(np.float32, copy=False)  # the batch contract of every restorer (float)


POST_PRESETS: dict[str, PostParams] = {
    "paper": PostParams(),
    "real": PostParams(lam=0.1, he_strength=0.3),
}
"""``paper``: Eq. (9) exactly as the paper writes it (full luma equalisation, lambda 0.3). ``real`` (murk's
default): 30 % of the luma equalisation and lambda 0.1, the settings that do not undo a good restoration on
real paired photographs (docs/enhance.md, "post presets": full equalisation after a restorer lost 1.9 dB on
the development set)."""
