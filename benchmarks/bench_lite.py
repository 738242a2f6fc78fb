"""Speed of the ``lite`` real-time restorer against the small Joint-ID and ``post``, side by side in one run, on
2 CPU threads at 640x480 and 1280x720; parameters and multiply-accumulates (MACs) per frame.

Run: PYTHONPATH=src python benchmarks/bench_lite.py [--checkpoint LITE.pt] [--rounds 7]

Measured per size (one frame at a time, numpy RGB float32 in, restored frame out, as ``murk enhance`` calls a
restorer; median over interleaved rounds so that machine noise hits every method alike):
- ``lite`` network only (the folded torch module on a padded tensor);
- ``lite`` restorer with torch, and with its ONNX export under ONNX Runtime (2 intra-op threads);
- ``lite+post``, ``post`` (Eq. 9, OpenCV) and the small Joint-ID restorer (``jointid?lite_blend=0``, shipped
  weights, with ``refine`` but without the ``lite`` blend of the ``jointid`` method): the baseline of the speed-ups.
Weights: ``--checkpoint``, else the shipped ``lite.pt``, else random weights with trained-like statistics (the
speed of a convolutional network does not depend on the values). MACs: convolutions, linear layers and attention
products counted by ``torch.utils.flop_counter`` (FLOPs / 2; the lite network's convolutions run on the working
image, about 128x160); the lite network's per-pixel work at full resolution (the luma guide, 3 MACs per pixel;
bilinear upsampling of the 12 guided-filter maps, 4 MACs per value; the 6 coefficients ``a * Y + b``, 1 MAC each;
``gain * x + offset``, 1 MAC per value) is added analytically; other element-wise work, the downsampling to the
working image and pooling are not counted.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import cv2
import numpy as np
import torch
from _common import Figure, Recorder, interleaved, machine

from murk.data import sample_underwater_images, shipped_lite_weights
from murk.enhance.restorer import create
from murk.io import read_rgb
from murk.models.jointid import normalize_input
from murk.models.lite.network import LiteNet, build_lite, parameter_count

SIZES = {"640x480": (480, 640), "1280x720": (720, 1280)}
THREADS = 2


def sample_frame(h: int, w: int) -> np.ndarray:
    src = read_rgb(sample_underwater_images()[0])
    return np.ascontiguousarray(cv2.resize(src, (w, h), interpolation=cv2.INTER_AREA).clip(0, 1), dtype=np.float32)


def random_lite() -> LiteNet:
    """A base lite network with batch-norm statistics and a head away from their initial values."""
    torch.manual_seed(0)
    net = build_lite("base")
    with torch.no_grad():
        for m in net.modules():
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.uniform_(-0.5, 0.5)
                m.running_var.uniform_(0.5, 2.0)
        net.head.weight.normal_(std=0.1)
    return net.eval()


def macs_per_frame(model: torch.nn.Module, x: torch.Tensor) -> int:
    """Multiply-accumulates of one forward pass counted by torch's flop counter (FLOPs / 2)."""
    from torch.utils.flop_counter import FlopCounterMode

    counter = FlopCounterMode(display=False)
    with counter, torch.inference_mode():
        model(x)
    return counter.get_total_flops() // 2


def lite_full_res_macs(h: int, w: int) -> int:
    """Per full-resolution pixel: luma (3), bilinear upsampling of 12 maps (4 each), 6 coefficients ``a * Y + b``
    (1 each), ``gain * x + offset`` (3)."""
    return (3 + 12 * 4 + 6 + 3) * h * w


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--checkpoint", type=Path, default=None, help="lite checkpoint (default: shipped, else random)")
    ap.add_argument("--rounds", type=int, default=7, help="interleaved timing rounds per size")
    args = ap.parse_args()
    torch.set_num_threads(THREADS)
    cv2.setNumThreads(THREADS)
    print(f"machine: {machine()}; {THREADS} threads (torch, OpenCV, ONNX Runtime)")

    from murk.models.lite.checkpoint import load_lite, save_lite_checkpoint
    from murk.models.lite.onnx_export import export_lite_onnx

    tmp = Path(tempfile.mkdtemp(prefix="bench-lite-"))
    ckpt = args.checkpoint or (shipped_lite_weights() if shipped_lite_weights().is_file() else None)
    if ckpt is None:
        ckpt = save_lite_checkpoint(random_lite(), tmp / "random-lite.pt")
        print("weights: random (no shipped lite.pt; speed does not depend on the values)")
    else:
        print(f"weights: {ckpt}")
    folded = load_lite(ckpt)
    try:
        import onnxruntime  # noqa: F401

        have_ort = True
    except ImportError:
        have_ort = False
        print("onnxruntime not installed: no ONNX Runtime figures (pip install 'murk[onnx]')")
    methods = {
        "lite (torch)": create("lite", checkpoint=str(ckpt)),
        "lite+post": create("lite+post", checkpoint=str(ckpt)),
        "post": create("post"),
        "jointid small": create("jointid", lite_blend=0.0),
    }
    if have_ort:
        onnx_path = export_lite_onnx(folded, tmp / "lite.onnx")
        methods["lite (ONNX Runtime)"] = create("lite", checkpoint=str(onnx_path), threads=THREADS)

    rec = Recorder(echo=True)
    lite_params = parameter_count(folded)
    jointid = methods["jointid small"].model
    jointid_params = sum(p.numel() for p in jointid.parameters())
    rec.add(Figure("lite_params", "lite parameters (folded, inference)", lite_params, "parameters"))
    training_params = parameter_count(load_lite(ckpt, fold=False))
    rec.add(Figure("lite_params_training", "lite parameters (training form)", training_params, "parameters"))
    rec.add(Figure("jointid_small_params", "small Joint-ID parameters", jointid_params, "parameters"))
    for label, (h, w) in SIZES.items():
        frame = sample_frame(h, w)[None]
        x = torch.from_numpy(frame).permute(0, 3, 1, 2).contiguous()
        lite_macs = macs_per_frame(folded, x) + lite_full_res_macs(h, w)
        xj = torch.nn.functional.pad(normalize_input(x), (0, (-w) % 32, 0, (-h) % 32), mode="reflect")
        j_macs = macs_per_frame(jointid, xj)
        rec.add(Figure(f"lite_gmacs_{label}", f"lite GMACs per {label} frame", lite_macs / 1e9, "GMAC"))
        rec.add(Figure(f"jointid_small_gmacs_{label}", f"small Joint-ID GMACs per {label} frame", j_macs / 1e9, "GMAC"))
        fns = {"lite network only": lambda x=x: folded(x)}
        fns |= {name: (lambda r=r, f=frame: r.restore(f)) for name, r in methods.items()}
        with torch.inference_mode():
            ms = interleaved(fns, rounds=args.rounds, inner=2)
        base = ms["jointid small"]
        for name, v in ms.items():
            ref = ("jointid small", 1e3 / base) if name != "jointid small" else (None, None)
            if name == "lite+post":
                ref = ("post", 1e3 / ms["post"])
            key = name.replace(" ", "_").replace("(", "").replace(")", "").replace("+", "_plus_")
            rec.add(Figure(f"{key}_{label}_fps", f"{name}, {label}, {THREADS} threads", 1e3 / v, "frames/s", *ref))
    print("speed-ups (x): against the small Joint-ID measured in the same run; lite+post against post")


if __name__ == "__main__":
    main()
