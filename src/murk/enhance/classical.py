"""Classical restorers that a practitioner tries first: ``greyworld``, ``colorbalance``, ``clahe`` and ``udcp``; and
``desnow``, which takes marine snow out (:mod:`murk.snow.remove`; chain it with a restorer: ``lite+desnow``).

Every report should show the learned models beside them (``murk compare ... --method greyworld+clahe``).

- ``greyworld``: grey-world white balance (Buchsbaum, "A spatial processor model for object colour
  perception", J. Franklin Inst. 310(1), 1980, doi:10.1016/0016-0032(80)90058-7): each channel is scaled so
  that its mean equals the mean of the three channel means, ``out_c = clip(I_c * mean(m) / m_c, 0, 1)``.
  ``strength`` in [0, 1] blends the gains towards 1 (``g_c ** strength``).
- ``colorbalance``: the "simplest colour balance" of Limare, Lisani, Morel, Petro and Sbert (Image Processing
  On Line 1, 2011, doi:10.5201/ipol.2011.llmps-scb): each channel is stretched affinely so that its ``low`` %
  darkest pixels become 0 and its ``high`` % brightest become 1 (saturated), ``out_c = clip((I_c - q_c) /
  (Q_c - q_c), 0, 1)`` with ``q_c``, ``Q_c`` the channel's ``low`` and ``100 - high`` percentiles
  (:mod:`murk.restore_ops.balance`, which says why it fits water).
- ``clahe``: contrast-limited adaptive histogram equalisation (Zuiderveld, Graphics Gems IV, 1994) of the
  CIE L* channel of the 8-bit image (OpenCV's Lab conversion and CLAHE), a* and b* kept; ``clip`` (OpenCV's
  clip limit) and ``tiles`` (tiles per side) as options. The output is 8-bit.
- ``udcp``: the Underwater Dark Channel Prior (Drews, do Nascimento, Moraes, Botelho, Campos, "Transmission
  Estimation in Underwater Single Images", ICCV Workshops 2013, doi:10.1109/ICCVW.2013.113), a physics-based
  inversion of the image formation model ``I = J t + A (1 - t)``: the dark channel is taken over the green
  and blue channels only (red is absorbed too fast to carry the prior), ``A`` is the input colour at the
  brightest dark-channel pixel among the top ``0.1 %``, ``t = 1 - omega * dark_gb(I / A)`` over a
  ``patch`` x ``patch`` window, refined with the guided filter of He, Sun and Tang (IEEE TPAMI 35(6), 2013,
  doi:10.1109/TPAMI.2012.213) guided by the grey input, and ``J = (I - A) / max(t, t_min) + A``.

All five work per image on float32 RGB in [0, 1] (numpy, OpenCV) and return no depth.
"""

from __future__ import annotations

import cv2
import numpy as np

from murk._checks import check_positive, check_range
from murk.enhance.declare import Checked
from murk.enhance.restorer import Restored, Restorer, as_batch
from murk.restore_ops.affine_transfer import guided_filter
from murk.restore_ops.balance import color_balance
from murk.snow.remove import SnowRemoval, remove_snow


def _check(images: np.ndarray) -> np.ndarray:
    return as_batch(images).astype(np.float32, copy=False)  # the batch contract of every restorer


# ------------------------------------------------------------------------------------------------ grey world


def grey_world(image: np.ndarray, strength: float = 1.0) -> np.ndarray:
    """Grey-world white balance of float32 RGB ``image`` (H, W, 3): channel means made equal (module doc)."""
    m = image.reshape(-1, 3).astype(np.float64).mean(0)
    gains = (m.mean() / np.maximum(m, 1e-6)) ** float(strength)
    return np.clip(image * gains.astype(np.float32), 0.0, 1.0).astype(np.float32)


class GreyWorld(Restorer):
    """:func:`grey_world` per image."""

    name = "greyworld"

    def __init__(self, strength: float = 1.0) -> None:
        self.strength = check_range("strength", strength, 0.0, 1.0)

    def restore(self, images: np.ndarray) -> Restored:
        return Restored(np.stack([grey_world(im, self.strength) for im in _check(images)]))


def make_greyworld(o: Checked) -> GreyWorld:
    """Implementation of ``greyworld`` (declared in :mod:`murk.enhance.methods`)."""
    return GreyWorld(o.strength)


# ------------------------------------------------------------------------------------ simplest colour balance


class ColorBalance(Restorer):
    """:func:`color_balance` per image."""

    name = "colorbalance"

    def __init__(self, low: float = 1.0, high: float = 1.0) -> None:
        self.low = check_range("low", low, 0.0, 49.0)
        self.high = check_range("high", high, 0.0, 49.0)

    def restore(self, images: np.ndarray) -> Restored:
        return Restored(np.stack([color_balance(im, self.low, self.high) for im in _check(images)]))


