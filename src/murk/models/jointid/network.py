"""The Joint-ID network: two encoder-decoder branches (depth, enhancement) coupled by eight joint blocks.

Reference: Yang, Kang, Lee, Cho, "Transformer-Based Joint Image Enhancement and Depth Estimation for
Underwater Environments", IEEE Sensors Journal 23(24), 2023, doi:10.1109/JSEN.2023.3338730. The paper
(Yun et al., "Robust Image Processing Techniques for Construction Environment Monitoring Using Underwater
Robots") retrains this network unchanged; this module re-implements it from ``docs/spec/jointid.md`` so that
the official released checkpoint loads with ``strict=True`` (state-dict names and shapes are identical, with
or without the official ``structure.`` prefix).

``forward`` takes the *normalised* RGB batch (see :func:`normalize_input`; the restorer applies it) whose
height and width are multiples of 32, and returns depth in metres and the enhanced image in [0, 1].
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any, Literal, NamedTuple

import numpy as np
import torch
from torch import Tensor, nn

from murk._config import from_dict, to_dict
from murk.errors import ShapeError
from murk.models.jointid.decoder import Decoder, JointBlock, Task
from murk.models.jointid.encoder import Encoder

Variant = Literal["base", "small", "tiny"]

INPUT_MEAN = (0.13553666, 0.41034216, 0.34636855)
"""Per-channel (R, G, B) mean of the input normalisation of the training recipe."""
INPUT_STD = (0.04927989, 0.10722694, 0.10722694)
"""Per-channel (R, G, B) standard deviation of the input normalisation of the training recipe."""
SIZE_MULTIPLE = 32
"""Input height and width must be multiples of this (the encoder's total stride)."""


@dataclass(frozen=True)
class JointIDConfig:
    """Widths and depths of a Joint-ID network. The defaults are the official model (``variant="base"``)."""

    embed_dims: tuple[int, int, int, int] = (64, 128, 320, 512)
    depths: tuple[int, int, int, int] = (4, 7, 12, 4)
    num_heads: tuple[int, int, int, int] = (1, 2, 5, 8)
    sr_ratios: tuple[int, int, int, int] = (8, 4, 2, 1)
    mlp_ratio: int = 4
    decoder_blocks: int = 3
    decoder_dim: int = 256
    max_depth_m: float = 15.0
    residual_output: bool = False
    """False (the original): ``enhanced = sigmoid(head)``. True: ``enhanced = sigmoid(head + logit(input))``,
    i.e. the head predicts a correction of the input in logit space, so full-resolution detail does not have
    to pass through the decoder's 1/4-resolution skips. murk's ``small`` CPU variant uses it (docs/models.md
    gives the measurements); the official ``base`` model does not."""
    shuffle_smoothing: bool = False
    """False (the original): every pixel shuffle's output is used as is. True: each map pixel-shuffled by ``r`` is
    filtered with a fixed ``2r - 1``-tap triangle (:func:`murk.models.jointid.decoder.smooth_shuffled`; no
    parameters, the state dict is unchanged), which removes every period-``r`` pattern the shuffle can make:
    the 4-32 px grids and bands that learned sub-pixel kernels otherwise draw in flat water."""
    global_colour: bool = False
    """False (the original). True: murk's global colour head (:class:`GlobalColourHead`, not in the paper): the
    enhancement encoder's deepest features and the input's per-channel mean and spread, pooled over the whole
    image, give a per-channel gain and offset of the output logits. Its last layer starts at zero, so the network
    starts out exactly as without it (weights of the same variant load with the head at identity)."""

    def to_dict(self) -> dict[str, Any]:
        """Plain dict (lists and numbers only), safe for ``torch.load(weights_only=True)`` and JSON."""
        return to_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> JointIDConfig:
        """Inverse of :meth:`to_dict`.

        Raises:
            ValueError: unknown keys.
        """
        return from_dict(cls, d, where="config")


# Same structure with small widths and depths: CPU tests, demos and quick experiments.
_TINY = JointIDConfig(
    embed_dims=(16, 32, 64, 128),
    depths=(1, 1, 2, 1),
    num_heads=(1, 1, 2, 4),
    decoder_blocks=2,
    decoder_dim=32,
)

VARIANTS: dict[str, JointIDConfig] = {
    "base": JointIDConfig(),
    # The model murk trains on 2 CPU cores and ships (docs/models.md): tiny's widths with two blocks per
    # encoder stage (more context), one mix block per decoder scale, the residual output and the smoothed
    # pixel shuffles.
    "small": replace(_TINY, depths=(2, 2, 2, 2), decoder_blocks=1, residual_output=True, shuffle_smoothing=True),
    "tiny": _TINY,
}


class JointIDOutput(NamedTuple):
    """Outputs of :class:`JointID`: ``depth_m`` (B, 1, H, W) in metres, ``enhanced`` (B, 3, H, W) in [0, 1]."""

    depth_m: Tensor
    enhanced: Tensor


class Branch(nn.Module):
    """One task's encoder and decoder (``depth_structure`` or ``enhanced_structure`` in the state dict)."""

    def __init__(self, cfg: JointIDConfig, task: Task) -> None:
        super().__init__()
        self.encoder = Encoder(cfg.embed_dims, cfg.depths, cfg.num_heads, cfg.sr_ratios, cfg.mlp_ratio)
        out_channels = 1 if task == "depth" else 3
        self.decoder = Decoder(
            cfg.embed_dims, cfg.decoder_blocks, cfg.decoder_dim, out_channels, task, cfg.shuffle_smoothing
        )


class GlobalColourHead(nn.Module):
    """A per-image, per-channel affine map of the output logits, ``(1 + g) * logits + b``, from pooled statistics.

    Input: the enhancement encoder's 1/32-scale map averaged over the image (``channels`` values) and the mean and
    standard deviation of each channel of the input's logit (6 values), so the head sees the image's global colour
    directly, whatever the crop size. A two-layer MLP gives ``(g, b)`` per channel; its last layer is zero at the
    start, which leaves the logits unchanged. Added by murk for issue 27: on murk's held-out water almost all of the
    small network's error is a global colour and level error (docs/train.md).
    """

    HIDDEN = 64

    def __init__(self, channels: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(channels + 6, self.HIDDEN)
        self.fc2 = nn.Linear(self.HIDDEN, 6)
        nn.init.zeros_(self.fc2.weight)
        nn.init.zeros_(self.fc2.bias)

    def forward(self, deep: Tensor, x_logit: Tensor, logits: Tensor) -> Tensor:
        """``logits`` (B, 3, H, W) mapped per image and channel; ``deep`` (B, C, h, w), ``x_logit`` (B, 3, H, W)."""
        stats = torch.cat([deep.mean(dim=(2, 3)), x_logit.mean(dim=(2, 3)), x_logit.std(dim=(2, 3))], dim=1)
        gb = self.fc2(torch.nn.functional.gelu(self.fc1(stats)))
        gain = 1.0 + gb[:, :3, None, None]
        return logits * gain + gb[:, 3:, None, None]


class JointID(nn.Module):
    """Joint image enhancement and depth estimation network (Yang et al. 2023).

    Both encoders see the same normalised input. At each decoder scale (c4 -> c1) both branches run their
    mix-decoder blocks, take the sigmoid, and each branch continues from its joint block applied to
    ``concat[z_self, z_other]`` (both joint blocks read the sigmoids computed before either runs).

    Loading a state dict accepts the official names (prefix ``structure.``) and murk's (no prefix).
    """

    input_balance_pct: float | None = None
    """Not part of the network: the simplest colour balance (:mod:`murk.restore_ops.balance`) its input takes in
    training and in the restorers, read from and written to checkpoints (``model.input_balance_pct``)."""

    def __init__(self, config: JointIDConfig | None = None) -> None:
        super().__init__()
        cfg = config or JointIDConfig()
        self.config = cfg
        self.depth_structure = Branch(cfg, "depth")
        self.enhanced_structure = Branch(cfg, "enhanced")
        for direction in ("de", "eh"):  # de: depth branch, eh: enhancement branch
            for i, s in enumerate((3, 2, 1, 0)):
                self.add_module(f"decoder_{direction}_joint_block_{i + 1}", JointBlock(cfg.embed_dims[s]))
        self.global_colour_head = GlobalColourHead(cfg.embed_dims[3]) if cfg.global_colour else None
        self.register_load_state_dict_pre_hook(_strip_official_prefix)

    def forward(self, x: Tensor) -> JointIDOutput:
        """Depth (metres) and enhanced image for a normalised batch ``x`` (B, 3, H, W), H and W multiples of 32.

        Raises:
            ShapeError: ``x`` is not (B, 3, H, W) with H, W positive multiples of 32.
        """
        depth_m, logits, fe3 = self._decode(x, enhanced=True)
        assert logits is not None
        if self.config.residual_output or self.global_colour_head is not None:
            x_logit = input_logit(x)
            if self.config.residual_output:
                logits = logits + x_logit
            if self.global_colour_head is not None:
                logits = self.global_colour_head(fe3, x_logit, logits)
        return JointIDOutput(depth_m, torch.sigmoid(logits))

    def depth(self, x: Tensor) -> Tensor:
        """The depth (metres) of :meth:`forward` alone, bit for bit: the enhancement branch's decoder runs only as far
        as the depth branch's joint blocks read it (no skips, head or colour head), a sixth to a fifth less time.
        It calls the submodules directly, not through ``forward``: forward hooks on the network do not fire.

        Raises:
            ShapeError: as :meth:`forward`.
        """
        return self._decode(x, enhanced=False)[0]

    def _decode(self, x: Tensor, *, enhanced: bool) -> tuple[Tensor, Tensor | None, Tensor]:
        """Both encoders and decoders -> (depth in m, the enhancement head's logits or None, the enhancement
        encoder's deepest features); ``enhanced=False`` skips what only the enhanced image needs."""
        if not (torch.jit.is_tracing() or torch.compiler.is_compiling()):
            _check_input(x)
        dbr, ebr = self.depth_structure, self.enhanced_structure
        fd = dbr.encoder(x)
        fe = ebr.encoder(x)
        xd = dbr.decoder.start(fd[3])
        xe = ebr.decoder.start(fe[3])
        skips_d: list[Tensor] = []
        skips_e: list[Tensor] = []
        for i, s in enumerate((3, 2, 1, 0)):
            zd = torch.sigmoid(dbr.decoder.mix(s, xd, fd[s]))
            ze = torch.sigmoid(ebr.decoder.mix(s, xe, fe[s]))
            jd = getattr(self, f"decoder_de_joint_block_{i + 1}")(zd, ze)
            skips_d.append(dbr.decoder.skip(s, jd))
            if not enhanced and s == 0:
                break  # the finest enhancement joint block feeds only the enhanced image's skip
            je = getattr(self, f"decoder_eh_joint_block_{i + 1}")(ze, zd)
            if enhanced:
                skips_e.append(ebr.decoder.skip(s, je))
            if s > 0:
                xd = dbr.decoder.up(s, jd)
                xe = ebr.decoder.up(s, je)
        depth_m = self.config.max_depth_m * torch.sigmoid(dbr.decoder.head(skips_d))
        return depth_m, ebr.decoder.head(skips_e) if enhanced else None, fe[3]


RESIDUAL_EPS = 1e-3
"""The input is clamped to [eps, 1 - eps] before its logit is taken (finite logits for black/white pixels)."""


def input_logit(x: Tensor) -> Tensor:
    """``logit(clamp(rgb, eps, 1 - eps))`` of the RGB image behind a normalised batch ``x`` (undoes
    :func:`normalize_input`); the residual output adds it to the head's logits."""
    mean = torch.tensor(INPUT_MEAN, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
    std = torch.tensor(INPUT_STD, dtype=x.dtype, device=x.device).view(1, 3, 1, 1)
    rgb = (x * std + mean).clamp(RESIDUAL_EPS, 1.0 - RESIDUAL_EPS)
    return torch.log(rgb) - torch.log1p(-rgb)


def _strip_official_prefix(module: nn.Module, state_dict: dict, prefix: str, *args: Any, **kwargs: Any) -> None:
    """Load-state-dict pre-hook: rename official keys ``structure.X`` to ``X`` in place."""
    official = prefix + "structure."
    for key in [k for k in state_dict if k.startswith(official)]:
        state_dict[prefix + key[len(official) :]] = state_dict.pop(key)


def _check_input(x: Tensor) -> None:
    if not isinstance(x, Tensor):
        raise TypeError(f"x: expected a torch.Tensor (B, 3, H, W), got {type(x).__name__}")
    if x.ndim != 4 or x.shape[1] != 3:
        raise ShapeError(f"x: expected shape (B, 3, H, W), got {tuple(x.shape)}")
    h, w = x.shape[2], x.shape[3]
    if h < SIZE_MULTIPLE or w < SIZE_MULTIPLE or h % SIZE_MULTIPLE or w % SIZE_MULTIPLE:
        raise ShapeError(
            f"x: expected height and width that are positive multiples of {SIZE_MULTIPLE}, got {h}x{w} "
            "(pad with murk.models.padding.pad_to_multiple)"
        )


def unused_parameter_names(model: nn.Module) -> list[str]:
    """Names of the parameters that never receive a gradient: each decoder block's second LayerNorm, kept
    only so that the official checkpoint loads (12,288 parameters in the base model). Training freezes them
    (DistributedDataParallel requires every trainable parameter to be used)."""
    return [n for n, _ in model.named_parameters() if ".norm_layer_2." in n]


DEPTH_HEAD_MODULES = (
    "up_skip_conv_c1",
    "up_skip_conv_c2",
    "up_skip_conv_c3",
    "up_skip_conv_c4",
    "up_skip_conv",
    "linear_pred1",
)
"""The depth decoder's modules that feed only the depth output: the skip convolutions and the head. Everything
else in the depth branch also reaches the enhanced image through the ``eh`` joint blocks."""


def depth_head_parameter_names(model: nn.Module) -> list[str]:
    """Names of the parameters that affect the depth output and nothing else (:data:`DEPTH_HEAD_MODULES` of the
    depth decoder). Training only these (``model.trainable: depth_head``) leaves the enhanced image unchanged
    bit for bit."""
    prefix = "depth_structure.decoder."
    return [
        n
        for n, _ in model.named_parameters()
        if n.startswith(prefix) and n[len(prefix) :].split(".")[0] in DEPTH_HEAD_MODULES
    ]


ENHANCE_HEAD_MODULES = (
    "decoder_eh_joint_block_4",
    "global_colour_head",
    *(f"enhanced_structure.decoder.{m}" for m in DEPTH_HEAD_MODULES),
)
"""The modules that feed only the enhanced image: the enhancement decoder's skip convolutions and head, the joint
block of its finest scale (whose output goes only to the skip path) and murk's global colour head. The other
enhancement modules also reach the depth map, through the ``de`` joint blocks."""


def enhance_head_parameter_names(model: nn.Module) -> list[str]:
    """Names of the parameters that affect the enhanced image and nothing else (:data:`ENHANCE_HEAD_MODULES`).
    Training only these (``model.trainable: enhance_head``) leaves the depth output unchanged bit for bit."""
    return [n for n, _ in model.named_parameters() if any(n.startswith(m + ".") for m in ENHANCE_HEAD_MODULES)]


def init_weights(model: JointID) -> JointID:
    """Initialise for training from scratch (no pretrained backbone), as the training recipe does.

    Linear: truncated normal (std 0.02), bias 0; LayerNorm: weight 1, bias 0; encoder convolutions (this
    includes the RLN meta convolutions): normal(0, sqrt(2 / fan_out)) with fan_out = k*k*out/groups, bias 0;
    decoder convolutions: Xavier-uniform, bias 0; joint blocks keep PyTorch's default initialisation.
    """
    for branch in (model.depth_structure, model.enhanced_structure):
        for m in branch.modules():
            if isinstance(m, nn.Linear):
                nn.init.trunc_normal_(m.weight, std=0.02)  # bounds +-2 (absolute), as timm
                nn.init.zeros_(m.bias)
            elif isinstance(m, nn.LayerNorm):
                nn.init.ones_(m.weight)
                nn.init.zeros_(m.bias)
        for m in branch.encoder.modules():
            if isinstance(m, nn.Conv2d):
                fan_out = m.kernel_size[0] * m.kernel_size[1] * m.out_channels // m.groups
                nn.init.normal_(m.weight, 0.0, math.sqrt(2.0 / fan_out))
                if m.bias is not None:
                    nn.init.zeros_(m.bias)
        for m in branch.decoder.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.xavier_uniform_(m.weight)
                if m.bias is not None:
                    nn.init.zeros_(m.bias)
    return model


def icnr_init_(model: JointID) -> JointID:
    """ICNR initialisation (Aitken et al., "Checkerboard artifact free sub-pixel convolution", arXiv:1707.02937)
    of every convolution that feeds a pixel shuffle: the ``r*r`` output channels that become one output
    channel's ``r x r`` sub-pixels start as copies of one kernel (drawn as :func:`init_weights` draws it), so
    the initial upsampling is a nearest-neighbour resize and no sub-pixel grid pattern is present at the start.
    Applied after :func:`init_weights`; in place."""
    from murk.models.jointid.decoder import _SKIP_SHUFFLE

    with torch.no_grad():
        for branch in (model.depth_structure, model.enhanced_structure):
            dec = branch.decoder
            convs = [(dec.up_skip_conv, 4)]
            for s in (3, 2, 1, 0):
                convs.append((getattr(dec, f"up_skip_conv_c{s + 1}"), _SKIP_SHUFFLE[s]))
                if s > 0:
                    convs.append((getattr(dec, f"up_channels_c{s + 1}"), 2))
            for conv, r in convs:
                if r == 1:
                    continue
                w = conv.weight
                base = w[:: r * r].clone()  # one kernel per shuffled output channel
                w.copy_(base.repeat_interleave(r * r, dim=0))
                if conv.bias is not None:
                    conv.bias.copy_(conv.bias[:: r * r].repeat_interleave(r * r))
    return model


def build_jointid(variant: Variant | JointIDConfig = "base", *, init: bool = True) -> JointID:
    """Build a Joint-ID network.

    Args:
        variant: ``"base"`` (the official model, 150,248,900 parameters), ``"small"`` (the model murk ships,
            3.9 M parameters, residual output), ``"tiny"`` (same structure, small widths/depths) or an explicit
            :class:`JointIDConfig`.
        init: apply :func:`init_weights` (skip it when weights are loaded right after).

    Raises:
        ValueError: unknown variant name.
        TypeError: ``variant`` is neither a name nor a config.
    """
    if isinstance(variant, JointIDConfig):
        cfg = variant
    elif isinstance(variant, str):
        if variant not in VARIANTS:
            raise ValueError(f"variant: expected one of {sorted(VARIANTS)}, got {variant!r}")
        cfg = VARIANTS[variant]
    else:
        raise TypeError(f"variant: expected a variant name or a JointIDConfig, got {type(variant).__name__}")
    model = JointID(cfg)
    return init_weights(model) if init else model


def variant_name(config: JointIDConfig) -> str | None:
    """The registered variant name of ``config`` (``"small+colour"`` for a registered variant with the global
    colour head added), or None for a custom configuration."""
    plain = replace(config, global_colour=False)
    name = next((name for name, cfg in VARIANTS.items() if cfg == plain), None)
    if name is None or not config.global_colour:
        return name
    return f"{name}+colour"


def normalize_input(x: Tensor) -> Tensor:
    """Normalise an RGB batch (..., 3, H, W) in [0, 1] with the training recipe's mean and std (per channel).

    The network's ``forward`` expects this; :func:`normalize_input_np` is the numpy twin (channels last).

    Raises:
        ShapeError: the channel dimension (-3) is not 3.
    """
    if x.ndim < 3 or x.shape[-3] != 3:
        raise ShapeError(f"x: expected shape (..., 3, H, W), got {tuple(x.shape)}")
    mean = torch.tensor(INPUT_MEAN, dtype=x.dtype, device=x.device).view(3, 1, 1)
    std = torch.tensor(INPUT_STD, dtype=x.dtype, device=x.device).view(3, 1, 1)
    return (x - mean) / std


def normalize_input_np(x: np.ndarray) -> np.ndarray:
    """Numpy twin of :func:`normalize_input` for channels-last arrays (..., H, W, 3); returns float32.

    Raises:
        ShapeError: the last dimension is not 3.
    """
    if x.ndim < 3 or x.shape[-1] != 3:
        raise ShapeError(f"x: expected shape (..., H, W, 3), got {x.shape}")
    mean = np.asarray(INPUT_MEAN, np.float32)
    std = np.asarray(INPUT_STD, np.float32)
    return ((x.astype(np.float32, copy=False) - mean) / std).astype(np.float32, copy=False)
