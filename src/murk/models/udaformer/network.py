"""UDAformer, exact and checkpoint-compatible (clean-room, from ``docs/spec/baselines.md`` section 1).

A Restormer-style U-Net of transformer blocks at four levels (36/72/144/288 channels): level 1 mixes channel
attention (CATB) with shifted-window pixel self-attention (SWB) through a learnt weight ``alpha``, the latent
level mixes channel attention with global latent pixel attention (LPB) through ``belta``; output = input +
a 1x1 projection (no activation, no clamp). Any H, W works; the official weights expect **BGR** in [0, 1].
State-dict names and shapes equal the official ``UFUformer`` (206 tensors, 9,601,422 parameters, no buffers),
so the released checkpoint loads with ``strict=True``.

Reference: Shen, Xu, Luo, Song, He, "UDAformer: Underwater image enhancement based on dual attention
transformer", Computers & Graphics 111 (2023) 77-88, doi:10.1016/j.cag.2023.01.009. The official code carries
no licence: it was not read; this module follows the spec only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from murk._config import as_config, to_dict
from murk.errors import ShapeError

WINDOW = 8
"""Side of the pixel-attention windows (the official ``window_size``)."""
SHIFT = 3
"""Cyclic shift of the second window pass (the official ``shift_size``)."""
HEADS = 2
"""Heads of the channel attention at every level."""
FFN_EXPANSION = 3
"""The FFN's gated hidden width in units of C (the 1x1 projection makes 2 x 3C channels)."""
NORM_EPS = 1e-5
MASK_VALUE = -100.0


