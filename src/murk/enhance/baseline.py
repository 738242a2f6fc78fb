"""The one restorer of the paper's comparison baselines (``udaformer``, ``ursct``): :class:`BaselineRestorer`,
parameterised by a :class:`BaselineNetwork` (the network, its checkpoint loader, its size rules and its official
pre- and post-processing; :mod:`murk.enhance.udaformer_restorer` and :mod:`murk.enhance.ursct_restorer` declare
one each), the torch runner (device, precision, chunks) and validation of their options.

Two input policies (``policy`` option, ``docs/baselines.md``):

- ``native`` (default): any size. The frame is reflect-padded (to a multiple of 8, and for a network of square
  tiles, URSCT-SESR, to at least one tile), run whole or in overlapping tiles blended at the seams as for
  Joint-ID, cropped back: the output has the input's size and every image of a batch is processed on its own
  (no batch coupling).
- ``official``: what each published test script does (the resize to 256x256, its channel order, its 8-bit
  rounding), and the output stays 256x256, so scores match published ones.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from torch import Tensor, nn

from murk.enhance.choices import DEFAULT_OVERLAP, POLICIES, Policy
from murk.enhance.declare import Checked
from murk.enhance.restorer import RestoredTensor, Restorer, check_tensor_batch, torch_device
from murk.enhance.tiling import pad_to_multiple, tiled_apply

OFFICIAL_SIZE = 256
"""Side of the square the official test scripts resize every image to (and leave the output at)."""
_DTYPES: dict[str, torch.dtype] = {"bf16": torch.bfloat16, "fp16": torch.float16}


def check_policy(policy: Any) -> Policy:
    """Raises ValueError unless ``policy`` is ``"native"`` or ``"official"``."""
    if policy not in POLICIES:
        raise ValueError(f"policy: expected 'native' or 'official', got {policy!r}")
    return policy  # type: ignore[no-any-return]


class TorchRunner:
    """Runs a network on a device in fp32 or bf16/fp16 autocast, at most ``batch`` images per forward pass,
    under ``torch.inference_mode``; returns float32."""

    def __init__(self, model: nn.Module, device: torch.device, precision: str, batch: int | None) -> None:
        if precision not in ("fp32", "bf16", "fp16"):
            raise ValueError(f"precision: expected 'fp32', 'bf16' or 'fp16', got {precision!r}")
        if batch is not None and (isinstance(batch, bool) or batch < 1):
            raise ValueError(f"batch: expected None or a positive integer, got {batch!r}")
        self.model = model.to(device).eval()
        self.device = device
        self.precision = precision
        self.batch = batch

    def _autocast(self) -> contextlib.AbstractContextManager[Any]:
        if self.precision == "fp32":
            return contextlib.nullcontext()
        return torch.autocast(self.device.type, dtype=_DTYPES[self.precision])

    def __call__(self, x: Tensor) -> Tensor:
        step = self.batch or x.shape[0]
        outs = []
        with torch.inference_mode(), self._autocast():
            for i in range(0, x.shape[0], step):
                outs.append(self.model(x[i : i + step].to(self.device, torch.float32)).float())
        return torch.cat(outs)


def check_tile(tile: Any, multiple: int, what: str) -> int | None:
    """``tile`` as None (0 = None) or a positive multiple of ``multiple``; ValueError otherwise."""
    if tile is None or tile == 0:
        return None
    if isinstance(tile, bool) or not isinstance(tile, int) or tile < multiple or tile % multiple:
        raise ValueError(f"tile: expected None or a positive multiple of {multiple} pixels ({what}), got {tile!r}")
    return tile


def check_overlap(overlap: Any, tile: int | None) -> int:
    """``overlap`` (None = 64) as 0 <= overlap < tile; ValueError otherwise."""
    overlap = DEFAULT_OVERLAP if overlap is None else overlap
    if isinstance(overlap, bool) or not isinstance(overlap, int) or overlap < 0:
        raise ValueError(f"overlap: expected >= 0 pixels, got {overlap!r}")
    if tile is not None and overlap >= tile:
        raise ValueError(f"overlap: expected 0 <= overlap < tile ({tile}), got {overlap}")
    return overlap


def missing_weights_message(method: str, where: str) -> str:
    """The error of a baseline factory called without weights (murk never bundles or downloads them)."""
    return (
        f"checkpoint: {method} needs its weights file, which murk does not bundle or download; get it from {where} "
        f"(docs/baselines.md) and pass --method {method}:PATH (murk compare) or --checkpoint PATH (murk enhance)"
    )


@dataclass(frozen=True)
class BaselineNetwork:
    """What one comparison baseline adds to :class:`BaselineRestorer`: its network and checkpoint.

    Attributes:
        name: the method name (``udaformer``).
        title: the network's name in messages (``UDAformer``).
        model_type: the network's class (a restorer refuses another).
        load: (checkpoint, trust_checkpoint, side) -> the network in eval mode; ``side`` is the square input
            size it will see (256 under the official policy, else the tile side; None: any size).
        weights_url: where the authors publish the weights (murk never downloads them).
        tile_multiple: ``tile`` must be a multiple of this.
        official_input, official_output: the published script's pre-processing of a float RGB batch
            (B, 3, H, W) in [0, 1] into the network's input, and its saving of the network's output, back as
            float RGB (B, 3, h, w) in [0, 1].
        bgr: the released weights were trained on BGR (the native policy flips the channels around the network).
        pad_multiple: native frames are reflect-padded to multiples of this.
        square_tile: the network takes only square tiles: their default side (frames are padded to at least one
            tile and always run in tiles); None: it takes any size that is a multiple of ``pad_multiple``.
        auto_tile: without a ``tile``, padded frames of more than ``auto_tile ** 2`` pixels run in tiles of this
            side; None: never.
    """

    name: str
    title: str
    model_type: type[nn.Module]
    load: Callable[[str | Path, bool, int | None], nn.Module]
    weights_url: str
    tile_multiple: int
    official_input: Callable[[Tensor], Tensor]
    official_output: Callable[[Tensor], Tensor]
    bgr: bool = False
    pad_multiple: int = 8
    square_tile: int | None = None
    auto_tile: int | None = None


class BaselineRestorer(Restorer):
    """A comparison baseline as a :class:`~murk.enhance.restorer.Restorer` (enhanced images, no depth).

    Args:
        network: which baseline (:data:`murk.enhance.udaformer_restorer.UDAFORMER`,
            :data:`murk.enhance.ursct_restorer.URSCT_SESR`).
        model: an instance of ``network.model_type`` (moved to ``device``).
        device: "cpu", "cuda" or "cuda:N".
        precision: "fp32", or "bf16"/"fp16" autocast.
        policy: "native" (any size, output at the input size) or "official" (256x256 as the published test).
        tile: native policy: tile side in pixels, a multiple of ``network.tile_multiple``; None = the network's
            ``square_tile``, or whole frames up to ``auto_tile ** 2`` pixels and larger ones in ``auto_tile``
            tiles.
        overlap: tile overlap in pixels (also the blending-ramp width).
        batch: at most this many images (or tiles) per forward pass.

    Raises:
        TypeError: ``model`` is not the network's class.
        ValueError: bad options, or CUDA not available.
    """

    def __init__(
        self,
        network: BaselineNetwork,
        model: nn.Module,
        *,
        device: str | torch.device = "cpu",
        precision: str = "fp32",
        policy: Policy = "native",
        tile: int | None = None,
        overlap: int | None = DEFAULT_OVERLAP,
        batch: int | None = None,
    ) -> None:
        if not isinstance(model, network.model_type):
            raise TypeError(f"model: expected a {network.model_type.__name__}, got {type(model).__name__}")
        self.network = network
        self.name = network.name
        self.policy = check_policy(policy)
        self.tile = check_tile(tile, network.tile_multiple, network.title) or network.square_tile
        self.overlap = check_overlap(overlap, self.tile)
        self.device = torch_device(device)
        self.run = TorchRunner(model, self.device, precision, batch)
        self.weights: str | None = None
        """The weights file (set by the method's factory)."""

    def restore_tensor(self, images: Tensor) -> RestoredTensor:
        """Restore a torch batch (B, 3, H, W) RGB in [0, 1] on the device (official policy: output 256x256).

        Raises:
            TypeError: not a floating-point tensor.
            ShapeError: not (B, 3, H, W).
        """
        check_tensor_batch(images)
        net = self.network
        x = images.to(self.device, torch.float32)
        if self.policy == "official":
            y = net.official_output(self.run(net.official_input(x)))
            return RestoredTensor(y.to(x.device).contiguous())
        if net.bgr:
            x = x.flip(1)
        x, pad = pad_to_multiple(x, net.pad_multiple, "reflect", min_size=(net.square_tile and self.tile) or 1)
        tile = self.tile
        if tile is None and net.auto_tile is not None and x.shape[2] * x.shape[3] > net.auto_tile**2:
            tile = net.auto_tile
        if tile is not None and (x.shape[2] > tile or x.shape[3] > tile):
            (y,) = tiled_apply(
                lambda t: (self.run(t),),
                x,
                tile=tile,
                overlap=self.overlap if net.square_tile else min(self.overlap, tile - net.pad_multiple),
                multiple=net.pad_multiple,
                max_batch=self.run.batch,
            )
        else:
            y = self.run(x)
        y = pad.crop(y)
        return RestoredTensor((y.flip(1) if net.bgr else y).clamp(0.0, 1.0).contiguous())

    def __repr__(self) -> str:
        return (
            f"BaselineRestorer({self.name}, device={self.device}, precision={self.run.precision}, "
            f"policy={self.policy}, tile={self.tile}, overlap={self.overlap}, batch={self.run.batch})"
        )


def baseline_factory(network: BaselineNetwork) -> Callable[[Checked], BaselineRestorer]:
    """The implementation of ``network``'s method (``create_<name>``; declared in :mod:`murk.enhance.methods`):
    load ``checkpoint`` (an official file that pickles more than weights needs ``trust_checkpoint``) and wrap it.
    Options: see :class:`BaselineRestorer`.

    The implementation raises ValueError for no checkpoint, an ONNX file or bad options, and InputFileError when
    the checkpoint cannot be loaded.
    """

    def create(o: Checked) -> BaselineRestorer:
        if o.onnx is not None:
            raise ValueError(
                f"checkpoint: {o.onnx} is an ONNX file; the {network.name} restorer runs the torch network (any frame "
                "size) from the weights file (murk export's fixed-size graphs are for ONNX Runtime users)"
            )
        if o.checkpoint is None:
            raise ValueError(missing_weights_message(network.name, network.weights_url))
        tile_px = check_tile(o.tile, network.tile_multiple, network.title) or network.square_tile
        model = network.load(o.checkpoint, o.trust_checkpoint, OFFICIAL_SIZE if o.policy == "official" else tile_px)
        settings = {k: o[k] for k in ("device", "precision", "policy", "tile", "overlap", "batch")}
        restorer = BaselineRestorer(network, model, **settings)
        restorer.weights = str(o.checkpoint)
        return restorer

    create.__name__ = create.__qualname__ = f"create_{network.name}"
    create.__doc__ = f"Implementation of ``{network.name}``: see :func:`baseline_factory`."
    return create
