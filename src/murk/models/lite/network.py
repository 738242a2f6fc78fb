"""``lite``: a small convolutional restorer for real-time CPU inference (about 90 K parameters folded).

The network predicts, at 1/4 of the input resolution, a per-pixel and per-channel gain and offset, upsamples
them bilinearly to full resolution and applies them to the input: ``enhanced = gain * x + offset``. That is
the form of the inverse of the image formation model, Eq. (1) of the paper: with transmission ``t_c`` and
backscatter ``B_c``, ``J_c = I_c / t_c - B_c (1 - t_c) / t_c``, a gain and an offset per colour channel that
vary smoothly with distance. Working at 1/4 resolution keeps the convolutions cheap; full-resolution detail
is never resampled (it passes through the per-pixel affine map), so there is no sub-pixel grid to draw.

Working resolution (as HDRNet's fixed low-resolution input): a frame larger than ``work_area_px`` (the area of
the training crops, 128x160) is first area-downsampled to about that many pixels (:func:`work_size`: multiples
of 16, aspect kept to within the rounding), the coefficients are computed from that small image and upsampled
bilinearly to the frame. The network therefore sees a 640x480 or 1280x720 frame at the scale of its training
crops, whatever the frame size, and its cost hardly grows with the frame. Without this, its fixed receptive
field saw an ever smaller part of the scene as frames grew (measured: held-out scenes at 640x480 went from
17.9 dB in to 16.0 dB out; with it, 24.2 dB). Frames up to ``work_area_px`` run at their own resolution.

Edge-aware upsampling (the fast guided filter: He, Sun, Tang, "Guided Image Filtering", IEEE TPAMI 35(6), 2013,
doi:10.1109/TPAMI.2012.213, upsampled as in He and Sun, "Fast Guided Filter", arXiv:1505.00996): plain bilinear
upsampling of coarse coefficient maps smears them across object outlines and leaves halos (a dark or
bright rim a few coefficient cells wide around a diver or a fish). Instead, on the coefficient grid each map is
fitted locally (box of ``2 guide_radius + 1`` cells) as a linear function ``a * Y + b`` of the luma ``Y`` of the
pooled working image; ``a`` and ``b`` are box-averaged, upsampled bilinearly and evaluated with the luma of the
full-resolution frame, so the coefficients change where the frame's luma changes. ``guide_radius: 0`` gives
plain bilinear upsampling.

Structure (``widths = (c1, c2, c3)`` channels at 1/4, 1/8, 1/16 resolution; ``blocks`` per scale):
``avg_pool x4 -> stem -> c1 blocks -> down -> c2 blocks -> down -> c3 blocks -> + global context ->
1x1, bilinear x2, + skip -> block -> 1x1, bilinear x2, + skip -> block -> 1x1 head (6 channels) -> bounded
log-gain and offset -> guided upsampling to the frame -> gain * x + offset``. Every block is a
:class:`~murk.models.lite.blocks.RepConv` while training and one 3x3 convolution after :func:`reparameterize`.

``forward`` takes RGB in [0, 1] (no normalisation), height and width multiples of :data:`SIZE_MULTIPLE`, and
returns the enhanced image, not clamped (the restorer clamps; training sees the unclamped values). No depth.

References:
    Yun et al., "Robust Image Processing Techniques for Construction Environment Monitoring Using Underwater
    Robots", Eq. (1) (the image formation model whose inverse the output layer has the form of).
    M. Gharbi, J. Chen, J. T. Barron, S. W. Hasinoff, F. Durand, "Deep Bilateral Learning for Real-Time Image
    Enhancement", ACM TOG 36(4), 2017, doi:10.1145/3072959.3073592 (low-resolution coefficients applied at full
    resolution).
    X. Ding et al., "RepVGG", CVPR 2021, doi:10.1109/CVPR46437.2021.01352 (re-parameterised blocks).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from murk._config import from_dict, to_dict
from murk.errors import ShapeError
from murk.models.lite.blocks import RepConv, conv_block, fold_rep_conv
from murk.models.padding import area_size
from murk.models.wrapped import unwrap_as
from murk.restore_ops.exposure import LUMA_601, exposure_gain_torch

LiteVariant = Literal["base", "wide", "tiny"]

SIZE_MULTIPLE = 16
"""Input height and width must be multiples of this (pooling x4, then two stride-2 blocks)."""
POOL = 4
"""The coefficients are computed at 1/POOL of the input resolution."""


@dataclass(frozen=True)
class LiteConfig:
    """Widths and depths of a ``lite`` network. The defaults are the shipped ``base`` variant."""

    widths: tuple[int, int, int] = (16, 32, 48)
    """Channels at 1/4, 1/8 and 1/16 of the input resolution."""
    blocks: tuple[int, int, int] = (1, 1, 2)
    """Encoder blocks at each scale after the stem / the downsampling block."""
    max_log_gain: float = 2.0
    """The gain is ``exp(g)`` with ``|g| <= max_log_gain`` (soft bound by tanh): 0.14x to 7.4x."""
    max_offset: float = 1.0
    """The offset is soft-bounded to ``[-max_offset, max_offset]`` (tanh)."""
    guide_radius: int = 2
    """Box radius (coefficient cells) of the guided upsampling; 0: plain bilinear."""
    guide_eps: float = 1e-3
    """Regularisation of the guided upsampling (luma variance units): larger is closer to bilinear."""
    work_area_px: int = 128 * 160
    """Larger frames are area-downsampled to about this many pixels for the coefficients (:func:`work_size`);
    the area of the training crops (``data.crop_hw``). 0: always the frame's own resolution."""

    def __post_init__(self) -> None:
        if len(self.widths) != 3 or any(int(w) < 1 for w in self.widths):
            raise ValueError(f"widths: expected three positive channel counts, got {self.widths}")
        if len(self.blocks) != 3 or any(int(b) < 0 for b in self.blocks):
            raise ValueError(f"blocks: expected three block counts >= 0, got {self.blocks}")
        if not self.max_log_gain > 0 or not self.max_offset > 0:
            raise ValueError(f"max_log_gain, max_offset: expected > 0, got {self.max_log_gain}, {self.max_offset}")
        if isinstance(self.guide_radius, bool) or int(self.guide_radius) != self.guide_radius or self.guide_radius < 0:
            raise ValueError(f"guide_radius: expected an integer >= 0, got {self.guide_radius!r}")
        if not self.guide_eps > 0:
            raise ValueError(f"guide_eps: expected > 0, got {self.guide_eps}")
        if isinstance(self.work_area_px, bool) or int(self.work_area_px) != self.work_area_px:
            raise ValueError(f"work_area_px: expected an integer, got {self.work_area_px!r}")
        if self.work_area_px != 0 and self.work_area_px < SIZE_MULTIPLE**2:
            raise ValueError(f"work_area_px: expected 0 or at least {SIZE_MULTIPLE**2}, got {self.work_area_px}")

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (lists and numbers only), safe for ``torch.load(weights_only=True)`` and JSON."""
        return to_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LiteConfig:
        """Inverse of :meth:`to_dict`.

        Raises:
            ValueError: unknown keys or bad values.
        """
        return from_dict(cls, d, where="config")


VARIANTS: dict[str, LiteConfig] = {
    "base": LiteConfig(),
    # Twice the channels and more blocks (about 490 K parameters folded, 5.4x base's): the network runs on the ~128x160
    # working image, so at 640x480 it costs a few milliseconds more than ``base`` (issue 46's capacity lever).
    "wide": LiteConfig(widths=(32, 64, 96), blocks=(2, 2, 3)),
    # For tests and quick experiments.
    "tiny": LiteConfig(widths=(8, 8, 16), blocks=(0, 1, 1)),
}


def variant_name(config: LiteConfig) -> str | None:
    """The registered variant equal to ``config``, or None."""
    return next((name for name, cfg in VARIANTS.items() if cfg == config), None)


def _up(x: Tensor, factor: int) -> Tensor:
    return F.interpolate(x, scale_factor=factor, mode="bilinear", align_corners=False)


LUMA = LUMA_601
"""BT.601 luma weights of the guide (those the exposure step measures with)."""


def _luma(x: Tensor) -> Tensor:
    return LUMA[0] * x[:, 0:1] + LUMA[1] * x[:, 1:2] + LUMA[2] * x[:, 2:3]


def _box(x: Tensor, radius: int) -> Tensor:
    """Mean over a (2 radius + 1)^2 box, the window cut at the borders (only pixels inside are averaged)."""
    return F.avg_pool2d(x, 2 * radius + 1, 1, radius, count_include_pad=False)


def guided_maps(coeffs: Tensor, guide_lo: Tensor, radius: int, eps: float) -> Tensor:
    """The low-resolution maps of the guided upsampling: (B, 2C, h, w), ``a`` (C maps) then ``b`` (C maps).

    ``guide_lo`` (B, 1, h, w) is the guide at the coefficients' resolution. Per box of radius ``radius``:
    ``a = cov(guide_lo, coeffs) / (var(guide_lo) + eps)``, ``b = mean(coeffs) - a mean(guide_lo)``; both are
    box-averaged. At full resolution the coefficients are ``up(a) * guide + up(b)`` (:func:`apply_maps`).
    ``radius == 0``: ``a = 0``, ``b = coeffs`` (plain bilinear upsampling).
    """
    if radius == 0:
        return torch.cat([torch.zeros_like(coeffs), coeffs], dim=1)
    mean_g, mean_c = _box(guide_lo, radius), _box(coeffs, radius)
    cov = _box(guide_lo * coeffs, radius) - mean_g * mean_c
    var = _box(guide_lo * guide_lo, radius) - mean_g * mean_g
    a = cov / (var + eps)
    b = mean_c - a * mean_g
    return _box(torch.cat([a, b], dim=1), radius)


def guided_upsample(coeffs: Tensor, guide_lo: Tensor, guide: Tensor, radius: int, eps: float) -> Tensor:
    """Upsample ``coeffs`` (B, C, h, w) to ``guide``'s size (B, 1, H, W) following ``guide``'s edges
    (:func:`guided_maps`, upsampled bilinearly, ``a * guide + b``). ``radius == 0``: bilinear."""
    ab = F.interpolate(guided_maps(coeffs, guide_lo, radius, eps), size=guide.shape[-2:], mode="bilinear")
    n = coeffs.shape[1]
    return torch.addcmul(ab[:, n:], ab[:, :n], guide)


def apply_maps(maps: Tensor, x: Tensor) -> Tensor:
    """The enhanced frame from the 12 upsampled maps (B, 12, H, W) of :meth:`LiteNet.maps` and the frame x
    (B, 3, H, W): coefficients ``c = a * luma(x) + b`` (gain in channels 0-2, offset in 3-5), then
    ``gain * x + offset``."""
    c = torch.addcmul(maps[:, 6:], maps[:, :6], _luma(x))
    return torch.addcmul(c[:, 3:], c[:, :3], x)  # Eq. (1) inverted: J = I / t - B (1 - t) / t, per channel


def apply_maps_hwc(
    a_gain: Tensor,
    a_offset: Tensor,
    b_gain: Tensor,
    b_offset: Tensor,
    x: Tensor,
    *,
    luma: Tensor | None = None,
    out: Tensor | None = None,
) -> Tensor:
    """:func:`apply_maps` for one frame in (H, W, C) layout, its 12 maps as four (H, W, 3) groups (channels 0-2,
    3-5, 6-8, 9-11 of :meth:`LiteNet.maps`) and x (H, W, 3) -> (H, W, 3), written into ``out`` when given.
    ``luma`` (H, W, 1): x's luma when the caller has it (else computed here)."""
    y = LUMA[0] * x[..., 0:1] + LUMA[1] * x[..., 1:2] + LUMA[2] * x[..., 2:3] if luma is None else luma
    gain = torch.addcmul(b_gain, a_gain, y)
    offset = torch.addcmul(b_offset, a_offset, y)
    return torch.addcmul(offset, gain, x, out=out)  # type: ignore[arg-type]


