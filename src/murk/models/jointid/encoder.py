"""Joint-ID encoder: a MiT-b3-like hierarchical transformer whose blocks normalise with RLN.

References:
    Yang, Kang, Lee, Cho, "Transformer-Based Joint Image Enhancement and Depth Estimation for Underwater
    Environments", IEEE Sensors Journal 23(24), 2023, doi:10.1109/JSEN.2023.3338730 (the network).
    Xie et al., "SegFormer: Simple and Efficient Design for Semantic Segmentation with Transformers",
    NeurIPS 2021, arXiv:2105.15203 (the Mix Transformer stages, spatial-reduction attention, Mix-FFN).
    Song et al., "Vision Transformers for Single Image Dehazing", IEEE TIP 32, 2023, doi:10.1109/TIP.2023.3256763
    (RLN, the rescale-aware layer normalisation).

Layout: the token sequence of a stage is (B, N, C) with N = h * w in row-major order. :func:`tokens_to_map`
views it as a (B, C, h, w) map in channels-last memory *without a copy*, and :func:`map_to_tokens` goes back
(also without a copy when the map is channels-last), so the convolutions inside attention and Mix-FFN never
pay for a layout change.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn


def tokens_to_map(x: Tensor, h: int, w: int) -> Tensor:
    """View tokens (B, h*w, C) as a map (B, C, h, w) with channels-last strides (no copy)."""
    return x.reshape(x.shape[0], h, w, x.shape[2]).permute(0, 3, 1, 2)


def map_to_tokens(x: Tensor) -> Tensor:
    """Tokens (B, H*W, C) of a map (B, C, H, W); a view when the map is channels-last."""
    return x.permute(0, 2, 3, 1).flatten(1, 2)


def rln(
    x: Tensor,
    weight: Tensor,
    bias: Tensor,
    scale_w: Tensor,
    scale_b: Tensor,
    shift_w: Tensor,
    shift_b: Tensor,
    eps: float = 1e-5,
) -> tuple[Tensor, Tensor, Tensor]:
    """Rescale-aware layer normalisation of a token batch (B, N, C).

    Statistics are per sample over all channels and positions: mu = mean(x), sigma = sqrt(var(x) + eps)
    (population variance). Returns ``(y, rescale, rebias)``: y = (x - mu) / sigma * weight + bias, and the
    per-channel (B, 1, C) rescale = scale_w * sigma + scale_b and rebias = shift_w * mu + shift_b (the 1x1
    "meta" convolutions of a scalar), which the block applies to the attention or FFN output.

    Args:
        x: tokens (B, N, C).
        weight, bias: per-channel affine, C elements (any shape, e.g. (1, C, 1, 1)).
        scale_w, scale_b, shift_w, shift_b: the meta convolutions' weights (C elements each).
        eps: added to the variance.
    """
    if torch.onnx.is_in_onnx_export():  # the exporter needs a static normalised shape: plain reductions
        mu = x.mean(dim=(1, 2), keepdim=True)
        sigma = torch.sqrt((x - mu).square().mean(dim=(1, 2), keepdim=True) + eps)
        y = (x - mu) / sigma
    else:  # one fused pass: layer norm over (N, C) gives (x - mu) / sigma together with mu and 1 / sigma
        y, mu, rstd = torch.native_layer_norm(x, x.shape[1:], None, None, eps)
        sigma = torch.reciprocal(rstd)
    c = x.shape[-1]
    y = torch.addcmul(bias.reshape(1, 1, c), y, weight.reshape(1, 1, c))  # one kernel for y * w + b
    rescale = torch.addcmul(scale_b.reshape(1, 1, c), sigma, scale_w.reshape(1, 1, c))
    rebias = torch.addcmul(shift_b.reshape(1, 1, c), mu, shift_w.reshape(1, 1, c))
    return y, rescale, rebias


class RLN(nn.Module):
    """Rescale-aware LayerNorm (learned weights of :func:`rln`); state-dict names match the official model."""

    def __init__(self, dim: int, eps: float = 1e-5) -> None:
        super().__init__()
        self.eps = eps
        self.weight = nn.Parameter(torch.ones(1, dim, 1, 1))
        self.bias = nn.Parameter(torch.zeros(1, dim, 1, 1))
        self.meta1 = nn.Conv2d(1, dim, 1)  # sigma -> rescale
        self.meta2 = nn.Conv2d(1, dim, 1)  # mu -> rebias

    def forward(self, x: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        meta1, meta2 = self.meta1, self.meta2
        return rln(x, self.weight, self.bias, meta1.weight, _bias(meta1), meta2.weight, _bias(meta2), self.eps)


def _bias(conv: nn.Conv2d) -> Tensor:
    """The bias of a convolution built with one (``nn.Conv2d`` types ``bias`` as optional)."""
    if conv.bias is None:
        raise ValueError("RLN: expected the meta convolutions to have a bias")
    return conv.bias


class Attention(nn.Module):
    """Multi-head self-attention with spatial reduction of the keys/values (sr > 1: strided conv + LayerNorm)."""

    def __init__(self, dim: int, num_heads: int, sr_ratio: int) -> None:
        super().__init__()
        if dim % num_heads:
            raise ValueError(f"num_heads: expected a divisor of dim={dim}, got {num_heads}")
        self.num_heads = num_heads
        self.head_dim = dim // num_heads
        self.sr_ratio = sr_ratio
        self.q = nn.Linear(dim, dim)
        self.kv = nn.Linear(dim, 2 * dim)
        self.proj = nn.Linear(dim, dim)
        if sr_ratio > 1:
            self.sr = nn.Conv2d(dim, dim, kernel_size=sr_ratio, stride=sr_ratio)
            self.norm = nn.LayerNorm(dim)

    def forward(self, x: Tensor, h: int, w: int) -> Tensor:
        b, n, c = x.shape
        q = self.q(x).reshape(b, n, self.num_heads, self.head_dim).transpose(1, 2)
        if self.sr_ratio > 1:
            x = self.norm(map_to_tokens(self.sr(tokens_to_map(x, h, w))))
        kv = self.kv(x).reshape(b, -1, 2, self.num_heads, self.head_dim).permute(2, 0, 3, 1, 4)
        out = F.scaled_dot_product_attention(q, kv[0], kv[1])  # softmax(q k^T / sqrt(64)) v
        return self.proj(out.transpose(1, 2).reshape(b, n, c))


class DWConv(nn.Module):
    """Depthwise 3x3 convolution of a token sequence (the name nests as ``dwconv.dwconv`` in the state dict)."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.dwconv = nn.Conv2d(dim, dim, 3, padding=1, groups=dim)

    def forward(self, x: Tensor, h: int, w: int) -> Tensor:
        return map_to_tokens(self.dwconv(tokens_to_map(x, h, w)))


