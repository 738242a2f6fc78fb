"""Writing PNG: encode time and size of the PNG settings murk could use, on murk's own 640x480 images (issue 29).

Candidates, all lossless standard PNG:
- ``murk ISA-L`` (:func:`murk.io.png.encode_png_isal`, level 3, murk's default since 2026-12-04): the Sub filter
  in numpy and ISA-L's deflate (``isal``), from the RGB array murk holds;
- ``murk before`` (until 2026-12-03): zlib level 3 with libpng's defaults (all five filters tried per row,
  zlib's default strategy), through OpenCV;
- ``murk fast`` (:func:`murk.io.images.png_params`, level 3; murk's fast path 2026-12-03, still its fallback
  without ``isal``): libpng's fast filters (none/sub/up) and zlib's run-length strategy;
- ``cv2.imwrite defaults``: what a plain script gets from ``cv2.imwrite(path, image)``;
- level 1, default filters; level 9 (the smallest files).

Images: the clean RGB and the uint16 depth of the shipped RGB-D pairs, and a degraded variant of each
(``murk synth``'s default stages). One thread; median of interleaved rounds.

Run: PYTHONPATH=src python benchmarks/bench_png.py [--rounds 9]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import interleaved, pin_one_core

pin_one_core()

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from murk.data import sample_rgbd_dir  # noqa: E402
from murk.io import DepthOptions, discover, load_pair  # noqa: E402
from murk.io.images import png_params, to_uint  # noqa: E402
from murk.io.png import encode_png_isal  # noqa: E402
from murk.synth.config import SynthConfig  # noqa: E402
from murk.synth.params import sample_variant  # noqa: E402
from murk.synth.render import render  # noqa: E402

CANDIDATES: dict[str, list[int]] = {
    "murk before (l3, libpng defaults)": [cv2.IMWRITE_PNG_COMPRESSION, 3],
    "murk fast (l3, fast filters, RLE)": png_params(3),
    "cv2.imwrite defaults": [],
    "l1, libpng default filters": [cv2.IMWRITE_PNG_COMPRESSION, 1],
    "l9 (smallest)": [cv2.IMWRITE_PNG_COMPRESSION, 9],
}


ISAL = "murk ISA-L (l3, Sub, isal)"


def encode(name: str, img: np.ndarray) -> bytes:
    """One candidate's PNG bytes of a BGR (OpenCV's order) or grey image."""
    if name == ISAL:  # murk holds RGB: the reversed view is what it passes
        return encode_png_isal(np.ascontiguousarray(img[:, :, ::-1]) if img.ndim == 3 else img, 3)
    return cv2.imencode(".png", img, CANDIDATES[name])[1].tobytes()


def images() -> dict[str, np.ndarray]:
    out: dict[str, np.ndarray] = {}
    sources, _ = discover(sample_rgbd_dir())
    for src in sources:
        clean, depth, valid = load_pair(src, DepthOptions())
        if clean.shape[:2] != (480, 640):
            continue
        out[f"{src.stem} clean"] = np.ascontiguousarray(to_uint(clean)[:, :, ::-1])
        out[f"{src.stem} depth16"] = np.clip(np.rint(np.where(valid, depth, 0) * 1000), 0, 65535).astype(np.uint16)
        res = render(clean, depth, sample_variant(0, SynthConfig()))
        out[f"{src.stem} degraded"] = np.ascontiguousarray(to_uint(res.degraded)[:, :, ::-1])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=9)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    imgs = images()
    stamp = time.strftime("%Y-%m-%d %H:%M")
    print(f"# bench_png  {stamp}  {len(imgs)} images 640x480, 1 thread, OpenCV {cv2.__version__}")
    names = [ISAL, *CANDIDATES]
    totals = {k: [0.0, 0] for k in names}
    for name, img in imgs.items():
        rgb = np.ascontiguousarray(img[:, :, ::-1]) if img.ndim == 3 else img
        calls = {k: (lambda p=p, img=img: cv2.imencode(".png", img, p)) for k, p in CANDIDATES.items()}
        calls[ISAL] = lambda rgb=rgb: encode_png_isal(rgb, 3)  # type: ignore[misc]
        ms = interleaved(calls, rounds=args.rounds, inner=2)
        for k in names:
            data = encode(k, img)
            totals[k][0] += ms[k]
            totals[k][1] += len(data)
            back = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
            assert np.array_equal(back, img), (name, k)  # lossless
        print(name + ": " + "; ".join(f"{k} {ms[k]:.1f} ms" for k in names))
    base_ms, base_kb = totals["murk before (l3, libpng defaults)"]
    print("\ntotal over the images (lossless checked):")
    for k, (t, b) in totals.items():
        print(f"  {k:36s} {t:7.1f} ms  {b / 1e3:8.1f} kB   speed x{base_ms / t:.2f}  size {b / base_kb:.3f}x")


if __name__ == "__main__":
    main()
