"""Configuration of a training run (YAML <-> frozen dataclasses). Defaults: Joint-ID's original recipe."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from murk._checks import check_interval, check_positive, check_range
from murk.io.pairs import DEPTH_FROM, DepthFrom
from murk.synth.config import SynthConfig

DataKind = Literal["auto", "synth", "list", "rgbd", "scenes", "shards"]


@dataclass(frozen=True)
class AugmentConfig:
    """Augmentation settings (defaults: the original recipe; applied by :mod:`murk.train.augment`)."""

    rotate_deg: float = 3.5
    flip_p: float = 0.5
    color_p: float = 0.7
    brightness: tuple[float, float] = (0.5, 1.1)
    channel_gain: tuple[float, float] = (0.9, 1.1)
    max_depth_m: float = 600.0
    enabled: bool = True
    vflip_p: float = 0.0
    """Up-down flip (input, target and depth together) with this probability; 0 in the original recipe. Drawn after
    every other parameter, so a run with 0 draws what it drew before. A distillation teacher (``loss.teacher``, a
    network or a method) restores the flipped frame."""

    def __post_init__(self) -> None:
        for name in ("flip_p", "color_p", "vflip_p"):
            check_range(name, getattr(self, name), 0.0, 1.0)


@dataclass(frozen=True)
class LossWeights:
    """Weights of the loss terms (defaults: the original recipe; used by :mod:`murk.train.losses`)."""

    enhance: float = 2.0
    laplacian: float = 0.1
    depth: float = 1.8
    ssim: float = 0.0
    snow: float = 0.0
    """Extra weight of the restoration error on the pixels covered by marine snow (Eq. 8's alpha of each training
    input), inside the enhancement term: ``enhance * (L2 + laplacian * Lap + snow * L2_snow)``
    (:func:`murk.train.losses.snow_l2`). Needs online synthesis with the ``marine_snow`` stage. 0: the original
    loss."""
    distill: float = 0.0
    """Weight of a distillation term inside the enhancement term: the row-wise L2 between the network's output and
    a teacher's restoration of the same input (``teacher``), ``enhance * (L2 + laplacian * Lap + snow * L2_snow +
    distill * L2_teacher)``. 0: the original loss."""
    teacher: str | None = None
    """The teacher of ``distill``: ``lite`` or ``jointid`` (the shipped weights) or ``lite:PATH`` /
    ``jointid:PATH`` (a checkpoint), or ``method:SPEC``, any restoration method as ``murk enhance --method`` takes it
    (``method:water``; run by :mod:`murk.workflows.distill`, which ``murk train`` calls). It restores each training
    input (after augmentation) without gradient, with its own input balance."""
    local: float = 0.0
    """Weight of the local term inside the enhancement term: the row-wise L2 left after the output's best gain and
    offset per image and channel onto the clean scene (:func:`murk.train.losses.local_l2`), i.e. the error no
    global colour correction removes (haze growing with distance, forward scatter, snow). It keeps a network from
    lowering the loss by colour alone. 0: the original loss."""
    silog_lambda: float = 0.85
    depth_min_m: float = 0.001

    def __post_init__(self) -> None:
        check_range("distill", self.distill, 0.0, 1e6)
        check_range("local", self.local, 0.0, 1e6)
        if self.distill > 0:
            kind, _, rest = (self.teacher or "").partition(":")
            if kind not in ("lite", "jointid", "method") or (kind == "method" and (not rest or rest != rest.strip())):
                raise ValueError(
                    f"teacher: expected lite, jointid, lite:PATH, jointid:PATH or method:SPEC with loss.distill > 0, "
                    f"got {self.teacher!r}"
                )


@dataclass(frozen=True)
class ModelConfig:
    """Which network, and optionally the weights to start from."""

    kind: Literal["jointid", "lite"] = "jointid"
    """``jointid`` (enhancement + depth, :mod:`murk.models.jointid`) or ``lite`` (the small real-time
    restorer, :mod:`murk.models.lite`; enhancement only: the depth loss is skipped)."""
    variant: Literal["base", "small", "wide", "tiny"] = "base"
    """jointid: base, small or tiny; lite: base (shipped), wide or tiny."""
    init_checkpoint: str | None = None
    """Start from these weights (murk or official format) instead of the random initialisation."""
    init: Literal["original", "icnr"] = "original"
    """Random initialisation: the recipe's, or with ICNR for the convolutions before pixel shuffles
    (:func:`murk.models.jointid.network.icnr_init_`; no sub-pixel grid at the start; jointid only)."""
    trust_checkpoint: bool = False
    """Load ``init_checkpoint`` (and a resumed ``latest.pt``) even when it pickles objects other than tensors and
    plain data (``torch.load(weights_only=False)``: runs code from the file; only for files you trust)."""
    trainable: Literal["all", "depth_head", "enhance_head", "colour_head"] = "all"
    """``all``, or ``depth_head``: train only the depth decoder's skip convolutions and head
    (:func:`murk.models.jointid.depth_head_parameter_names`), the parameters that feed nothing but the depth
    output, so the enhanced image of ``init_checkpoint`` stays exactly as it was (jointid only; needs
    ``init_checkpoint``), or ``enhance_head``: the mirror image, train only the parameters that feed nothing but
    the enhanced image (:func:`murk.models.jointid.enhance_head_parameter_names`: the enhancement decoder's skip
    convolutions and head, its finest joint block, the global colour head), so the depth map of
    ``init_checkpoint`` stays exactly as it was (jointid only; needs ``init_checkpoint``), or ``colour_head``:
    train only the global colour head (needs ``global_colour`` and ``init_checkpoint``; the rest of the network
    stays as it was)."""
    global_colour: bool = False
    """jointid: add murk's global colour head (:class:`murk.models.jointid.network.GlobalColourHead`): a per-image,
    per-channel gain and offset of the output logits from pooled features. It starts at identity, so
    ``init_checkpoint`` may hold weights of the same variant without the head (they load, the head starts at
    zero). False: the network as the paper has it."""
    input_balance_pct: float | None = None
    """Take the network's input through the simplest colour balance (:mod:`murk.restore_ops.balance`) with this
    percentage saturated at each end of each channel, in training and in every restorer of the checkpoint
    (recorded in it as ``input_balance_pct``): the network restores what one global affine map per channel
    cannot. None: the input as it is (the paper's recipe)."""

    def __post_init__(self) -> None:
        if self.kind == "lite":
            if self.variant not in ("base", "wide", "tiny"):
                raise ValueError(f"variant: expected base, wide or tiny for model.kind lite, got {self.variant!r}")
            if self.init != "original":
                raise ValueError(f"init: {self.init!r} applies to model.kind jointid only (lite has no pixel shuffle)")
            if self.trainable != "all":
                raise ValueError(
                    f"trainable: {self.trainable!r} applies to model.kind jointid only (lite is one network with no "
                    "separate heads)"
                )
            if self.global_colour:
                raise ValueError("global_colour: applies to model.kind jointid only")
        elif self.variant == "wide":
            raise ValueError("variant: wide applies to model.kind lite only (jointid: base, small or tiny)")
        if self.input_balance_pct is not None:
            check_range("input_balance_pct", self.input_balance_pct, 0.0, 49.0)
        if self.trainable != "all" and not self.init_checkpoint:
            raise ValueError(
                f"trainable: {self.trainable} trains one head of existing weights; set model.init_checkpoint"
            )
        if self.trainable == "colour_head" and not self.global_colour:
            raise ValueError("trainable: colour_head needs model.global_colour: true")


@dataclass(frozen=True)
class DataConfig:
    """Where samples come from.

    ``source`` is a ``murk synth`` output folder, a Joint-ID list file, a clean RGB-D folder (``rgb/`` +
    ``depth/``; degraded online), ``scenes`` (procedural construction-site scenes, degraded online) or tar shards
    of ``murk synth --format webdataset`` (``'out/shards/{000000..000199}.tar'``, its ``index.json`` or folder;
    streamed: :mod:`murk.train.shard_data`); ``kind: auto`` tells them apart.
    """

    source: str = ""
    kind: DataKind = "auto"
    list_root: str | None = None
    """Base folder of the relative paths of a Joint-ID list (default: the list's folder)."""
    crop_hw: tuple[int, int] = (288, 512)
    """Training size (height, width): samples are centre-cropped to it (multiples of 32)."""
    val_fraction: float = 0.05
    """Share of clean images (by stem) held out for validation."""
    val_source: str | None = None
    """A separate validation source instead of the split."""
    workers: int = 2
    """DataLoader worker processes per training process."""
    shuffle_buffer: int = 256
    """Tar shards (``kind: shards``): samples each stream holds to shuffle across shards (compressed bytes,
    about 1 MB per 640x480 sample; :mod:`murk.train.shard_data`)."""
    depth_scale: float = 1000.0
    depth_encoding: Literal["linear", "sun", "kinect-disparity"] = "linear"
    invalid_depth: Literal["fill", "far", "fail"] = "fill"
    depth_from: DepthFrom = "file"
    """Clean RGB-D sources (``source`` or ``photos``): ``file`` reads their depth/; ``layout`` takes clean
    photographs without depth (rgb/, or the folder itself) and gives each the ground-plane layout prior's distance
    (:mod:`murk.io.distance_prior`, drawn from the run's seed and the stem)."""
    photos: str | None = None
    """``source: scenes``: a folder of clean photographs (RGB-D, or photographs with ``depth_from: layout``) mixed
    into the procedural training scenes, degraded online like them (:mod:`murk.train.photo_source`); the
    validation split stays procedural. Photographs are real content, with the contrast and texture the scenes lack."""
    photos_share: float = 0.5
    """``photos``: the share of training samples that are photograph windows (each photograph is repeated, with
    windows at different positions and sizes, to reach it)."""
    photos_scale: tuple[float, float] = (1.0, 2.5)
    """``photos``: each window is cut from the photograph resized to ``s`` times the size that just covers the
    crop (``s`` uniform in this range, fixed per photograph and repeat)."""
    scenes_count: int = 2000
    """Number of procedural scenes (``source: scenes``); scene i is the same in every epoch."""
    cache_scenes: bool = False
    """Keep rendered scenes in memory (``source: scenes``, ``workers: 0``): each scene is rendered once instead
    of every epoch (about 12 ms per 128x160 scene; 0.33 MB each)."""
    scene_scale: tuple[float, float] = (1.0, 1.0)
    """``source: scenes``: each scene is rendered at ``s`` times the size that just covers the crop (``s``
    uniform in this range, fixed per scene by its seed) and a crop-sized window is cut at a position also fixed
    per scene. With ``s > 1`` objects appear larger in pixels, as in higher-resolution footage, so a model
    cannot read distance from apparent size at one resolution only. (1, 1): the whole scene, centre-cropped."""
    scene_saturation: tuple[float, float] = (1.0, 1.0)
    """``source: scenes``: the clean scene's colour saturation is scaled by ``s`` (uniform in this range, fixed
    per scene by its seed) around its BT.601 luma, before the water is added, so the targets span the vivid
    colours of real photographs (fish, paint, marine growth) and not only the procedural palette. (1, 1): off."""
    scene_contrast: tuple[float, float] = (1.0, 1.0)
    """``source: scenes``: the clean scene's colours are stretched by ``c`` (uniform in this range, fixed per scene
    by its seed) around its mean luma, ``clip(m + c (rgb - m))``, before the water is added. The procedural
    scenes are flatter than photographs (luma std 0.11 against 0.18-0.21 for the shipped real RGB-D photos),
    so a restorer trained on them returns flat images. (1, 1): off."""
    scene_balance_pct: float | None = None
    """``source: scenes``: the clean scene goes through the simplest colour balance (:mod:`murk.restore_ops.balance`)
    with this percentage saturated at each end of each channel, after ``scene_contrast`` and
    ``scene_saturation`` and before the water, so every target spans the range in each channel as photographs
    (and the references of real pairs) do. None: off."""
    scene_water_background: float = 0.0
    """``source: scenes``: probability that a scene's open-water background is clear-water blue to cyan-green
    (:class:`murk.scenes.SceneConfig` ``water_background``) instead of near-grey, so that a restorer learns to
    leave clear water looking like water. 0: off (the scenes of stages 1-2)."""
    synthesis: SynthConfig = field(
        default_factory=lambda: SynthConfig(stages=("basic", "forward_scatter", "marine_snow"))
    )
    """Online degradation (rgbd and scenes sources): the paper's three stages by default."""

    def __post_init__(self) -> None:
        h, w = self.crop_hw
        if h % 32 or w % 32 or h < 32 or w < 32:
            raise ValueError(f"crop_hw: expected multiples of 32 (Joint-ID's input rule), got {self.crop_hw}")
        check_range("val_fraction", self.val_fraction, 0.0, 0.9)
        if self.workers < 0:
            raise ValueError(f"workers: expected >= 0, got {self.workers}")
        if self.shuffle_buffer < 1:
            raise ValueError(f"shuffle_buffer: expected >= 1, got {self.shuffle_buffer}")
        check_positive("depth_scale", self.depth_scale)
        if self.scenes_count < 1:
            raise ValueError(f"scenes_count: expected >= 1, got {self.scenes_count}")
        lo, hi = self.scene_scale
        if not (1.0 <= lo <= hi <= 4.0):
            raise ValueError(f"scene_scale: expected 1 <= low <= high <= 4, got {list(self.scene_scale)}")
        check_interval("scene_saturation", self.scene_saturation, 0.0, 4.0)
        check_range("scene_water_background", self.scene_water_background, 0.0, 1.0)
        check_interval("scene_contrast", self.scene_contrast, 0.0, 4.0)
        if self.scene_balance_pct is not None:
            check_range("scene_balance_pct", self.scene_balance_pct, 0.0, 49.0)
        if self.depth_from not in DEPTH_FROM:
            raise ValueError(f"depth_from: expected one of {', '.join(DEPTH_FROM)}, got {self.depth_from!r}")
        if not 0.0 < self.photos_share < 1.0:
            raise ValueError(f"photos_share: expected 0 < share < 1, got {self.photos_share}")
        lo, hi = self.photos_scale
        if not (1.0 <= lo <= hi <= 4.0):
            raise ValueError(f"photos_scale: expected 1 <= low <= high <= 4, got {list(self.photos_scale)}")


@dataclass(frozen=True)
class OptimConfig:
    """AdamW and the warm-up + cosine schedule (the original: lr 2e-4, min 2e-6, wd 0.01, 1 warm-up epoch)."""

    lr: float = 2e-4
    min_lr: float = 2e-6
    betas: tuple[float, float] = (0.9, 0.999)
    eps: float = 1e-8
    weight_decay: float = 0.01
    warmup_epochs: float = 1.0
    grad_clip: float = 0.0
    """Clip the global gradient norm (0 = off, as in the original)."""

    def __post_init__(self) -> None:
        check_positive("lr", self.lr)
        check_positive("min_lr", self.min_lr, allow_zero=True)
        check_positive("weight_decay", self.weight_decay, allow_zero=True)
        check_positive("grad_clip", self.grad_clip, allow_zero=True)


@dataclass(frozen=True)
class EvalConfig:
    """Evaluation during training."""

    every: int = 500
    """Evaluate (and save ``latest.pt``) every N optimiser steps, and at the end."""
    val_batches: int = 8
    """Batches of the held-out synthetic split per evaluation (PSNR/SSIM, depth errors)."""
    real: str | None = None
    """Folder of REAL underwater images: UIQM/UCIQE of the restored images."""
    real_max: int = 16
    """At most this many real images per evaluation."""
    real_max_side: int = 640
    """Real images are downscaled so that their long side is at most this (then padded to multiples of 32)."""
    best_metric: str = "val_psnr"
    """Log key that selects ``best.pt`` (e.g. val_psnr, val_ssim, val_silog, real_uiqm)."""
    best_mode: Literal["max", "min"] = "max"


@dataclass(frozen=True)
class TrainConfig:
    """A whole training run."""

    model: ModelConfig = field(default_factory=ModelConfig)
    data: DataConfig = field(default_factory=DataConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    loss: LossWeights = field(default_factory=LossWeights)
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    eval: EvalConfig = field(default_factory=EvalConfig)
    epochs: float = 5.0
    steps: int | None = None
    """Total optimiser steps; overrides ``epochs`` (the schedule is stretched over them)."""
    batch: int = 7
    """Samples per process per step (the original: 7)."""
    precision: Literal["fp32", "bf16"] = "fp32"
    seed: int = 0
    device: str = "cpu"
    out: str = "runs/train"
    log_every: int = 10
    compile: bool = False
    """torch.compile the network (GPU; first steps are slow while it compiles)."""
    channels_last: bool = False

    def __post_init__(self) -> None:
        if self.batch < 1:
            raise ValueError(f"batch: expected >= 1, got {self.batch}")
        check_range("loss.snow", self.loss.snow, 0.0, 1000.0)
        if self.loss.snow > 0 and "marine_snow" not in self.data.synthesis.stages:
            raise ValueError(
                "loss.snow: weights the pixels of the training input's marine snow; add marine_snow to "
                "data.synthesis.stages (online synthesis) or set loss.snow to 0"
            )
        if self.steps is not None and self.steps < 1:
            raise ValueError(f"steps: expected >= 1, got {self.steps}")
        check_positive("epochs", self.epochs)
        if self.log_every < 1:
            raise ValueError(f"log_every: expected >= 1, got {self.log_every}")
