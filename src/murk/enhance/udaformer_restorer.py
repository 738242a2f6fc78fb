"""The ``udaformer`` restorer: UDAformer (a comparison baseline of the paper) on images of any size, CPU or GPU:
:class:`murk.enhance.baseline.BaselineRestorer` with the network declared here (:data:`UDAFORMER`).

Policies (``policy`` option; :mod:`murk.enhance.baseline`):

- ``native`` (default): RGB -> BGR (the released weights were trained on BGR), reflect-pad to a multiple of 8,
  the network on the whole frame (or in blended tiles: ``tile``; frames above :data:`AUTO_TILE_PIXELS` are
  tiled at :data:`AUTO_TILE` automatically, because the latent attention holds an N x N matrix, N = pixels/64),
  crop, BGR -> RGB, clamp to [0, 1]. Output at the input size.
- ``official`` (the published ``test.py``): 8-bit image, ``cv2.resize`` to 256x256 (bilinear), BGR, /255;
  output clamp(rint(255 y), 0, 255) (what ``cv2.imwrite`` does with it), left at 256x256.

Registry options (``murk.enhance.create("udaformer", **options)``): ``checkpoint`` (required: the official
``checkpoint_489_epoch.pkl`` with ``trust_checkpoint=True``, or a weights-only copy), ``device``,
``precision`` ("fp32", "bf16", "fp16"), ``policy`` ("native", "official"), ``tile`` (pixels, a multiple of 8),
``overlap`` (pixels, default 64), ``batch``, ``trust_checkpoint``.

Reference: Shen, Xu, Luo, Song, He, "UDAformer: Underwater image enhancement based on dual attention
transformer", Computers & Graphics 111 (2023) 77-88, doi:10.1016/j.cag.2023.01.009.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import torch
from torch import Tensor

from murk.enhance.baseline import OFFICIAL_SIZE, BaselineNetwork, baseline_factory
from murk.models.udaformer.network import WINDOW, UDAformer

SIZE_MULTIPLE = WINDOW
"""Native frames are reflect-padded to multiples of this (no zero-padding paths inside the network)."""
AUTO_TILE = 1024
"""Native frames (padded) larger than ``AUTO_TILE ** 2`` pixels are tiled at this side when no ``tile`` is given."""
AUTO_TILE_PIXELS = AUTO_TILE * AUTO_TILE
WEIGHTS_URL = "https://drive.google.com/drive/folders/13ehthtYe7GSnQWaTZsnTa2n_08RNlF22"
"""Where the authors publish the weights (their README); no licence: murk never downloads them."""


def official_input(images: Tensor) -> Tensor:
    """The published ``test.py`` input from float RGB (B, 3, H, W) in [0, 1]: 8-bit, ``cv2.resize`` to 256x256
    (bilinear, on the 8-bit image), BGR, /255 -> float32 (B, 3, 256, 256) on the CPU."""
    rgb = images.detach().float().permute(0, 2, 3, 1).cpu().numpy()
    u8 = np.clip(np.rint(np.asarray(rgb, np.float64) * 255.0), 0, 255).astype(np.uint8)
    size = (OFFICIAL_SIZE, OFFICIAL_SIZE)
    resized = np.stack([cv2.resize(im, size, interpolation=cv2.INTER_LINEAR) for im in u8])
    bgr = np.ascontiguousarray(resized[..., ::-1].transpose(0, 3, 1, 2)).astype(np.float32) / np.float32(255.0)
    return torch.from_numpy(bgr)


def official_output(y: Tensor) -> Tensor:
    """The network's BGR output (B, 3, h, w) as ``cv2.imwrite`` stores it (clamp(rint(255 y), 0, 255)), back as
    float RGB (B, 3, h, w) in [0, 1] on the CPU."""
    u8 = np.clip(np.rint(y.detach().float().cpu().numpy() * 255.0), 0, 255)
    return torch.from_numpy(np.ascontiguousarray(u8[:, ::-1]).astype(np.float32) / np.float32(255.0))


def _load(checkpoint: str | Path, trust: bool, side: int | None) -> UDAformer:
    """The network of ``checkpoint`` (any input size: ``side`` is not needed)."""
    from murk.models.udaformer.checkpoint import load_udaformer

    return load_udaformer(checkpoint, trust=trust)


UDAFORMER = BaselineNetwork(
    name="udaformer", title="UDAformer", model_type=UDAformer, load=_load, weights_url=WEIGHTS_URL,
    tile_multiple=SIZE_MULTIPLE, official_input=official_input, official_output=official_output,
    bgr=True, pad_multiple=SIZE_MULTIPLE, auto_tile=AUTO_TILE,
)  # fmt: skip
"""UDAformer: BGR weights, any size (whole frames up to :data:`AUTO_TILE_PIXELS`), tiles a multiple of 8."""

create_udaformer = baseline_factory(UDAFORMER)
"""Factory of ``udaformer`` (declared in :mod:`murk.enhance.methods`): the official
``checkpoint_489_epoch.pkl`` needs ``trust_checkpoint`` (it pickles an optimiser object); see
:func:`murk.enhance.baseline.baseline_factory`."""
