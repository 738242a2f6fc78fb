"""Joint-ID decoder: mix-decoder blocks per scale, pixel-shuffle upsampling and the multi-scale head.

Reference: Yang, Kang, Lee, Cho, "Transformer-Based Joint Image Enhancement and Depth Estimation for
Underwater Environments", IEEE Sensors Journal 23(24), 2023, doi:10.1109/JSEN.2023.3338730.

The two branches (depth, enhancement) are coupled by joint blocks between "mix" and "upsample" at every
scale, so the decoder exposes its steps (:meth:`Decoder.start`, :meth:`Decoder.mix`, :meth:`Decoder.skip`,
:meth:`Decoder.up`, :meth:`Decoder.head`) and the network (``network.py``) runs them in lock step. Scales are
indexed 0..3 for c1..c4. Maps stay channels-last: token-wise LayerNorm/Linear work on the (B, H, W, C) view
of the same memory, so no layout copy is needed between the linear and the convolutional paths.
"""

from __future__ import annotations

from typing import Literal

import torch
import torch.nn.functional as F
from torch import Tensor, nn

Task = Literal["depth", "enhanced"]


class ConvMix(nn.Module):
    """t = LN(x); GELU(conv1x1(Linear(t) + conv3x3(t))) + t. ``norm_layer_2`` exists for checkpoint
    compatibility only: the official block defines it and never uses it."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.norm_layer_1 = nn.LayerNorm(dim)
        self.norm_layer_2 = nn.LayerNorm(dim)  # unused (no gradient), kept for the official state dict
        self.linear_1 = nn.Linear(dim, dim)
        self.conv_2 = nn.Conv2d(dim, dim, 3, padding=1)
        self.conv_3 = nn.Conv2d(dim, dim, 1)

    def forward(self, x: Tensor) -> Tensor:
        t = self.norm_layer_1(x.permute(0, 2, 3, 1))  # (B, H, W, C)
        t_map = t.permute(0, 3, 1, 2)
        y = self.linear_1(t).permute(0, 3, 1, 2) + self.conv_2(t_map)
        return F.gelu(self.conv_3(y)) + t_map


class FeatureMix(nn.Module):
    """t = LN(x); GELU(conv1x1(concat[Linear_{C->C/2}(t), conv3x3_{C->C/2}(t)])) + t."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        if dim % 2:
            raise ValueError(f"dim: expected an even channel count, got {dim}")
        self.norm_layer_1 = nn.LayerNorm(dim)
        self.linear_1 = nn.Linear(dim, dim // 2)
        self.conv_2 = nn.Conv2d(dim, dim // 2, 3, padding=1)
        self.conv_3 = nn.Conv2d(dim, dim, 1)

    def forward(self, x: Tensor) -> Tensor:
        t = self.norm_layer_1(x.permute(0, 2, 3, 1))
        t_map = t.permute(0, 3, 1, 2)
        y = torch.cat([self.linear_1(t).permute(0, 3, 1, 2), self.conv_2(t_map)], dim=1)
        return F.gelu(self.conv_3(y)) + t_map


class MixDecoderBlock(nn.Module):
    """ConvMix(x), fuse with the encoder feature (concat -> conv1x1 2C->C), then FeatureMix."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.convmix_decoder = ConvMix(dim)
        self.reduction_channels = nn.Conv2d(2 * dim, dim, 1)
        self.feature_mix_decoder = FeatureMix(dim)

    def forward(self, x: Tensor, feat: Tensor) -> Tensor:
        x = self.convmix_decoder(x)
        x = self.reduction_channels(torch.cat([x, feat], dim=1))
        return self.feature_mix_decoder(x)


_SKIP_SHUFFLE = (1, 2, 4, 8)  # c1..c4: every skip ends at 1/4 of the input


def triangle_kernel(r: int) -> Tensor:
    """The normalised 1-D triangle of ``2r - 1`` taps, ``(1, 2, .., r, .., 2, 1) / r**2``: the box of ``r`` taps
    convolved with itself. Its frequency response is zero at ``k / r`` cycles per pixel (k = 1 .. r-1), so
    filtering a pixel-shuffled map with it (separably) removes every pattern of period ``r`` that the shuffle
    can create, without a shift (it is symmetric). After a shuffle whose ``r*r`` sub-pixel channels are equal it
    makes the upsampling linear interpolation."""
    t = torch.arange(1, r + 1, dtype=torch.float32)
    return torch.cat([t, t.flip(0)[1:]]) / (r * r)


def smooth_shuffled(x: Tensor, r: int) -> Tensor:
    """Separable :func:`triangle_kernel` filter of a map pixel-shuffled by ``r`` (replicate-padded so the size is
    kept). Identity for ``r == 1``. Reference: the zero-order-hold condition for sub-pixel convolutions without
    checkerboard artefacts (Sugawara, Shiota, Kiya, ICIP 2018), here with the hold kernel applied twice
    (triangle) so that it is symmetric. Computed as box averages of ``r`` taps, twice along each axis (the
    triangle is the box convolved with itself): on CPUs a depthwise convolution with the triangle is up to 15x
    slower (162 ms against 11 ms on a 2-channel 640x480 map, 2 threads); both agree within float rounding
    (tested). Plain float32 inference on the CPU takes OpenCV's separable filter instead (its twin,
    :func:`_smooth_shuffled_opencv`: 0.42 against 7.0 ms on the same map; equal within 5e-7, tested)."""
    if r == 1:
        return x
    return _smooth_shuffled_opencv(x, r) if _plain_cpu_inference(x) else _smooth_shuffled_torch(x, r)


def _smooth_shuffled_torch(x: Tensor, r: int) -> Tensor:
    """:func:`smooth_shuffled` by torch's pooling (any device, dtype, gradient, trace): replicate padding, then
    box averages of ``r`` taps, twice along each axis."""
    x = F.pad(x, (r - 1, r - 1, r - 1, r - 1), mode="replicate")
    for k in ((1, r), (1, r), (r, 1), (r, 1)):  # separable: 4r taps per pixel instead of 2r^2
        x = F.avg_pool2d(x, k, stride=1)
    return x


def _plain_cpu_inference(x: Tensor) -> bool:
    """True when ``x`` is a float32 CPU map that no gradient, trace, compilation or export follows (OpenCV may
    compute on it)."""
    return (
        x.device.type == "cpu"
        and x.dtype == torch.float32
        and not (x.requires_grad and torch.is_grad_enabled())
        and not torch.jit.is_tracing()
        and not torch.jit.is_scripting()
        and not torch.compiler.is_compiling()
    )


def _smooth_shuffled_opencv(x: Tensor, r: int) -> Tensor:
    """The twin of :func:`_smooth_shuffled_torch` by ``cv2.sepFilter2D`` per plane (the triangle along each axis,
    replicated border); float32 (B, C, H, W) in contiguous memory."""
    import cv2
    import numpy as np

    k = triangle_kernel(r).numpy()
    src = x.contiguous().numpy()
    out = np.empty_like(src)
    for b in range(src.shape[0]):
        for c in range(src.shape[1]):
            cv2.sepFilter2D(src[b, c], -1, k, k, dst=out[b, c], borderType=cv2.BORDER_REPLICATE)
    return torch.from_numpy(out)


class Decoder(nn.Module):
    """One branch's decoder. Attribute names follow the official state dict (``init_depth`` or
    ``init_enhanced``, ``c{s}_layer``, ``up_channels_c{s}``, ``up_skip_conv_c{s}``, ``up_skip_conv``,
    ``linear_pred1``)."""

    def __init__(
        self,
        in_channels: tuple[int, int, int, int],
        blocks: int,
        embed_dim: int,
        out_channels: int,
        task: Task,
        shuffle_smoothing: bool = False,
    ) -> None:
        super().__init__()
        self.shuffle_smoothing = shuffle_smoothing
        if embed_dim % 16:
            raise ValueError(f"embed_dim: expected a multiple of 16 (pixel shuffle by 4), got {embed_dim}")
        self.task = task
        c4 = in_channels[3]
        init = nn.Sequential(nn.Conv2d(c4, c4, 3, padding=1), nn.Conv2d(c4, c4, 1), nn.GELU())
        self.add_module(f"init_{task}", init)
        skip_total = 0
        for s in (3, 2, 1, 0):
            c = in_channels[s]
            self.add_module(f"c{s + 1}_layer", nn.ModuleList(MixDecoderBlock(c) for _ in range(blocks)))
            if s > 0:
                self.add_module(f"up_channels_c{s + 1}", nn.Conv2d(c, 4 * in_channels[s - 1], 1))
            r = _SKIP_SHUFFLE[s]
            if (2 * c) % (r * r):
                raise ValueError(f"in_channels[{s}]: 2*{c} is not divisible by the pixel-shuffle factor {r * r}")
            self.add_module(f"up_skip_conv_c{s + 1}", nn.Conv2d(c, 2 * c, 3, padding=1))
            skip_total += 2 * c // (r * r)
        self.up_skip_conv = nn.Conv2d(skip_total, embed_dim, 3, padding=1)
        self.linear_pred1 = nn.Conv2d(embed_dim // 16, out_channels, 3, padding=1)

    def start(self, c4: Tensor) -> Tensor:
        """conv3x3 -> conv1x1 -> GELU on the deepest encoder map."""
        return getattr(self, f"init_{self.task}")(c4)

    def mix(self, scale: int, x: Tensor, feat: Tensor) -> Tensor:
        """The mix-decoder blocks of ``scale`` (0..3 = c1..c4) on ``x`` with the encoder map ``feat``."""
        for blk in getattr(self, f"c{scale + 1}_layer"):
            x = blk(x, feat)
        return x

    def skip(self, scale: int, j: Tensor) -> Tensor:
        """Skip path: conv3x3(C -> 2C) -> PixelShuffle to 1/4 resolution (-> triangle filter if smoothing)."""
        return self._shuffle(getattr(self, f"up_skip_conv_c{scale + 1}")(j), _SKIP_SHUFFLE[scale])

    def up(self, scale: int, j: Tensor) -> Tensor:
        """Main path to the next finer scale: conv1x1(C -> 4 C_next) -> PixelShuffle(2) (-> triangle filter)."""
        return self._shuffle(getattr(self, f"up_channels_c{scale + 1}")(j), 2)

    def head(self, skips: list[Tensor]) -> Tensor:
        """concat skips (c4, c3, c2, c1) -> conv3x3 -> PixelShuffle(4) (-> triangle filter) -> conv3x3 (logits at
        full resolution)."""
        x = self._shuffle(self.up_skip_conv(torch.cat(skips, dim=1)), 4)
        return self.linear_pred1(x)

    def _shuffle(self, x: Tensor, r: int) -> Tensor:
        x = F.pixel_shuffle(x, r)
        return smooth_shuffled(x, r) if self.shuffle_smoothing else x


class JointBlock(nn.Module):
    """Cross-task coupling: u = concat[z_self, z_other]; conv1x1(conv1x1(u)) + conv1x1(u), no activation."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.joint_layer1 = nn.Sequential(nn.Conv2d(2 * dim, 2 * dim, 1), nn.Conv2d(2 * dim, dim, 1))
        self.joint_layer2 = nn.Conv2d(2 * dim, dim, 1)

    def forward(self, z_self: Tensor, z_other: Tensor) -> Tensor:
        u = torch.cat([z_self, z_other], dim=1)
        return self.joint_layer1(u) + self.joint_layer2(u)
