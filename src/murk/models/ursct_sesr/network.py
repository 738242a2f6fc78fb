"""URSCT-SESR, enhancement-only configuration, exact and checkpoint-compatible (clean-room, from
``docs/spec/baselines.md`` section 2).

A Swin-U-Net: 3x3 conv and a 2x2 patch embedding to 128x128 tokens, four encoder stages of Swin blocks
(32/64/128/256 channels, PatchMerging between), a decoder of UpSample + skip concatenation + Swin blocks, and
a PixelShuffle/bilinear enhancement upsampler back to full size; no global residual, no activation, no clamp.
Two departures from Swin that the weights depend on: the q/k/v projection is a 1x1 conv followed by a
depthwise 3x3 conv over the *grid of windows* (rows = windows in raster order, columns = tokens), so
neighbouring windows see each other; and q is multiplied by 8 (QK_SCALE) instead of d^-0.5.

The official code also convolves across the images of a batch (the last window of image b and the first of
image b+1 see each other). Here every image gets its own window grid (zero padding between images), which
equals running each image alone; ``URSCTConfig(batch_coupled=True)`` reproduces the official batch quirk.

Input: (B, 3, S, S) RGB in [0, 1] with S a multiple of 128 (the released weights were trained at 256; the
relative-position indices and shift masks are rebuilt for every S and are not part of the state dict). State-dict
names and shapes equal the official ``URSCT`` model's 899 learnable tensors (11,362,057 parameters); the
official file's 84 buffers are dropped on loading (:mod:`murk.models.ursct_sesr.checkpoint`).

Reference: Ren, Xu, Jiang, Yu, Zhang, Wang, Luo, "Reinforced Swin-Convs Transformer for Simultaneous
Underwater Sensing Scene Image Enhancement and Super-resolution", IEEE Trans. Geoscience and Remote Sensing
60 (2022), doi:10.1109/TGRS.2022.3205061. Official code MIT (Copyright (c) 2022 Tingdi Ren); not read.
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
HEADS = 8
SHIFT = 4
QK_SCALE = 8.0
"""q is MULTIPLIED by this (the official QK_SCALE), replacing Swin's d^-0.5."""
MASK_VALUE = -100.0
SIZE_MULTIPLE = 128
"""Input sizes must be multiples of this (every stage's token grid a multiple of the 8-token window)."""
TAP_NAMES = ("patch_embed", "layers.0", "layers.1", "layers.2")
"""Encoder taps of :meth:`URSCT.encoder_taps` (the golden fixture's ``release_config_taps``)."""


