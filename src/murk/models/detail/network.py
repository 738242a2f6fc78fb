"""The detail stage: a small full-resolution network that adds a learned local residual to a restoration,
``out = x + s R(x)`` (issue 46, item 3: "a learned residual").

``R``: five 3x3 convolutions of :data:`DEFAULT_CHANNELS` channels with dilations 1, 2, 4, 1 and 1 (a receptive field
of 19x19 pixels) and leaky ReLU (slope :data:`LEAK`) between (plain ReLU units died in training: tests/train); the
last convolution starts at zero, so an untrained ``R`` changes nothing. The input is padded once by repeating its
border pixels (:data:`RADIUS_PX`) and the convolutions run unpadded: with zero padding the network learned where the
frame's top is (the far water of the training scenes) and tinted it red. It is trained (:mod:`murk.train.detail`) on a
base method's restorations of murk's synthetic water against the true clean scene, with the error that no global gain
and offset per channel removes, plus a term that keeps the residual's mean per image and channel near zero, so the
base's colour stays. Measured (docs/models/detail.md), it takes out marine snow and some forward-scatter blur, not the
haze that grows with distance (its field is too small to see distance, and seeing Joint-ID's distance as an input
did not help: docs/train.md); on water with neither the shipped weights leave the image as it was.

Weights: an ``.npz`` file (``detail.npz``, shipped; model card docs/models/detail.md) holding each convolution's
``conv{k}.weight`` and ``conv{k}.bias`` (float32) and ``meta`` (JSON text with ``channels`` and how it was trained).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn

from murk.models.npz_weights import read_npz_weights, write_npz_weights

DEFAULT_CHANNELS = 24
"""Width of the hidden convolutions of the shipped network."""

LEAK = 0.1
"""Slope of the leaky ReLU for negative inputs."""

DILATIONS = (1, 2, 4, 1)
"""Dilations of the first four convolutions (the fifth, the output, is 1)."""

BAND_PX = 1 << 20
"""Pixels per pass of :meth:`DetailNet.detailed` (about 100 MB of activations at 24 channels)."""

RADIUS_PX = sum(DILATIONS) + 1
"""The receptive field's radius (19x19 pixels): the input is padded by this many repeated border pixels once, and
every convolution runs without padding."""


class DetailNet(nn.Module):
    """``R`` (the module doc); :meth:`forward` gives the residual, :meth:`detailed` the detailed image."""

    def __init__(self, channels: int = DEFAULT_CHANNELS) -> None:
        super().__init__()
        if isinstance(channels, bool) or not isinstance(channels, int) or not 1 <= channels <= 256:
            raise ValueError(f"channels: expected an int in [1, 256], got {channels!r}")
        self.channels = channels
        widths = (3, *([channels] * len(DILATIONS)), 3)
        dilations = (*DILATIONS, 1)
        self.convs = nn.ModuleList(nn.Conv2d(widths[k], widths[k + 1], 3, dilation=d) for k, d in enumerate(dilations))
        last = self.convs[-1]
        assert isinstance(last, nn.Conv2d)
        nn.init.zeros_(last.weight)
        nn.init.zeros_(last.bias)  # type: ignore[arg-type]

    def forward(self, x: Tensor) -> Tensor:
        """The residual ``R(x)`` of a batch (B, 3, H, W) of RGB in [0, 1] (any size)."""
        return self.unpadded(F.pad(x, (RADIUS_PX,) * 4, mode="replicate"))

    def unpadded(self, padded: Tensor) -> Tensor:
        """The residual of the pixels at least :data:`RADIUS_PX` inside ``padded`` (2 x RADIUS_PX smaller on each
        axis): the convolutions alone, so that a band of rows of a padded frame, with its margin, gives exactly those
        rows of the frame's residual."""
        x = padded
        for conv in self.convs[:-1]:
            x = F.leaky_relu(conv(x), LEAK)
        return self.convs[-1](x)

    def detailed(self, x: Tensor, strength: float = 1.0, band_px: int = BAND_PX) -> Tensor:
        """``clamp(x + strength R(x), 0, 1)``, computed in bands of rows of about ``band_px`` pixels each (the same
        result as one pass; the network's activations of a whole large frame would take 24 floats per pixel)."""
        padded = F.pad(x, (RADIUS_PX,) * 4, mode="replicate")
        rows = max(1, band_px // max(1, x.shape[-1]))
        bands = [self.unpadded(padded[..., top : top + rows + 2 * RADIUS_PX, :]) for top in range(0, x.shape[-2], rows)]
        return (x + strength * torch.cat(bands, dim=-2)).clamp(0.0, 1.0)

    def arrays(self) -> dict[str, np.ndarray]:
        """The weights as float32 arrays named as in the ``.npz`` file."""
        return {f"conv{k}.{n}": p.detach().cpu().numpy().astype(np.float32)
                for k, conv in enumerate(self.convs) for n, p in conv.named_parameters()}  # fmt: skip


def save_detail(net: DetailNet, path: str | Path, meta: dict[str, Any] | None = None) -> Path:
    """Write ``net`` as a ``.npz`` file (atomically); ``meta`` (JSON-able) is stored beside ``channels``."""
    return write_npz_weights(path, net.arrays(), {**(meta or {}), "channels": net.channels})


def _network(arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> tuple[DetailNet, dict[str, Any]]:
    net = DetailNet(int(meta["channels"]))
    state = {f"convs.{k.removeprefix('conv')}": torch.from_numpy(v.astype(np.float32)) for k, v in arrays.items()}
    net.load_state_dict(state, strict=True)
    return net.eval(), meta


def load_detail(path: str | Path | None = None) -> tuple[DetailNet, dict[str, Any]]:
    """``(network in eval mode, meta)`` of a ``.npz`` file; None: the one shipped with murk.

    Raises:
        InputFileError: the file is missing, unreadable or not a detail network.
    """
    if path is None:
        from murk.data import shipped_detail_weights

        path = shipped_detail_weights()
    return read_npz_weights(path, "detail network", ".npz with conv0..conv4 and meta", _network)