def work_size(height: int, width: int, work_area_px: int) -> tuple[int, int] | None:
    """(h, w) of the working image for a ``height`` x ``width`` frame, or None to use the frame itself.

    None when ``work_area_px`` is 0 or the frame has at most that many pixels. Otherwise the frame scaled by
    ``s = sqrt(work_area_px / (height * width))``, each side rounded to the nearest multiple of
    :data:`SIZE_MULTIPLE` (at least one multiple). Examples with the default 20,480 px: 640x480 -> 160x128,
    1280x720 -> 192x112.
    """
    return area_size(height, width, work_area_px, SIZE_MULTIPLE)


def work_size_tensor(height: Tensor, width: Tensor, work_area_px: int) -> tuple[Tensor, Tensor]:
    """:func:`work_size` for a frame larger than ``work_area_px`` (> 0) with the sizes as 0-dim int64 tensors and
    tensor arithmetic only (an ONNX graph traced through it computes the size of each frame it gets): float64,
    rounded half to even as Python's ``round``; equal to :func:`work_size` (pinned by a test)."""
    pixels = (height * width).to(torch.float64)
    scale = torch.sqrt(torch.full_like(pixels, work_area_px) / pixels)  # a Div (a scalar / tensor is 1 / x * a)

    def side(n: Tensor) -> Tensor:
        rounded = torch.round(n.to(torch.float64) * scale / SIZE_MULTIPLE).to(torch.int64) * SIZE_MULTIPLE
        return torch.clamp(rounded, min=SIZE_MULTIPLE)

    return side(height), side(width)