@dataclass(frozen=True)
class UDAformerConfig:
    """Hyper-parameters; the defaults are the official ``UFUformer()`` that ``test.py`` builds."""

    dim: int = 36
    """Channels at level 1 (x2 per level below)."""
    blocks: tuple[int, int, int, int] = (2, 2, 2, 2)
    """Blocks at levels 1, 2, 3 and in the latent (the decoder mirrors levels 1-3)."""
    refinement_blocks: int = 2

    def __post_init__(self) -> None:
        if self.dim < 2 or self.dim % 2:
            raise ValueError(f"dim: expected an even number of channels >= 2, got {self.dim}")
        if len(self.blocks) != 4 or any(b < 1 for b in self.blocks):
            raise ValueError(f"blocks: expected 4 positive block counts, got {self.blocks}")
        if self.refinement_blocks < 0:
            raise ValueError(f"refinement_blocks: expected >= 0, got {self.refinement_blocks}")

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (lists and numbers only), safe for ``torch.load(weights_only=True)`` and JSON."""
        return to_dict(self)


# ---------------------------------------------------------------------------------------------------------
# Functions (the work); the modules below only hold weights.


def bias_free_norm(x: Tensor, weight: Tensor) -> Tensor:
    """Per pixel over channels: x / sqrt(var_c(x) + 1e-5) * w, biased variance, x not centred. x: (B, C, H, W)."""
    var = x.var(dim=1, keepdim=True, unbiased=False)
    return x / torch.sqrt(var + NORM_EPS) * weight.view(1, -1, 1, 1)


def gated_ffn(x: Tensor, project_in: nn.Conv2d, dwconv: nn.Conv2d, project_out: nn.Conv2d) -> Tensor:
    """1x1 C -> 6C, depthwise 3x3, ReLU(first 3C) * (last 3C), 1x1 3C -> C."""
    a, b = dwconv(project_in(x)).chunk(2, dim=1)
    return project_out(F.relu(a) * b)


def channel_attention(x: Tensor, qkv_conv: nn.Conv2d, qkv_dwconv: nn.Conv2d, project_out: nn.Conv2d) -> Tensor:
    """CA: per head (d = C/2 channels), A = softmax(q k^T / sqrt(d)) over (d x d), q and k L2-normalised over
    the pixels; out = A v; heads in order; 1x1 C -> C. No learnable temperature."""
    b, c, h, w = x.shape
    d = c // HEADS
    q, k, v = (t.reshape(b, HEADS, d, h * w) for t in qkv_dwconv(qkv_conv(x)).chunk(3, dim=1))
    q, k = F.normalize(q, dim=-1), F.normalize(k, dim=-1)
    attn = (q @ k.transpose(-2, -1) / math.sqrt(d)).softmax(dim=-1)
    return project_out((attn @ v).reshape(b, c, h, w))


@dataclass(frozen=True)
class PackGeometry:
    """What :func:`unpack` needs to invert :func:`pack`."""

    batch: int
    height: int
    width: int
    tiles_h: int
    tiles_w: int


def pack(x: Tensor, window: int = WINDOW) -> tuple[Tensor, PackGeometry]:
    """The official window split (NOT the usual one): zero-pad H, W at the bottom/right to multiples of
    ``window``, cut (B, C, nh, nw) tiles of window x window numbered channel-major then tile row then tile
    column, and reinterpret that list as (B*L, C, w, w): packed item q holds tiles q*C .. q*C + C - 1.
    Items never mix images."""
    b, c, h, w = x.shape
    ph, pw = -h % window, -w % window
    if ph or pw:
        x = F.pad(x, (0, pw, 0, ph))
    nh, nw = (h + ph) // window, (w + pw) // window
    tiles = x.reshape(b, c, nh, window, nw, window).permute(0, 1, 2, 4, 3, 5).contiguous()
    return tiles.view(b * nh * nw, c, window, window), PackGeometry(b, h, w, nh, nw)


def unpack(p: Tensor, geo: PackGeometry) -> Tensor:
    """The exact inverse of :func:`pack`, cropped back to H x W."""
    _, c, window, _ = p.shape
    tiles = p.contiguous().view(geo.batch, c, geo.tiles_h, geo.tiles_w, window, window)
    x = tiles.permute(0, 1, 2, 4, 3, 5).reshape(geo.batch, c, geo.tiles_h * window, geo.tiles_w * window)
    return x[:, :, : geo.height, : geo.width]


def shifted_window_mask(
    height: int, width: int, window: int = WINDOW, shift: int = SHIFT, device: torch.device | str | None = None
) -> Tensor:
    """(L, w*w, w*w) mask of the shifted pass over the padded height x width grid: region per row 0 if
    r < H - w, 1 if H - w <= r < H - shift, else 2 (columns likewise), label = 3*row region + column region;
    0 where the two tokens' labels are equal, -100 elsewhere. Tiles in raster order."""

    def regions(n: int) -> Tensor:
        r = torch.arange(n, device=device)
        return (r >= n - window).long() + (r >= n - shift).long()

    labels = 3 * regions(height)[:, None] + regions(width)[None, :]
    nh, nw = height // window, width // window
    lab = labels.view(nh, window, nw, window).permute(0, 2, 1, 3).reshape(nh * nw, window * window)
    same = lab[:, :, None] == lab[:, None, :]
    return torch.where(same, 0.0, MASK_VALUE)


def window_pixel_attention(
    p: Tensor,
    qkv_conv: nn.Conv2d,
    qkv_dwconv: nn.Conv2d,
    project_out: nn.Conv2d,
    mask: Tensor | None = None,
    images: int = 1,
) -> Tensor:
    """Single-head attention inside each packed item (N, C, w, w): q, k, v (N, C, T) with T = w*w tokens;
    q, k L2-normalised over the tokens; S = q^T k / 8 (T x T), plus ``mask`` (L, T, T) added by item index
    within each of the ``images``; softmax over the last axis; O = v S; 3x3 conv C -> C."""
    n, c, h, w = p.shape
    q, k, v = (t.reshape(n, c, h * w) for t in qkv_dwconv(qkv_conv(p)).chunk(3, dim=1))
    q, k = F.normalize(q, dim=-1), F.normalize(k, dim=-1)
    s = q.transpose(-2, -1) @ k / 8.0
    if mask is not None:
        s = (s.view(images, -1, h * w, h * w) + mask.to(s.dtype)).view(n, h * w, h * w)
    return project_out((v @ s.softmax(dim=-1)).view(n, c, h, w))