def make_colorbalance(o: Checked) -> ColorBalance:
    """Implementation of ``colorbalance`` (declared in :mod:`murk.enhance.methods`)."""
    return ColorBalance(o.low, o.high)


# ----------------------------------------------------------------------------------------------------- CLAHE


def clahe_lab(image: np.ndarray, clip: float = 2.0, tiles: int = 8) -> np.ndarray:
    """CLAHE of the L* channel of float32 RGB ``image`` (8-bit Lab, a* and b* kept); float32 output."""
    u8 = np.rint(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8)
    lab = cv2.cvtColor(u8, cv2.COLOR_RGB2LAB)
    lab[..., 0] = cv2.createCLAHE(float(clip), (int(tiles), int(tiles))).apply(np.ascontiguousarray(lab[..., 0]))
    return cv2.cvtColor(lab, cv2.COLOR_LAB2RGB).astype(np.float32) * np.float32(1.0 / 255.0)


class Clahe(Restorer):
    """:func:`clahe_lab` per image."""

    name = "clahe"

    def __init__(self, clip: float = 2.0, tiles: int = 8) -> None:
        self.clip = check_positive("clip", clip)
        if isinstance(tiles, bool) or not isinstance(tiles, int) or not 1 <= tiles <= 64:
            raise ValueError(f"tiles: expected an int in [1, 64], got {tiles!r}")
        self.tiles = tiles

    def restore(self, images: np.ndarray) -> Restored:
        return Restored(np.stack([clahe_lab(im, self.clip, self.tiles) for im in _check(images)]))


def make_clahe(o: Checked) -> Clahe:
    """Implementation of ``clahe`` (declared in :mod:`murk.enhance.methods`)."""
    return Clahe(o.clip, o.tiles)


# ------------------------------------------------------------------------------------------------------ UDCP


def _min_filter(x: np.ndarray, patch: int) -> np.ndarray:
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (patch, patch))
    return cv2.erode(x, kernel, borderType=cv2.BORDER_REPLICATE)


def udcp(
    image: np.ndarray, patch: int = 15, omega: float = 0.95, t_min: float = 0.1, top: float = 0.001
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """UDCP restoration of float32 RGB ``image`` (module doc). Returns ``(restored, transmission, A)``."""
    img = np.ascontiguousarray(image, dtype=np.float32)
    dark = _min_filter(np.minimum(img[..., 1], img[..., 2]), patch)
    n = max(1, round(top * dark.size))
    idx = np.argpartition(dark.ravel(), -n)[-n:]
    flat = img.reshape(-1, 3)
    bright = idx[np.argmax(flat[idx].sum(1))]
    a = np.maximum(flat[bright].astype(np.float32), np.float32(1e-3))
    norm = np.minimum(img[..., 1] / a[1], img[..., 2] / a[2])
    t = 1.0 - np.float32(omega) * _min_filter(np.ascontiguousarray(norm, dtype=np.float32), patch)
    grey = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    t = np.clip(guided_filter(grey, t.astype(np.float32), max(1, 2 * patch), 1e-3), t_min, 1.0)
    out = (img - a) / t[..., None] + a
    return np.clip(out, 0.0, 1.0).astype(np.float32), t, a


class Udcp(Restorer):
    """:func:`udcp` per image."""

    name = "udcp"

    def __init__(self, patch: int = 15, omega: float = 0.95, t_min: float = 0.1) -> None:
        if isinstance(patch, bool) or not isinstance(patch, int) or not 1 <= patch <= 255:
            raise ValueError(f"patch: expected an int in [1, 255], got {patch!r}")
        self.patch = patch
        self.omega = check_range("omega", omega, 0.0, 1.0)
        self.t_min = check_range("t_min", t_min, 1e-3, 1.0)

    def restore(self, images: np.ndarray) -> Restored:
        return Restored(np.stack([udcp(im, self.patch, self.omega, self.t_min)[0] for im in _check(images)]))


def make_udcp(o: Checked) -> Udcp:
    """Implementation of ``udcp`` (declared in :mod:`murk.enhance.methods`)."""
    return Udcp(o.patch, o.omega, o.t_min)


# ------------------------------------------------------------------------------------------------- marine snow


class DeSnow(Restorer):
    """:func:`murk.snow.remove.remove_snow` per image: the particles found, the background put back behind them."""

    name = "desnow"

    def __init__(self, removal: SnowRemoval) -> None:
        self.removal = removal

    def restore(self, images: np.ndarray) -> Restored:
        return Restored(np.stack([remove_snow(im, self.removal) for im in _check(images)]))


def make_desnow(o: Checked) -> DeSnow:
    """Implementation of ``desnow`` (declared in :mod:`murk.enhance.methods`)."""
    return DeSnow(SnowRemoval(o.threshold, o.size, o.max_elongation, o.crowd))