@dataclass(frozen=True)
class URSCTConfig:
    """Hyper-parameters; the defaults are the official ``configs/Enh_opt.yaml``."""

    img_size: int = 256
    """Side of the square input the model is built for (buffers); other multiples of 128 are computed on demand."""
    depths: tuple[int, int, int, int] = (8, 8, 8, 8)
    """Swin blocks per encoder stage (DEPTH_EN); decoder stage j has depths[3 - j]."""
    embed_dim: int = 32
    mlp_ratio: int = 4
    batch_coupled: bool = False
    """Reproduce the official batch quirk (the q/k/v depthwise conv runs over all images' windows at once)."""

    def __post_init__(self) -> None:
        if self.img_size < SIZE_MULTIPLE or self.img_size % SIZE_MULTIPLE:
            raise ValueError(f"img_size: expected a positive multiple of {SIZE_MULTIPLE}, got {self.img_size}")
        if len(self.depths) != 4 or any(d < 1 for d in self.depths):
            raise ValueError(f"depths: expected 4 positive block counts, got {self.depths}")
        if self.embed_dim < HEADS or self.embed_dim % HEADS:
            raise ValueError(f"embed_dim: expected a positive multiple of {HEADS}, got {self.embed_dim}")
        if self.mlp_ratio < 1:
            raise ValueError(f"mlp_ratio: expected >= 1, got {self.mlp_ratio}")

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (lists and numbers only), safe for ``torch.load(weights_only=True)`` and JSON."""
        return to_dict(self)


# ---------------------------------------------------------------------------------------------------------
# Functions (the work).


def relative_position_index(window: int = WINDOW) -> Tensor:
    """(N, N) int64, N = window^2: (yi - yj + w - 1)(2w - 1) + (xi - xj + w - 1) for tokens i, j (row-major)."""
    ys, xs = torch.meshgrid(torch.arange(window), torch.arange(window), indexing="ij")
    y, x = ys.flatten(), xs.flatten()
    dy = y[:, None] - y[None, :] + window - 1
    dx = x[:, None] - x[None, :] + window - 1
    return dy * (2 * window - 1) + dx


def window_geometry(resolution: int, block_index: int) -> tuple[int, int]:
    """(window, shift) of a Swin block: window 8 and shift 4 for odd blocks; a map of at most 8 tokens a side
    is one unshifted window."""
    if resolution <= WINDOW:
        return resolution, 0
    return WINDOW, SHIFT if block_index % 2 else 0


def shift_mask(resolution: int, window: int, shift: int) -> Tensor:
    """(windows, N, N) float mask of a shifted block: label each token of the R x R map by region (row < R-w: 0;
    R-w <= row < R-s: 1; else 2; columns likewise; label = 3*row region + column region), split into windows
    (raster), -100 between tokens of different labels, 0 otherwise."""

    def regions(n: int) -> Tensor:
        r = torch.arange(n)
        return (r >= n - window).long() + (r >= n - shift).long()

    labels = 3 * regions(resolution)[:, None] + regions(resolution)[None, :]
    nw = resolution // window
    lab = labels.view(nw, window, nw, window).permute(0, 2, 1, 3).reshape(nw * nw, window * window)
    return torch.where(lab[:, :, None] == lab[:, None, :], 0.0, MASK_VALUE)


def window_partition(x: Tensor, window: int) -> Tensor:
    """(B, R, R, C) -> (B * windows, window^2, C), windows in raster order, tokens row-major."""
    b, r, _, c = x.shape
    n = r // window
    return x.view(b, n, window, n, window, c).permute(0, 1, 3, 2, 4, 5).reshape(b * n * n, window * window, c)


def window_merge(windows: Tensor, batch: int, resolution: int, window: int) -> Tensor:
    """The inverse of :func:`window_partition`: -> (B, R, R, C)."""
    n = resolution // window
    c = windows.shape[-1]
    x = windows.view(batch, n, n, window, window, c).permute(0, 1, 3, 2, 4, 5)
    return x.reshape(batch, resolution, resolution, c)


def to_map(tokens: Tensor) -> Tensor:
    """(B, R*R, C) tokens -> (B, C, R, R) map (square)."""
    b, n, c = tokens.shape
    r = math.isqrt(n)
    return tokens.transpose(1, 2).reshape(b, c, r, r)


def to_tokens(x: Tensor) -> Tensor:
    """(B, C, H, W) map -> (B, H*W, C) tokens, token = row*W + col."""
    return x.flatten(2).transpose(1, 2)


# ---------------------------------------------------------------------------------------------------------
# Modules (weights; names follow the official state dict).


class WindowAttention(nn.Module):
    """Window attention with the depthwise q/k/v conv over the window grid and the relative-position bias."""

    relative_position_index: Tensor  # a buffer (register_buffer below); declared for the type checker

    def __init__(self, dim: int, batch_coupled: bool = False) -> None:
        super().__init__()
        self.dim = dim
        self.batch_coupled = batch_coupled
        self.qkv = nn.Conv2d(dim, 3 * dim, 1, bias=True)
        self.qkv_dwconv = nn.Conv2d(3 * dim, 3 * dim, 3, padding=1, groups=3 * dim, bias=True)
        self.proj = nn.Linear(dim, dim)
        self.relative_position_bias_table = nn.Parameter(torch.zeros((2 * WINDOW - 1) ** 2, HEADS))
        self.register_buffer("relative_position_index", relative_position_index(WINDOW), persistent=False)

    def forward(self, x: Tensor, images: int, mask: Tensor | None = None) -> Tensor:
        """x: (B * windows, N, C) of ``images`` images -> same shape.

        1. q/k/v: each image's windows as a C-channel (windows x N) map (all images as one map when
           ``batch_coupled``): 1x1 conv C -> 3C, depthwise 3x3 conv.
        2. Heads (channel = part*C + head*d + j); q *= 8; logits = q k^T + bias (+ ``mask`` (windows, N, N)
           per window index within each image); softmax; out = attn v; heads back (head-major); Linear.
        """
        bw, n, c = x.shape
        d = c // HEADS
        if self.batch_coupled:
            grid = x.permute(2, 0, 1).unsqueeze(0)  # (1, C, B*windows, N)
        else:
            grid = x.view(images, bw // images, n, c).permute(0, 3, 1, 2)  # (B, C, windows, N)
        qkv = self.qkv_dwconv(self.qkv(grid)).permute(0, 2, 3, 1).reshape(bw, n, 3, HEADS, d)
        q, k, v = qkv.permute(2, 0, 3, 1, 4).unbind(0)  # (Bw, heads, N, d) each
        attn = (q * QK_SCALE) @ k.transpose(-2, -1)
        bias = self.relative_position_bias_table[self.relative_position_index.view(-1)]
        attn = attn + bias.view(n, n, HEADS).permute(2, 0, 1).unsqueeze(0)
        if mask is not None:
            attn = attn.view(images, -1, HEADS, n, n) + mask.to(attn.dtype)[None, :, None]
            attn = attn.view(bw, HEADS, n, n)
        out = attn.softmax(dim=-1) @ v
        return self.proj(out.transpose(1, 2).reshape(bw, n, c))


class Mlp(nn.Module):
    def __init__(self, dim: int, hidden: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(dim, hidden)
        self.fc2 = nn.Linear(hidden, dim)

    def forward(self, x: Tensor) -> Tensor:
        return self.fc2(F.gelu(self.fc1(x)))


class SwinBlock(nn.Module):
    """x = x + W-MSA/SW-MSA(LN1(x)); x = x + MLP(LN2(x)) on (B, R*R, C) tokens (drop-path: identity)."""

    def __init__(self, dim: int, resolution: int, index: int, mlp_ratio: int, batch_coupled: bool) -> None:
        super().__init__()
        self.resolution = resolution
        self.index = index
        self.window, self.shift = window_geometry(resolution, index)
        self.norm1 = nn.LayerNorm(dim)
        self.attn = WindowAttention(dim, batch_coupled)
        self.norm2 = nn.LayerNorm(dim)
        self.mlp = Mlp(dim, dim * mlp_ratio)
        if self.shift:
            self.register_buffer("attn_mask", shift_mask(resolution, self.window, self.shift), persistent=False)
        else:
            self.attn_mask = None
        self._masks: dict[int, Tensor | None] = {}

    def _geometry(self, resolution: int, device: torch.device) -> tuple[int, int, Tensor | None]:
        """Window, shift and mask for ``resolution`` (the built one from the buffer, others computed once)."""
        if resolution == self.resolution:
            return self.window, self.shift, self.attn_mask
        window, shift = window_geometry(resolution, self.index)
        mask = self._masks.get(resolution)
        if shift and (mask is None or mask.device != device):
            mask = shift_mask(resolution, window, shift).to(device)
            self._masks[resolution] = mask
        return window, shift, mask if shift else None

    def forward(self, x: Tensor) -> Tensor:
        b, n, c = x.shape
        r = math.isqrt(n)
        window, shift, mask = self._geometry(r, x.device)
        y = self.norm1(x).view(b, r, r, c)
        if shift:
            y = torch.roll(y, shifts=(-shift, -shift), dims=(1, 2))
        y = self.attn(window_partition(y, window), b, mask)
        y = window_merge(y, b, r, window)
        if shift:
            y = torch.roll(y, shifts=(shift, shift), dims=(1, 2))
        x = x + y.reshape(b, n, c)
        return x + self.mlp(self.norm2(x))


class PatchMerging(nn.Module):
    """(B, R*R, C) -> (B, (R/2)^2, 2C): concat [even/even, odd row/even col, even row/odd col, odd/odd], LN,
    Linear 4C -> 2C (no bias)."""

    def __init__(self, dim: int) -> None:
        super().__init__()
        self.norm = nn.LayerNorm(4 * dim)
        self.reduction = nn.Linear(4 * dim, 2 * dim, bias=False)

    def forward(self, x: Tensor) -> Tensor:
        b, n, c = x.shape
        r = math.isqrt(n)
        x = x.view(b, r, r, c)
        x = torch.cat([x[:, 0::2, 0::2], x[:, 1::2, 0::2], x[:, 0::2, 1::2], x[:, 1::2, 1::2]], dim=-1)
        return self.reduction(self.norm(x.view(b, -1, 4 * c)))


class UpSample(nn.Module):
    """x2 upsampling of a token map: p = conv 1x1 C -> 4C/f, PReLU, PixelShuffle(2), conv; b = conv 1x1 (bias),
    PReLU, bilinear x2, conv -> C/f; out = 1x1 conv of [p, b]. ``halve`` (f = 2): tokens (B, 4R^2, C/2) out;
    otherwise (the enhancement upsampler, f = 1) a (B, C, 2R, 2R) map."""

    def __init__(self, dim: int, halve: bool = True) -> None:
        super().__init__()
        self.halve = halve
        out = dim // 2 if halve else dim
        self.up_p = nn.Sequential(
            nn.Conv2d(dim, 4 * out, 1, bias=False), nn.PReLU(), nn.PixelShuffle(2), nn.Conv2d(out, out, 1, bias=False)
        )
        self.up_b = nn.Sequential(
            nn.Conv2d(dim, dim, 1, bias=True),
            nn.PReLU(),
            nn.Upsample(scale_factor=2, mode="bilinear", align_corners=False),
            nn.Conv2d(dim, out, 1, bias=False),
        )
        self.conv = nn.Conv2d(2 * out, out, 1, bias=False)

    def forward(self, x: Tensor) -> Tensor:
        m = to_map(x)
        y = self.conv(torch.cat([self.up_p(m), self.up_b(m)], dim=1))
        return to_tokens(y) if self.halve else y


class EncoderStage(nn.Module):
    def __init__(self, dim: int, resolution: int, depth: int, mlp_ratio: int, merge: bool, coupled: bool) -> None:
        super().__init__()
        self.blocks = nn.ModuleList([SwinBlock(dim, resolution, i, mlp_ratio, coupled) for i in range(depth)])
        self.downsample = PatchMerging(dim) if merge else None

    def forward(self, x: Tensor) -> Tensor:
        for blk in self.blocks:
            x = blk(x)
        return x if self.downsample is None else self.downsample(x)


class DecoderStage(nn.Module):
    def __init__(self, dim: int, resolution: int, depth: int, mlp_ratio: int, upsample: bool, coupled: bool) -> None:
        super().__init__()
        self.blocks = nn.ModuleList([SwinBlock(dim, resolution, i, mlp_ratio, coupled) for i in range(depth)])
        self.upsample = UpSample(dim) if upsample else None

    def forward(self, x: Tensor) -> Tensor:
        for blk in self.blocks:
            x = blk(x)
        return x if self.upsample is None else self.upsample(x)


class PatchEmbed(nn.Module):
    def __init__(self, dim: int) -> None:
        super().__init__()
        self.proj = nn.Conv2d(dim, dim, 2, stride=2)
        self.norm = nn.LayerNorm(dim)

    def forward(self, x: Tensor) -> Tensor:
        return self.norm(to_tokens(self.proj(x)))


class URSCT(nn.Module):
    """The official ``URSCT`` (Enh_opt.yaml): (B, 3, S, S) RGB in [0, 1] -> (B, 3, S, S), unclamped."""

    def __init__(self, config: URSCTConfig | None = None) -> None:
        super().__init__()
        self.config = cfg = config or URSCTConfig()
        c, r0 = cfg.embed_dim, cfg.img_size // 2
        coupled = cfg.batch_coupled
        self.prelu = nn.PReLU()
        """Defined by the official model and never used (kept for checkpoint loading)."""
        self.conv_first = nn.Conv2d(3, c, 3, padding=1)
        self.patch_embed = PatchEmbed(c)
        self.layers = nn.ModuleList(
            [
                EncoderStage(c * 2**i, r0 // 2**i, cfg.depths[i], cfg.mlp_ratio, merge=i < 3, coupled=coupled)
                for i in range(4)
            ]
        )
        self.norm = nn.LayerNorm(8 * c)
        self.layers_up = nn.ModuleList([UpSample(8 * c)])
        self.concat_back_dim = nn.ModuleList([nn.Identity()])
        for j in range(1, 4):
            dim, res = 8 * c // 2**j, r0 // 8 * 2**j
            self.layers_up.append(DecoderStage(dim, res, cfg.depths[3 - j], cfg.mlp_ratio, j < 3, coupled))
            self.concat_back_dim.append(nn.Linear(2 * dim, dim))
        self.norm_up = nn.LayerNorm(c)
        self.up = UpSample(c, halve=False)
        self.output = nn.Conv2d(c, 3, 3, padding=1, bias=False)

    def _check(self, x: Any) -> None:
        if not isinstance(x, Tensor):
            raise TypeError(f"x: expected a torch.Tensor (B, 3, S, S), got {type(x).__name__}")
        if x.ndim != 4 or x.shape[1] != 3:
            raise ShapeError(f"x: expected shape (B, 3, S, S), got {tuple(x.shape)}")
        h, w = x.shape[-2:]
        if h != w or h % SIZE_MULTIPLE:
            raise ShapeError(f"x: expected a square input whose side is a multiple of {SIZE_MULTIPLE}, got {h}x{w}")

    def _encode(self, x: Tensor) -> tuple[Tensor, list[Tensor]]:
        """Final encoder tokens (after ``norm``) and the stage inputs skip_0..skip_3, plus skip_4 = stage 3's
        output before ``norm``, as a list [skip_0, ..., skip_3, stage-3 output]."""
        x = self.patch_embed(self.conv_first(x))
        skips = []
        for layer in self.layers:
            skips.append(x)
            x = layer(x)
        skips.append(x)
        return self.norm(x), skips

    def encoder_taps(self, x: Tensor) -> dict[str, Tensor]:
        """The golden fixture's internal taps: ``patch_embed`` (tokens after its LayerNorm = skip_0) and
        ``layers.i`` (output of encoder stage i incl. its PatchMerging = skip_{i+1}) for i = 0, 1, 2, each
        (B, tokens, channels). Runs encoder stages 0-2 only."""
        self._check(x)
        t = self.patch_embed(self.conv_first(x))
        taps = {"patch_embed": t}
        for i in range(3):
            t = self.layers[i](t)
            taps[f"layers.{i}"] = t
        return taps

    def forward(self, x: Tensor) -> Tensor:
        """(B, 3, S, S) -> (B, 3, S, S), S a multiple of 128.

        Raises:
            TypeError: not a tensor.
            ShapeError: not (B, 3, S, S) with S a multiple of 128.
        """
        self._check(x)
        x, skips = self._encode(x)
        x = self.layers_up[0](x)
        for j in range(1, 4):
            x = self.concat_back_dim[j](torch.cat([x, skips[3 - j]], dim=-1))
            x = self.layers_up[j](x)
        return self.output(self.up(self.norm_up(x)))


UNUSED_PARAMETERS = ("prelu.weight",)
"""Parameters the official model defines and never uses (they get no gradient)."""
BUFFER_SUFFIXES = ("relative_position_index", "attn_mask")
"""Buffers the official state dict carries (they depend on the input size only; murk rebuilds them)."""


def build_ursct(config: URSCTConfig | dict[str, Any] | None = None, *, init: bool = True) -> URSCT:
    """The official Enh_opt.yaml configuration (or ``config``), initialised as the official code does from
    scratch: Linear weights trunc-normal std 0.02 (bounds +-2), biases 0; LayerNorm 1/0; relative tables
    trunc-normal std 0.02; convs PyTorch default; PReLU 0.25.

    Raises:
        TypeError: ``config`` is neither a URSCTConfig, a dict nor None.
        ValueError: invalid values or unknown keys in a dict.
    """
    model = URSCT(as_config(URSCTConfig, config))
    if init:
        init_weights(model)
    return model


@torch.no_grad()
def init_weights(model: URSCT) -> URSCT:
    """The official initialisation (see :func:`build_ursct`), in place; convs keep PyTorch's default."""
    for m in model.modules():
        if isinstance(m, nn.Linear):
            nn.init.trunc_normal_(m.weight, std=0.02, a=-2.0, b=2.0)
            if m.bias is not None:
                nn.init.zeros_(m.bias)
        elif isinstance(m, nn.LayerNorm):
            nn.init.ones_(m.weight)
            nn.init.zeros_(m.bias)
        elif isinstance(m, WindowAttention):
            nn.init.trunc_normal_(m.relative_position_bias_table, std=0.02, a=-2.0, b=2.0)
    return model