def lpa(x: Tensor, qkv: nn.Conv2d, qkv_dwconv: nn.Conv2d, project_out: nn.Conv2d) -> Tensor:
    """Latent pixel attention over the whole map: q, k, v (B, C, N), q and k L2-normalised over N,
    S = softmax(q^T k) (N x N, no scaling), O = v S, 3x3 conv C -> C. Memory grows with N^2."""
    b, c, h, w = x.shape
    q, k, v = (t.reshape(b, c, h * w) for t in qkv_dwconv(qkv(x)).chunk(3, dim=1))
    q, k = F.normalize(q, dim=-1), F.normalize(k, dim=-1)
    s = (q.transpose(-2, -1) @ k).softmax(dim=-1)
    return project_out((v @ s).view(b, c, h, w))


def pad_odd(x: Tensor) -> Tensor:
    """One zero row at the TOP if H is odd, one zero column at the LEFT if W is odd (Down/Up)."""
    h, w = x.shape[-2:]
    return F.pad(x, (w % 2, 0, h % 2, 0)) if (h % 2 or w % 2) else x


def join(up: Tensor, skip: Tensor) -> Tensor:
    """Pad (or crop, for negative differences) ``up`` to ``skip``'s size, floor(d/2) before and the rest after;
    then concatenate [skip, up] on channels."""
    dy, dx = skip.shape[-2] - up.shape[-2], skip.shape[-1] - up.shape[-1]
    if dy or dx:
        up = F.pad(up, (dx // 2, dx - dx // 2, dy // 2, dy - dy // 2))
    return torch.cat([skip, up], dim=1)


# ---------------------------------------------------------------------------------------------------------
# Modules (weights; names follow the official state dict).


def _conv(cin: int, cout: int, k: int, groups: int = 1) -> nn.Conv2d:
    return nn.Conv2d(cin, cout, k, stride=1, padding=k // 2, groups=groups, bias=False)


class _NormBody(nn.Module):
    def __init__(self, c: int) -> None:
        super().__init__()
        self.weight = nn.Parameter(torch.ones(c))


class BiasFreeNorm(nn.Module):
    """Bias-free channel norm (key ``<x>.body.weight``)."""

    def __init__(self, c: int) -> None:
        super().__init__()
        self.body = _NormBody(c)

    def forward(self, x: Tensor) -> Tensor:
        return bias_free_norm(x, self.body.weight)


class FFN(nn.Module):
    def __init__(self, c: int) -> None:
        super().__init__()
        hidden = FFN_EXPANSION * c
        self.project_in = _conv(c, 2 * hidden, 1)
        self.dwconv = _conv(2 * hidden, 2 * hidden, 3, groups=2 * hidden)
        self.project_out = _conv(hidden, c, 1)

    def forward(self, x: Tensor) -> Tensor:
        return gated_ffn(x, self.project_in, self.dwconv, self.project_out)


class ChannelAttention(nn.Module):
    def __init__(self, c: int) -> None:
        super().__init__()
        self.qkv_conv = _conv(c, 3 * c, 1)
        self.qkv_dwconv = _conv(3 * c, 3 * c, 3, groups=3 * c)
        self.project_out = _conv(c, c, 1)

    def forward(self, x: Tensor) -> Tensor:
        return channel_attention(x, self.qkv_conv, self.qkv_dwconv, self.project_out)


class SWPSA(nn.Module):
    """Shifted-window pixel self-attention: a plain window pass, then a pass on the map rolled by -3, -3 with
    the shift mask, rolled back."""

    def __init__(self, c: int) -> None:
        super().__init__()
        self.qkv_conv = _conv(c, 3 * c, 1)
        self.qkv_dwconv = _conv(3 * c, 3 * c, 3, groups=3 * c)
        self.project_out = _conv(c, c, 3)
        self.qkv_conv1 = _conv(c, 3 * c, 1)
        self.qkv_dwconv1 = _conv(3 * c, 3 * c, 3, groups=3 * c)
        self.project_out1 = _conv(c, c, 3)

    def forward(self, x: Tensor) -> Tensor:
        p, geo = pack(x)
        y = unpack(window_pixel_attention(p, self.qkv_conv, self.qkv_dwconv, self.project_out), geo)
        p, geo = pack(torch.roll(y, shifts=(-SHIFT, -SHIFT), dims=(2, 3)))
        mask = shifted_window_mask(geo.tiles_h * WINDOW, geo.tiles_w * WINDOW, device=p.device)
        y = window_pixel_attention(p, self.qkv_conv1, self.qkv_dwconv1, self.project_out1, mask, geo.batch)
        return torch.roll(unpack(y, geo), shifts=(SHIFT, SHIFT), dims=(2, 3))


class LatentPixelAttention(nn.Module):
    def __init__(self, c: int) -> None:
        super().__init__()
        self.qkv = _conv(c, 3 * c, 1)
        self.qkv_dwconv = _conv(3 * c, 3 * c, 3, groups=3 * c)
        self.project_out = _conv(c, c, 3)

    def forward(self, x: Tensor) -> Tensor:
        return lpa(x, self.qkv, self.qkv_dwconv, self.project_out)


class Block(nn.Module):
    """x = x + attn(LN1(x)); x = x + FFN(LN2(x)). CATB, SWB and LPB differ by ``attn`` only."""

    def __init__(self, c: int, attn: nn.Module) -> None:
        super().__init__()
        self.norm1 = BiasFreeNorm(c)
        self.attn = attn
        self.norm2 = BiasFreeNorm(c)
        self.ffn = FFN(c)

    def forward(self, x: Tensor) -> Tensor:
        x = x + self.attn(self.norm1(x))
        return x + self.ffn(self.norm2(x))


def catb(c: int) -> Block:
    return Block(c, ChannelAttention(c))


class Dual(nn.Module):
    """Level-1 block: alpha * SWB(x) + (1 - alpha) * CATB(x)."""

    def __init__(self, c: int) -> None:
        super().__init__()
        self.alpha = nn.Parameter(torch.full((1,), 0.5))
        self.globa = catb(c)
        self.pixel = Block(c, SWPSA(c))

    def forward(self, x: Tensor) -> Tensor:
        return self.alpha * self.pixel(x) + (1 - self.alpha) * self.globa(x)


class DualLatent(nn.Module):
    """Latent block: belta * LPB(x) + (1 - belta) * CATB(x)."""

    def __init__(self, c: int) -> None:
        super().__init__()
        self.belta = nn.Parameter(torch.full((1,), 0.5))
        self.csa = catb(c)
        self.pixel = Block(c, LatentPixelAttention(c))

    def forward(self, x: Tensor) -> Tensor:
        return self.belta * self.pixel(x) + (1 - self.belta) * self.csa(x)


class Down(nn.Module):
    """Odd padding (top/left), 3x3 conv C -> C/2, PixelUnshuffle(2) -> 2C at half size."""

    def __init__(self, c: int) -> None:
        super().__init__()
        self.body = nn.Sequential(_conv(c, c // 2, 3), nn.PixelUnshuffle(2))

    def forward(self, x: Tensor) -> Tensor:
        return self.body(pad_odd(x))


class Up(nn.Module):
    """Odd padding (top/left), 3x3 conv C -> 2C, PixelShuffle(2) -> C/2 at double size."""

    def __init__(self, c: int) -> None:
        super().__init__()
        self.body = nn.Sequential(_conv(c, 2 * c, 3), nn.PixelShuffle(2))

    def forward(self, x: Tensor) -> Tensor:
        return self.body(pad_odd(x))


class PatchEmbed(nn.Module):
    def __init__(self, c: int) -> None:
        super().__init__()
        self.proj = _conv(3, c, 3)

    def forward(self, x: Tensor) -> Tensor:
        return self.proj(x)


class UDAformer(nn.Module):
    """The official ``UFUformer``: (B, 3, H, W) in [0, 1] (BGR for the released weights) -> (B, 3, H, W),
    unclamped. Any H, W >= 1; no coupling across the batch."""

    def __init__(self, config: UDAformerConfig | None = None) -> None:
        super().__init__()
        self.config = cfg = config or UDAformerConfig()
        c, (n1, n2, n3, n4) = cfg.dim, cfg.blocks
        self.patch_embed = PatchEmbed(c)
        self.encoder_level1 = nn.Sequential(*[Dual(c) for _ in range(n1)])
        self.down1_2 = Down(c)
        self.encoder_level2 = nn.Sequential(*[catb(2 * c) for _ in range(n2)])
        self.down2_3 = Down(2 * c)
        self.encoder_level3 = nn.Sequential(*[catb(4 * c) for _ in range(n3)])
        self.down3_4 = Down(4 * c)
        self.latent = nn.Sequential(*[DualLatent(8 * c) for _ in range(n4)])
        self.up4_3 = Up(8 * c)
        self.reduce_chan_level3 = _conv(8 * c, 4 * c, 1)
        self.decoder_level3 = nn.Sequential(*[catb(4 * c) for _ in range(n3)])
        self.up3_2 = Up(4 * c)
        self.reduce_chan_level2 = _conv(4 * c, 2 * c, 1)
        self.decoder_level2 = nn.Sequential(*[catb(2 * c) for _ in range(n2)])
        self.up2_1 = Up(2 * c)
        self.reduce_chan_level1 = _conv(2 * c, c, 1)
        self.decoder_level1 = nn.Sequential(*[Dual(c) for _ in range(n1)])
        self.reduce_chan_ref = _conv(2 * c, c, 1)
        """Defined by the official model and never used (kept for checkpoint loading)."""
        self.refinement = nn.Sequential(*[catb(c) for _ in range(cfg.refinement_blocks)])
        self.output = _conv(c, 3, 1)

    def forward(self, x: Tensor) -> Tensor:
        """(B, 3, H, W) -> input + the network's residual (no activation, no clamp).

        Raises:
            TypeError: not a tensor.
            ShapeError: not (B, 3, H, W).
        """
        if not isinstance(x, Tensor):
            raise TypeError(f"x: expected a torch.Tensor (B, 3, H, W), got {type(x).__name__}")
        if x.ndim != 4 or x.shape[1] != 3:
            raise ShapeError(f"x: expected shape (B, 3, H, W), got {tuple(x.shape)}")
        e1 = self.encoder_level1(self.patch_embed(x))
        e2 = self.encoder_level2(self.down1_2(e1))
        e3 = self.encoder_level3(self.down2_3(e2))
        z = self.latent(self.down3_4(e3))
        d3 = self.decoder_level3(self.reduce_chan_level3(join(self.up4_3(z), e3)))
        d2 = self.decoder_level2(self.reduce_chan_level2(join(self.up3_2(d3), e2)))
        d1 = self.decoder_level1(self.reduce_chan_level1(join(self.up2_1(d2), e1)))
        return self.output(self.refinement(d1)) + x


UNUSED_MODULES = ("reduce_chan_ref",)
"""Modules the official model defines and never uses (they get no gradient)."""


def build_udaformer(config: UDAformerConfig | dict[str, Any] | None = None) -> UDAformer:
    """The official configuration (dim 36, blocks [2, 2, 2, 2], 2 refinement blocks) or ``config``, with
    PyTorch's default initialisation (the official model has no custom init; ``alpha``/``belta`` = 0.5).

    Raises:
        TypeError: ``config`` is neither a UDAformerConfig, a dict nor None.
        ValueError: invalid values or unknown keys in a dict.
    """
    return UDAformer(as_config(UDAformerConfig, config))
