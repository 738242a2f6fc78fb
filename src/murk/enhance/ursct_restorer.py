"""The ``ursct`` restorer: URSCT-SESR (enhancement model; a comparison baseline of the paper) on images of any
size, CPU or GPU: :class:`murk.enhance.baseline.BaselineRestorer` with the network declared here
(:data:`URSCT_SESR`).

The network only takes square inputs whose side is a multiple of 128 and was trained at 256x256. Policies
(``policy`` option; :mod:`murk.enhance.baseline`):

- ``native`` (default): reflect-pad to a multiple of 8 and to at least one tile, run square tiles of ``tile``
  pixels (default 256, the training size; a multiple of 128) overlapping by ``overlap`` and blended at the
  seams, crop, clamp to [0, 1]. Output at the input size. Every image (and tile) is processed on its own
  window grid: the official batch coupling (:mod:`murk.models.ursct_sesr.network`) never happens.
- ``official`` (the published ``Enh_eval.py``): resize the [0, 1] tensor to 256x256 (bilinear, no antialias),
  output clamped and stored as 8 bit with round-half-up (``save_image``), left at 256x256.

Registry options (``murk.enhance.create("ursct", **options)``): ``checkpoint`` (required: the released
``*_bestSSIM.pth`` or a state dict), ``device``, ``precision`` ("fp32", "bf16", "fp16"), ``policy``
("native", "official"), ``tile`` (pixels, a multiple of 128; default 256), ``overlap`` (default 64),
``batch``, ``trust_checkpoint``.

Reference: Ren, Xu, Jiang, Yu, Zhang, Wang, Luo, "Reinforced Swin-Convs Transformer for Simultaneous
Underwater Sensing Scene Image Enhancement and Super-resolution", IEEE TGRS 60 (2022),
doi:10.1109/TGRS.2022.3205061.
"""

from __future__ import annotations

from pathlib import Path

import torch
import torch.nn.functional as F
from torch import Tensor

from murk.enhance.baseline import OFFICIAL_SIZE, BaselineNetwork, baseline_factory
from murk.models.ursct_sesr.network import SIZE_MULTIPLE, URSCT

DEFAULT_TILE = 256
"""The released weights' training size."""
PAD_MULTIPLE = 8
WEIGHTS_URL = (
    "https://drive.google.com/drive/folders/1ljhYcXwbdJ0fYzlF9UbEbZwr5zKk1ERb or "
    "https://pan.baidu.com/s/1SSwjv37uvwR7Zilq0s3YHw (password SESR)"
)
"""Where the authors publish the weights (their README, github.com/TingdiRen/URSCT-SESR)."""


def official_input(images: Tensor) -> Tensor:
    """The published ``Enh_eval.py`` input: the [0, 1] RGB tensor resized to 256x256, bilinear, no antialias
    (torchvision 0.12 on tensors)."""
    if images.shape[-2:] == (OFFICIAL_SIZE, OFFICIAL_SIZE):
        return images
    size = (OFFICIAL_SIZE, OFFICIAL_SIZE)
    return F.interpolate(images, size=size, mode="bilinear", align_corners=False, antialias=False)


def official_output(y: Tensor) -> Tensor:
    """What ``torchvision.utils.save_image`` stores: floor(clamp(y, 0, 1) * 255 + 0.5), back in [0, 1]."""
    return torch.floor(y.clamp(0.0, 1.0) * 255.0 + 0.5) / 255.0


def _load(checkpoint: str | Path, trust: bool, side: int | None) -> URSCT:
    """The network of ``checkpoint`` built for square inputs of ``side`` pixels."""
    from murk.models.ursct_sesr.checkpoint import load_ursct

    return load_ursct(checkpoint, trust=trust, img_size=side or DEFAULT_TILE)


URSCT_SESR = BaselineNetwork(
    name="ursct", title="URSCT-SESR", model_type=URSCT, load=_load, weights_url=WEIGHTS_URL,
    tile_multiple=SIZE_MULTIPLE, official_input=official_input, official_output=official_output,
    pad_multiple=PAD_MULTIPLE, square_tile=DEFAULT_TILE,
)  # fmt: skip
"""URSCT-SESR: RGB weights, square tiles only (a multiple of 128; 256 by default, the training size)."""

create_ursct = baseline_factory(URSCT_SESR)
"""Factory of ``ursct`` (declared in :mod:`murk.enhance.methods`): the released ``*_bestSSIM.pth`` or a
state dict; see :func:`murk.enhance.baseline.baseline_factory`."""
