"""Comparison figures (the paper's Figs. 7 and 9): methods side by side with zoomed boxes.

:func:`auto_boxes` picks the regions to zoom into when the user gives none: the window with the most
structure (mean gradient magnitude: edges of blocks, nets, piles) and the window with the most small bright
blobs (white top-hat response: marine snow), without overlapping. :func:`comparison_grid` draws them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

BOX_COLOURS = ((255, 200, 0), (0, 220, 255), (255, 80, 80), (120, 255, 120))
"""RGB colours of the boxes, in order."""


@dataclass(frozen=True)
class Box:
    """A region ``x, y, w, h`` in pixels of the original image, with the reason it was chosen."""

    x: int
    y: int
    w: int
    h: int
    kind: str = "user"

    def clip(self, width: int, height: int) -> Box:
        w, h = min(self.w, width), min(self.h, height)
        return Box(min(max(0, self.x), width - w), min(max(0, self.y), height - h), w, h, self.kind)


def parse_box(text: str) -> Box:
    """Parse ``x,y,w,h`` (pixels)."""
    try:
        x, y, w, h = (int(v) for v in text.split(","))
    except ValueError:
        raise ValueError(f"--box: expected x,y,w,h in pixels, got {text!r}") from None
    if w < 4 or h < 4 or x < 0 or y < 0:
        raise ValueError(f"--box: expected x, y >= 0 and w, h >= 4, got {text!r}")
    return Box(x, y, w, h)


def _best_window(score: np.ndarray, size: int, taken: Sequence[Box]) -> tuple[int, int]:
    mean = cv2.boxFilter(score, -1, (size, size), normalize=True, borderType=cv2.BORDER_REFLECT)
    h, w = score.shape
    half = size // 2
    valid = np.full_like(mean, -np.inf)
    valid[half : h - half + 1, half : w - half + 1] = mean[half : h - half + 1, half : w - half + 1]
    for b in taken:  # no overlap with boxes already chosen
        y0, x0 = max(0, b.y - half), max(0, b.x - half)
        valid[y0 : b.y + b.h + half, x0 : b.x + b.w + half] = -np.inf
    if not np.isfinite(valid).any():
        return max(0, h // 2 - half), max(0, w // 2 - half)
    cy, cx = np.unravel_index(int(np.argmax(valid)), valid.shape)
    return int(cy) - half, int(cx) - half


def auto_boxes(image: np.ndarray, *, fraction: float = 0.22) -> list[Box]:
    """Two boxes on a float RGB image: most structure, then most marine snow (square, ``fraction`` of the
    shorter side).

    The image is split with a morphological opening (7 px ellipse): structure is the gradient energy of the
    opened image (particles removed), snow the white top-hat (the particles alone), so a field of snow never
    wins the structure box.
    """
    h, w = image.shape[:2]
    size = max(8, round(min(h, w) * fraction))
    gray = cv2.cvtColor(np.ascontiguousarray(image, dtype=np.float32), cv2.COLOR_RGB2GRAY)
    u8 = np.clip(gray * 255.0 + 0.5, 0, 255).astype(np.uint8)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    opened = cv2.morphologyEx(u8, cv2.MORPH_OPEN, kernel).astype(np.float32)
    gx = cv2.Sobel(opened, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(opened, cv2.CV_32F, 0, 1, ksize=3)
    y, x = _best_window(cv2.magnitude(gx, gy), size, [])
    first = Box(x, y, size, size, "structure")
    snow = (u8.astype(np.float32) - opened).clip(min=0.0)  # white top-hat
    y, x = _best_window(snow, size, [first])
    return [first, Box(x, y, size, size, "snow")]


def _label(panel: np.ndarray, text: str) -> np.ndarray:
    bar = np.full((22, panel.shape[1], 3), 24, np.uint8)
    cv2.putText(
        bar,
        text[: max(1, panel.shape[1] // 8)],
        (4, 16),
        cv2.FONT_HERSHEY_SIMPLEX,
        0.45,
        (235, 235, 235),
        1,
        cv2.LINE_AA,
    )
    return np.vstack([bar, panel])


def comparison_grid(
    images: Sequence[np.ndarray], labels: Sequence[str], boxes: Sequence[Box], *, panel_width: int = 360
) -> np.ndarray:
    """A uint8 RGB figure: one column per method; the full image (boxes drawn) on top, the zoomed boxes below.

    All ``images`` are float RGB in [0, 1] of the same size.
    """
    if not images or len(images) != len(labels):
        raise ValueError(f"images/labels: expected the same non-zero count, got {len(images)} and {len(labels)}")
    h, w = images[0].shape[:2]
    scale = panel_width / w
    ph = max(1, round(h * scale))
    boxes = [b.clip(w, h) for b in boxes]
    columns = []
    for img, label in zip(images, labels, strict=True):
        if img.shape[:2] != (h, w):
            raise ValueError(f"images: expected all {w}x{h}, got {img.shape[1]}x{img.shape[0]} for {label}")
        u8 = np.clip(img * 255.0 + 0.5, 0, 255).astype(np.uint8)
        full = cv2.resize(u8, (panel_width, ph), interpolation=cv2.INTER_AREA)
        for i, b in enumerate(boxes):
            c = BOX_COLOURS[i % len(BOX_COLOURS)]
            p0 = (int(b.x * scale), int(b.y * scale))
            p1 = (int((b.x + b.w) * scale) - 1, int((b.y + b.h) * scale) - 1)
            cv2.rectangle(full, p0, p1, c, 2)
        parts = [_label(full, label)]
        zw = panel_width // max(1, len(boxes))
        zooms = []
        for i, b in enumerate(boxes):
            crop = u8[b.y : b.y + b.h, b.x : b.x + b.w]
            zh = max(1, round(zw * b.h / b.w))
            z = cv2.resize(crop, (zw, zh), interpolation=cv2.INTER_NEAREST if b.w < zw else cv2.INTER_AREA)
            cv2.rectangle(z, (0, 0), (zw - 1, zh - 1), BOX_COLOURS[i % len(BOX_COLOURS)], 2)
            zooms.append(z)
        if zooms:
            zh = max(z.shape[0] for z in zooms)
            row = np.zeros((zh, panel_width, 3), np.uint8)
            x = 0
            for z in zooms:
                row[: z.shape[0], x : x + z.shape[1]] = z
                x += z.shape[1]
            parts.append(row)
        columns.append(np.vstack(parts))
    gap = np.full((columns[0].shape[0], 4, 3), 255, np.uint8)
    out = [columns[0]]
    for column in columns[1:]:
        out += [gap, column]
    return np.hstack(out)
