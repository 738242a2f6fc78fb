"""The ``ursct`` restorer: URSCT-SESR (enhancement model; a comparison baseline of the paper) on images of any
size, CPU or GPU.

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

from murk.enhance.baseline import (
    DEFAULT_OVERLAP,
    OFFICIAL_SIZE,
    Policy,
    TorchRunner,
    check_images,
    check_overlap,
    check_policy,
    check_tile,
    missing_weights_message,
)
from murk.enhance.jointid_restorer import _resolve_device
from murk.enhance.restorer import RestoredTensor, Restorer
from murk.enhance.tiling import pad_to_multiple, tiled_apply
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


class URSCTRestorer(Restorer):
    """URSCT-SESR as a :class:`~murk.enhance.restorer.Restorer` (enhanced images, no depth).

    Args:
        model: a :class:`~murk.models.ursct_sesr.URSCT` (moved to ``device``).
        device: "cpu", "cuda" or "cuda:N".
        precision: "fp32", or "bf16"/"fp16" autocast.
        policy: "native" (any size, output at the input size) or "official" (256x256 as the published script).
        tile: native policy: tile side in pixels, a multiple of 128 (None = 256, the training size).
        overlap: tile overlap in pixels (also the blending-ramp width).
        batch: at most this many images (or tiles) per forward pass.

    Raises:
        ValueError: bad options, or CUDA not available.
    """

    name = "ursct"

    def __init__(
        self,
        model: URSCT,
        *,
        device: str | torch.device = "cpu",
        precision: str = "fp32",
        policy: Policy = "native",
        tile: int | None = None,
        overlap: int | None = DEFAULT_OVERLAP,
        batch: int | None = None,
    ) -> None:
        if not isinstance(model, URSCT):
            raise TypeError(f"model: expected a URSCT, got {type(model).__name__}")
        self.policy = check_policy(policy)
        self.tile = check_tile(tile, SIZE_MULTIPLE, "URSCT-SESR") or DEFAULT_TILE
        self.overlap = check_overlap(overlap, self.tile)
        self.device = _resolve_device(device)
        self.run = TorchRunner(model, self.device, precision, batch)
        self.weights: str | None = None
        """The weights file (set by the ``ursct`` factory)."""

    def restore_tensor(self, images: Tensor) -> RestoredTensor:
        """Restore a torch batch (B, 3, H, W) RGB in [0, 1] on the device (official policy: output 256x256).

        Raises:
            TypeError: not a floating-point tensor.
            ShapeError: not (B, 3, H, W).
        """
        check_images(images)
        x = images.to(self.device, torch.float32)
        if self.policy == "official":
            return RestoredTensor(official_output(self.run(official_input(x))).contiguous())
        x, pad = pad_to_multiple(x, PAD_MULTIPLE, "reflect", min_size=self.tile)
        (y,) = tiled_apply(
            lambda t: (self.run(t),),
            x,
            tile=self.tile,
            overlap=self.overlap,
            multiple=PAD_MULTIPLE,
            max_batch=self.run.batch,
        )
        return RestoredTensor(pad.crop(y).clamp(0.0, 1.0).contiguous())

    def __repr__(self) -> str:
        return (
            f"URSCTRestorer(device={self.device}, precision={self.run.precision}, policy={self.policy}, "
            f"tile={self.tile}, overlap={self.overlap}, batch={self.run.batch})"
        )


def create_ursct(
    *,
    checkpoint: str | Path | None = None,
    onnx: str | Path | None = None,
    device: str | torch.device = "cpu",
    precision: str = "fp32",
    policy: Policy = "native",
    tile: int | None = None,
    overlap: int | None = DEFAULT_OVERLAP,
    batch: int | None = None,
    trust_checkpoint: bool = False,
) -> URSCTRestorer:
    """Factory of ``ursct`` (registered lazily by :mod:`murk.enhance.methods`): load ``checkpoint`` and wrap
    it. Options: see :class:`URSCTRestorer`.

    Raises:
        ValueError: no checkpoint, or bad options.
        InputFileError: the checkpoint cannot be loaded (see ``murk.models.ursct_sesr.load_ursct``).
    """
    from murk.models.ursct_sesr.checkpoint import load_ursct

    if onnx is not None:
        raise ValueError(
            f"checkpoint: {onnx} is an ONNX file; the ursct restorer runs the torch network (any frame size) "
            "from the weights file (murk export's fixed-size graphs are for ONNX Runtime users)"
        )
    if checkpoint is None:
        raise ValueError(missing_weights_message("ursct", WEIGHTS_URL))
    tile_px = check_tile(tile, SIZE_MULTIPLE, "URSCT-SESR") or DEFAULT_TILE
    img_size = OFFICIAL_SIZE if policy == "official" else tile_px
    model = load_ursct(checkpoint, trust=trust_checkpoint, img_size=img_size)
    restorer = URSCTRestorer(
        model, device=device, precision=precision, policy=policy, tile=tile, overlap=overlap, batch=batch
    )
    restorer.weights = str(checkpoint)
    return restorer