def work_image(x: Tensor, work_area_px: int) -> Tensor:
    """The working image of a batch (B, 3, H, W): area-downsampled to :func:`work_size`, or ``x`` itself."""
    size = work_size(int(x.shape[-2]), int(x.shape[-1]), work_area_px)
    return x if size is None else F.interpolate(x, size=size, mode="area")


def keep_exposure(maps: Tensor, work: Tensor) -> Tensor:
    """``maps`` (B, 12, h / 4, w / 4) of :meth:`LiteNet.maps` scaled per frame so that the restoration keeps the
    exposure of the working image ``work`` (B, 3, h, w), the network's input: the maps applied to ``work``
    average-pooled to their resolution give a restoration whose mean luma the gain of
    :func:`murk.restore_ops.exposure.exposure_gain_torch` brings to the pooled input's. Gain and offset are both
    scaled, so the full-resolution restoration is scaled by the same factor (docs/enhance.md, "exposure")."""
    x = F.avg_pool2d(work, POOL)
    k = exposure_gain_torch(x, apply_maps(maps, x))
    return maps * k[:, None, None, None]


class LiteNet(nn.Module):
    """The ``lite`` restorer network (see the module docstring).

    Args:
        config: widths and depths (default: ``base``).
        folded: build the inference form (plain convolutions) instead of the training form; normally made by
            :func:`reparameterize` from a trained network.
    """

    input_balance_pct: float | None = None
    """Not part of the network: the simplest colour balance (:mod:`murk.restore_ops.balance`) its input takes in
    training and in the restorers, read from and written to checkpoints (``model.input_balance_pct``)."""

    keep_exposure: bool = False
    """Not part of the network: :meth:`maps` scales its maps so that the restoration keeps the mean luma of the
    working image (:func:`keep_exposure`). Off in training; the ``lite`` restorer turns it on (its ``exposure``
    option, default ``input``), and an ONNX export records it (``murk.exposure``)."""

    def __init__(self, config: LiteConfig | None = None, *, folded: bool = False) -> None:
        super().__init__()
        cfg = config or LiteConfig()
        self.config = cfg
        self.folded = folded
        c1, c2, c3 = (int(w) for w in cfg.widths)
        n1, n2, n3 = (int(b) for b in cfg.blocks)

        def block(cin: int, cout: int, stride: int = 1) -> nn.Module:
            return conv_block(cin, cout, stride, folded=folded)

        self.stem = block(3, c1)
        self.enc1 = nn.Sequential(*[block(c1, c1) for _ in range(n1)])
        self.down2 = block(c1, c2, 2)
        self.enc2 = nn.Sequential(*[block(c2, c2) for _ in range(n2)])
        self.down3 = block(c2, c3, 2)
        self.enc3 = nn.Sequential(*[block(c3, c3) for _ in range(n3)])
        self.context = nn.Sequential(nn.Conv2d(c3, c3, 1), nn.LeakyReLU(0.1), nn.Conv2d(c3, c3, 1))
        self.proj2 = nn.Conv2d(c3, c2, 1)
        self.dec2 = block(c2, c2)
        self.proj1 = nn.Conv2d(c2, c1, 1)
        self.dec1 = block(c1, c1)
        self.head = nn.Conv2d(c1, 6, 1)
        nn.init.zeros_(self.head.weight)  # starts as the identity: gain 1, offset 0
        nn.init.zeros_(self.head.bias)  # type: ignore[arg-type]  # a Conv2d built with bias=True

    def coefficients(self, x: Tensor) -> Tensor:
        """Gain (channels 0-2) and offset (3-5) at 1/4 resolution for an input (B, 3, H, W) in [0, 1]."""
        f1 = self.enc1(self.stem(F.avg_pool2d(x, POOL)))
        f2 = self.enc2(self.down2(f1))
        f3 = self.enc3(self.down3(f2))
        f3 = f3 + self.context(f3.mean(dim=(2, 3), keepdim=True))  # global context: the water's overall cast
        u2 = self.dec2(_up(self.proj2(f3), 2) + f2)  # a 1x1 conv commutes with bilinear upsampling: done first
        u1 = self.dec1(_up(self.proj1(u2), 2) + f1)
        h = self.head(u1)
        g, o = self.config.max_log_gain, self.config.max_offset
        gain = torch.exp(g * torch.tanh(h[:, :3] / g))
        offset = o * torch.tanh(h[:, 3:] / o)
        return torch.cat([gain, offset], dim=1)

    def forward(self, x: Tensor, work: Tensor | None = None) -> Tensor:
        """Enhance (B, 3, H, W) RGB in [0, 1]: ``gain * x + offset``, not clamped.

        Args:
            x: the frames. H and W must be multiples of 16 when the frame is used at its own resolution (at most
                ``work_area_px`` pixels); larger frames may have any size.
            work: the working image (B, 3, h, w), h and w multiples of 16, from which the coefficients are
                computed; default :func:`work_image` of ``x`` (the ONNX export takes it as a second input).

        Raises:
            ShapeError: not (B, 3, H, W), or a working image whose sides are not multiples of 16.
        """
        if x.ndim != 4 or x.shape[1] != 3:
            raise ShapeError(f"x: expected (B, 3, H, W), got {tuple(x.shape)}")
        if work is None:
            work = work_image(x, self.config.work_area_px)
        if (
            work.ndim != 4
            or work.shape[:2] != x.shape[:2]
            or work.shape[2] % SIZE_MULTIPLE
            or work.shape[3] % SIZE_MULTIPLE
        ):
            raise ShapeError(
                f"x: expected (B, 3, H, W) with H and W multiples of {SIZE_MULTIPLE} (or a working image of such a "
                f"size), got {tuple(x.shape)}" + ("" if work is x else f" with a working image {tuple(work.shape)}")
            )
        maps = F.interpolate(self.maps(work), size=x.shape[-2:], mode="bilinear", align_corners=False)
        return apply_maps(maps, x)

    def maps(self, work: Tensor) -> Tensor:
        """The 12 low-resolution maps (B, 12, h/4, w/4) of the guided upsampling (:func:`guided_maps`) for the
        working image ``work`` (B, 3, h, w): upsampled bilinearly to the frame and applied by
        :func:`apply_maps`, they give :meth:`forward`'s output. Scaled by :func:`keep_exposure` when
        :attr:`keep_exposure` is set."""
        cfg = self.config
        guide_lo = _luma(F.avg_pool2d(work, POOL)) if cfg.guide_radius else work[:, :1]
        maps = guided_maps(self.coefficients(work), guide_lo, cfg.guide_radius, cfg.guide_eps)
        return keep_exposure(maps, work) if self.keep_exposure else maps


