"""Re-parameterisable convolution blocks: several linear branches while training, one plain convolution after.

A :class:`RepConv` block computes ``act(BN(conv3x3(x)) + BN(conv1x1(x)) + BN(x))`` during training (the identity
branch only when the block keeps the channel count and the resolution). Every branch is linear in ``x`` once
the batch norms use their running statistics (eval mode), so the sum is exactly one 3x3 convolution with a bias:
:func:`fold_rep_conv` computes it and :class:`PlainConv` (``act(conv3x3(x))``) runs it. Training sees the
better-conditioned multi-branch form; inference pays for one convolution.

References:
    X. Ding, X. Zhang, N. Ma, J. Han, G. Ding, J. Sun, "RepVGG: Making VGG-style ConvNets Great Again",
    CVPR 2021, doi:10.1109/CVPR46437.2021.01352.
    H. Yan, A. Li, X. Zhang, Z. Liu, Z. Shi, C. Zhu, L. Zhang, "MobileIE: An Extremely Lightweight and Effective
    ConvNet for Real-Time Image Enhancement on Mobile Devices", ICCV 2025, arXiv:2507.01838.
"""

from __future__ import annotations

import torch
from torch import Tensor, nn

NEGATIVE_SLOPE = 0.1
"""Slope of the leaky ReLU after every block (no dead units in a network this small)."""


def _act() -> nn.Module:
    return nn.LeakyReLU(NEGATIVE_SLOPE)


class RepConv(nn.Module):
    """Training-time block: 3x3 conv + BN, 1x1 conv + BN and (same shape) identity BN, summed, leaky ReLU.

    Args:
        in_channels: input channels.
        out_channels: output channels.
        stride: 1 or 2 (stride 2 halves the resolution; no identity branch then).
    """

    def __init__(self, in_channels: int, out_channels: int, stride: int = 1) -> None:
        super().__init__()
        if stride not in (1, 2):
            raise ValueError(f"stride: expected 1 or 2, got {stride}")
        self.in_channels, self.out_channels, self.stride = in_channels, out_channels, stride
        self.conv3 = nn.Conv2d(in_channels, out_channels, 3, stride, 1, bias=False)
        self.bn3 = nn.BatchNorm2d(out_channels)
        self.conv1 = nn.Conv2d(in_channels, out_channels, 1, stride, 0, bias=False)
        self.bn1 = nn.BatchNorm2d(out_channels)
        self.bn_id = nn.BatchNorm2d(out_channels) if in_channels == out_channels and stride == 1 else None
        self.act = _act()

    def forward(self, x: Tensor) -> Tensor:
        y = self.bn3(self.conv3(x)) + self.bn1(self.conv1(x))
        if self.bn_id is not None:
            y = y + self.bn_id(x)
        return self.act(y)


class PlainConv(nn.Module):
    """Inference-time block: one 3x3 convolution with bias and the leaky ReLU (what a :class:`RepConv` folds to)."""

    def __init__(self, in_channels: int, out_channels: int, stride: int = 1) -> None:
        super().__init__()
        self.in_channels, self.out_channels, self.stride = in_channels, out_channels, stride
        self.conv = nn.Conv2d(in_channels, out_channels, 3, stride, 1, bias=True)
        self.act = _act()

    def forward(self, x: Tensor) -> Tensor:
        return self.act(self.conv(x))


def fold_bn(kernel: Tensor, bn: nn.BatchNorm2d) -> tuple[Tensor, Tensor]:
    """``BN(conv(x; kernel))`` with running statistics as one convolution: the scaled kernel and the bias (in
    ``kernel``'s dtype)."""
    if bn.running_mean is None or bn.running_var is None:
        raise ValueError("fold_bn: the batch norm keeps no running statistics (track_running_stats=False)")
    mean, var = bn.running_mean.to(kernel), bn.running_var.to(kernel)
    scale = bn.weight.to(kernel) / torch.sqrt(var + bn.eps)
    return kernel * scale.reshape(-1, 1, 1, 1), bn.bias.to(kernel) - mean * scale


@torch.no_grad()
def fold_rep_conv(block: RepConv) -> PlainConv:
    """The :class:`PlainConv` equal to ``block`` in eval mode (to float rounding): the 1x1 kernel goes to the
    centre tap of the 3x3 kernel, the identity is a 3x3 kernel with a 1 at the centre of its own channel, and
    each branch's batch norm is folded into its kernel and bias before they are summed. Computed in float64."""
    dev = block.conv3.weight.device
    k3, b3 = fold_bn(block.conv3.weight.to(dev, torch.float64), block.bn3)
    k1 = torch.zeros_like(k3)
    k1[:, :, 1:2, 1:2] = block.conv1.weight.to(dev, torch.float64)
    k1, b1 = fold_bn(k1, block.bn1)
    kernel, bias = k3 + k1, b3 + b1
    if block.bn_id is not None:
        kid = torch.zeros_like(k3)
        idx = torch.arange(block.out_channels)
        kid[idx, idx, 1, 1] = 1.0
        kid, bid = fold_bn(kid, block.bn_id)
        kernel, bias = kernel + kid, bias + bid
    plain = PlainConv(block.in_channels, block.out_channels, block.stride).to(block.conv3.weight.device)
    assert plain.conv.bias is not None  # PlainConv builds its convolution with a bias
    plain.conv.weight.copy_(kernel.to(block.conv3.weight.dtype))
    plain.conv.bias.copy_(bias.to(block.conv3.weight.dtype))
    return plain


def conv_block(in_channels: int, out_channels: int, stride: int = 1, *, folded: bool = False) -> nn.Module:
    """A :class:`RepConv` (training form) or a :class:`PlainConv` (folded form) of the given shape."""
    cls = PlainConv if folded else RepConv
    return cls(in_channels, out_channels, stride)