class MixFFN(nn.Module):
    """Mix-FFN: Linear(C, rC) -> depthwise 3x3 -> exact GELU -> Linear(rC, C)."""

    def __init__(self, dim: int, hidden: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(dim, hidden)
        self.dwconv = DWConv(hidden)
        self.fc2 = nn.Linear(hidden, dim)

    def forward(self, x: Tensor, h: int, w: int) -> Tensor:
        return self.fc2(F.gelu(self.dwconv(self.fc1(x), h, w)))


class Block(nn.Module):
    """Transformer block: x += A(RLN(x)) * rescale + rebias; x += M(RLN(x)) * rescale + rebias."""

    def __init__(self, dim: int, num_heads: int, sr_ratio: int, mlp_ratio: int) -> None:
        super().__init__()
        self.norm1 = RLN(dim)
        self.attn = Attention(dim, num_heads, sr_ratio)
        self.norm2 = RLN(dim)
        self.mlp = MixFFN(dim, dim * mlp_ratio)

    def forward(self, x: Tensor, h: int, w: int) -> Tensor:
        y, rescale, rebias = self.norm1(x)
        x = torch.addcmul(x + rebias, self.attn(y, h, w), rescale)  # x + (A * rescale + rebias)
        y, rescale, rebias = self.norm2(x)
        return torch.addcmul(x + rebias, self.mlp(y, h, w), rescale)


class PatchEmbed(nn.Module):
    """Overlapping patch embedding: conv (k 7 s 4 p 3 for stage 1, k 3 s 2 p 1 after) then LayerNorm."""

    def __init__(self, in_ch: int, dim: int, kernel: int, stride: int) -> None:
        super().__init__()
        self.proj = nn.Conv2d(in_ch, dim, kernel, stride=stride, padding=kernel // 2)
        self.norm = nn.LayerNorm(dim)

    def forward(self, x: Tensor) -> tuple[Tensor, int, int]:
        x = self.proj(x)
        h, w = x.shape[2], x.shape[3]
        return self.norm(map_to_tokens(x)), h, w


class Encoder(nn.Module):
    """Four MiT stages; returns the maps c1..c4 at 1/4, 1/8, 1/16, 1/32 of the input (channels-last views).

    Attribute names (``patch_embed{i}``, ``block{i}``, ``norm{i}``) follow the official state dict.
    """

    def __init__(
        self,
        embed_dims: tuple[int, int, int, int],
        depths: tuple[int, int, int, int],
        num_heads: tuple[int, int, int, int],
        sr_ratios: tuple[int, int, int, int],
        mlp_ratio: int,
    ) -> None:
        super().__init__()
        in_ch = 3
        for i in range(4):  # registration order = the official state-dict order
            kernel, stride = (7, 4) if i == 0 else (3, 2)
            self.add_module(f"patch_embed{i + 1}", PatchEmbed(in_ch, embed_dims[i], kernel, stride))
            in_ch = embed_dims[i]
        for i in range(4):
            blocks = [Block(embed_dims[i], num_heads[i], sr_ratios[i], mlp_ratio) for _ in range(depths[i])]
            self.add_module(f"block{i + 1}", nn.ModuleList(blocks))
            self.add_module(f"norm{i + 1}", nn.LayerNorm(embed_dims[i]))

    def forward(self, x: Tensor) -> list[Tensor]:
        feats = []
        for i in range(1, 5):
            x, h, w = getattr(self, f"patch_embed{i}")(x)
            for blk in getattr(self, f"block{i}"):
                x = blk(x, h, w)
            x = tokens_to_map(getattr(self, f"norm{i}")(x), h, w)
            feats.append(x)
        return feats