def build_lite(variant: LiteVariant | str = "base", **overrides: Any) -> LiteNet:
    """A randomly initialised ``lite`` network in its training form.

    Args:
        variant: ``"base"`` (shipped, about 90 K parameters folded), ``"wide"`` (about 490 K) or ``"tiny"`` (tests).
        **overrides: :class:`LiteConfig` fields to change.

    Raises:
        ValueError: unknown variant or bad overrides.
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant: expected one of {', '.join(VARIANTS)} for lite, got {variant!r}")
    cfg = VARIANTS[variant]
    if overrides:
        cfg = LiteConfig.from_dict({**cfg.to_dict(), **overrides})
    return LiteNet(cfg)


def unwrap(model: nn.Module) -> LiteNet:
    """The :class:`LiteNet` inside a DistributedDataParallel / ``torch.compile`` wrapper.

    Raises:
        TypeError: no LiteNet inside ``model``.
    """
    return unwrap_as(model, LiteNet)


@torch.no_grad()
def reparameterize(model: nn.Module) -> LiteNet:
    """The inference form of a trained network: every :class:`RepConv` folded into one 3x3 convolution (see
    :func:`~murk.models.lite.blocks.fold_rep_conv`); equal to ``model`` in eval mode to float rounding.

    Returns a new network in eval mode on ``model``'s device and dtype; ``model`` is not changed. An already
    folded network is returned as is.

    Raises:
        TypeError: ``model`` is not a LiteNet.
    """
    net = unwrap(model)
    if net.folded:
        return net.eval()
    param = next(net.parameters())
    folded = LiteNet(net.config, folded=True).to(device=param.device, dtype=param.dtype)
    reps = {name: m for name, m in net.named_modules() if isinstance(m, RepConv)}
    state = {}
    for name, module in reps.items():
        for k, v in fold_rep_conv(module).state_dict().items():
            state[f"{name}.{k}"] = v
    for k, v in net.state_dict().items():
        if not any(k.startswith(f"{name}.") for name in reps):
            state[k] = v
    folded.load_state_dict(state, strict=True)
    return folded.eval()


def parameter_count(model: nn.Module) -> int:
    """Number of parameters (the inference count when ``model`` is folded)."""
    return sum(p.numel() for p in model.parameters())
