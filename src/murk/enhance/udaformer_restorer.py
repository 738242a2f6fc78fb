"""The ``udaformer`` restorer: UDAformer (a comparison baseline of the paper) on images of any size, CPU or GPU.

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
from murk.enhance.restorer import Restored, RestoredTensor, Restorer
from murk.enhance.tiling import pad_to_multiple, tiled_apply
from murk.models.udaformer.network import WINDOW, UDAformer

SIZE_MULTIPLE = WINDOW
"""Native frames are reflect-padded to multiples of this (no zero-padding paths inside the network)."""
AUTO_TILE_PIXELS = 1024 * 1024
"""Native frames (padded) larger than this many pixels are tiled when no ``tile`` is given."""
AUTO_TILE = 1024
WEIGHTS_URL = "https://drive.google.com/drive/folders/13ehthtYe7GSnQWaTZsnTa2n_08RNlF22"
"""Where the authors publish the weights (their README); no licence: murk never downloads them."""


def official_input(images: np.ndarray) -> np.ndarray:
    """The published ``test.py`` input from float RGB (B, H, W, 3) in [0, 1]: 8-bit, ``cv2.resize`` to 256x256
    (bilinear, on the 8-bit image), BGR, /255 -> float32 (B, 3, 256, 256)."""
    u8 = np.clip(np.rint(np.asarray(images, np.float64) * 255.0), 0, 255).astype(np.uint8)
    size = (OFFICIAL_SIZE, OFFICIAL_SIZE)
    resized = np.stack([cv2.resize(im, size, interpolation=cv2.INTER_LINEAR) for im in u8])
    return np.ascontiguousarray(resized[..., ::-1].transpose(0, 3, 1, 2)).astype(np.float32) / np.float32(255.0)


def official_output(y: Tensor) -> np.ndarray:
    """The network's BGR output (B, 3, h, w) as ``cv2.imwrite`` stores it (clamp(rint(255 y), 0, 255)), back as
    float RGB (B, h, w, 3) in [0, 1]."""
    u8 = np.clip(np.rint(y.detach().float().cpu().numpy() * 255.0), 0, 255)
    return np.ascontiguousarray(u8.transpose(0, 2, 3, 1)[..., ::-1]).astype(np.float32) / np.float32(255.0)


class UDAformerRestorer(Restorer):
    """UDAformer as a :class:`~murk.enhance.restorer.Restorer` (enhanced images, no depth).

    Args:
        model: a :class:`~murk.models.udaformer.UDAformer` (moved to ``device``).
        device: "cpu", "cuda" or "cuda:N".
        precision: "fp32", or "bf16"/"fp16" autocast.
        policy: "native" (any size, output at the input size) or "official" (256x256 as the published test).
        tile: native policy: tile size in pixels (a multiple of 8); None = whole frames up to
            :data:`AUTO_TILE_PIXELS`, larger ones in :data:`AUTO_TILE` tiles.
        overlap: tile overlap in pixels (also the blending-ramp width).
        batch: at most this many images (or tiles) per forward pass.

    Raises:
        ValueError: bad options, or CUDA not available.
    """

    name = "udaformer"

    def __init__(
        self,
        model: UDAformer,
        *,
        device: str | torch.device = "cpu",
        precision: str = "fp32",
        policy: Policy = "native",
        tile: int | None = None,
        overlap: int | None = DEFAULT_OVERLAP,
        batch: int | None = None,
    ) -> None:
        if not isinstance(model, UDAformer):
            raise TypeError(f"model: expected a UDAformer, got {type(model).__name__}")
        self.policy = check_policy(policy)
        self.tile = check_tile(tile, SIZE_MULTIPLE, "UDAformer")
        self.overlap = check_overlap(overlap, self.tile)
        self.device = _resolve_device(device)
        self.run = TorchRunner(model, self.device, precision, batch)
        self.weights: str | None = None
        """The weights file (set by the ``udaformer`` factory)."""

    def restore(self, images: np.ndarray) -> Restored:
        """Restore a numpy batch (B, H, W, 3) float32 RGB in [0, 1] (official policy: output 256x256)."""
        if self.policy != "official":
            return super().restore(images)
        if not isinstance(images, np.ndarray) or images.ndim != 4 or images.shape[3] != 3:
            raise TypeError(f"images: expected a numpy batch (B, H, W, 3), got {getattr(images, 'shape', images)!r}")
        x = torch.from_numpy(official_input(images))
        return Restored(official_output(self.run(x)))

    def restore_tensor(self, images: Tensor) -> RestoredTensor:
        """Restore a torch batch (B, 3, H, W) RGB in [0, 1] on the device.

        Raises:
            TypeError: not a floating-point tensor.
            ShapeError: not (B, 3, H, W).
        """
        check_images(images)
        if self.policy == "official":  # the published pre-processing is OpenCV on 8-bit images
            return super().restore_tensor(images)
        x = images.to(self.device, torch.float32).flip(1)  # RGB -> BGR
        x, pad = pad_to_multiple(x, SIZE_MULTIPLE, "reflect")
        tile = self.tile
        if tile is None and x.shape[2] * x.shape[3] > AUTO_TILE_PIXELS:
            tile = AUTO_TILE
        if tile is not None and (x.shape[2] > tile or x.shape[3] > tile):
            (y,) = tiled_apply(
                lambda t: (self.run(t),),
                x,
                tile=tile,
                overlap=min(self.overlap, tile - SIZE_MULTIPLE),
                multiple=SIZE_MULTIPLE,
                max_batch=self.run.batch,
            )
        else:
            y = self.run(x)
        return RestoredTensor(pad.crop(y).flip(1).clamp(0.0, 1.0).contiguous())

    def __repr__(self) -> str:
        return (
            f"UDAformerRestorer(device={self.device}, precision={self.run.precision}, policy={self.policy}, "
            f"tile={self.tile}, overlap={self.overlap}, batch={self.run.batch})"
        )


def create_udaformer(
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
) -> UDAformerRestorer:
    """Factory of ``udaformer`` (registered lazily by :mod:`murk.enhance.methods`): load ``checkpoint`` (the
    official file needs ``trust_checkpoint``: it pickles an optimiser object) and wrap it. Options: see
    :class:`UDAformerRestorer`.

    Raises:
        ValueError: no checkpoint, or bad options.
        InputFileError: the checkpoint cannot be loaded (see ``murk.models.udaformer.load_udaformer``).
    """
    from murk.models.udaformer.checkpoint import load_udaformer

    if onnx is not None:
        raise ValueError(
            f"checkpoint: {onnx} is an ONNX file; the udaformer restorer runs the torch network (any frame size) "
            "from the weights file (murk export's fixed-size graphs are for ONNX Runtime users)"
        )
    if checkpoint is None:
        raise ValueError(missing_weights_message("udaformer", WEIGHTS_URL))
    model = load_udaformer(checkpoint, trust=trust_checkpoint)
    restorer = UDAformerRestorer(
        model, device=device, precision=precision, policy=policy, tile=tile, overlap=overlap, batch=batch
    )
    restorer.weights = str(checkpoint)
    return restorer
