"""The ``lite`` restorer: the small real-time network (:mod:`murk.models.lite`) for images of any size.

Pipeline per batch: the simplest colour balance when the checkpoint's network was trained on a balanced input
(``input_balance_pct``, :mod:`murk.restore_ops.balance`; the shipped weights since 2026-12-03; with ``temporal`` its
levels are averaged over a video's frames like the maps) -> the working image (a frame larger than the network's
``work_area_px``, 128x160 for the shipped weights, is area-downsampled to about that many pixels; a smaller frame
is reflect-padded to multiples of 16 and used itself) -> the folded (re-parameterised) network computes gain and
offset maps from it -> upsampled to the frame -> ``gain * frame + offset`` -> clamp to [0, 1]. The frame itself
is never resampled. No depth. An ONNX export (:mod:`murk.models.lite.onnx_export`) does all of that inside its
graph: the runner gets the frames as they are. Then, with ``refine`` > 0 (off by default), the restoration is
re-expressed as a locally affine map of the input with the particle guard (:mod:`murk.enhance.refine`), outside
the ONNX graph.

Registry options (``murk.enhance.create("lite", **options)``; any other option is an error):
``checkpoint`` (a ``murk train`` checkpoint with ``model.kind: lite``, or an ``.onnx`` export; default: the
weights shipped with murk), ``onnx`` (an ``.onnx`` path, alternative to ``checkpoint``), ``device`` ("cpu",
"cuda", "cuda:N"; ONNX runs on the CPU), ``precision`` (only "fp32"), ``trust_checkpoint`` (bool), ``batch``
(max frames per forward pass), ``threads`` (ONNX Runtime intra-op threads), ``temporal`` (weight in [0, 1) of
the previous frames in an average of the low-resolution maps over a video's frames, :mod:`murk.enhance.temporal`;
0 = each frame on its own; torch network only), ``refine``, ``refine_eps`` and ``refine_guard`` (as ``jointid``'s,
but ``refine`` 0 by default), ``exposure`` (``input``, the default: the maps are scaled so that the restoration keeps
the mean luma of the balanced input, :func:`murk.models.lite.network.keep_exposure`; ``network``: the network's own;
an ONNX export keeps what it was exported with).
"""

from __future__ import annotations

import contextlib
import copy
from collections.abc import Iterator
from typing import Any, get_args

import numpy as np
import torch
import torch.nn.functional as F
from torch import Tensor, nn

from murk.enhance.choices import DEFAULT_REFINE_GUARD, Exposure
from murk.enhance.declare import Checked
from murk.enhance.methods import weights_file
from murk.enhance.refine import RefineSettings, refine_restoration
from murk.enhance.restorer import NetworkRestorer, RestoredTensor, torch_device
from murk.enhance.temporal import FrameEMA
from murk.models.lite.network import (
    LUMA,
    SIZE_MULTIPLE,
    apply_maps,
    apply_maps_hwc,
    reparameterize,
    unwrap,
    work_image,
    work_size,
)
from murk.models.padding import pad_to_multiple
from murk.restore_ops.balance import apply_levels, apply_levels_torch, balance_levels, balance_levels_torch


class LiteRestorer(NetworkRestorer):
    """The ``lite`` network as a :class:`~murk.enhance.restorer.Restorer` (enhanced image, no depth).

    Args:
        model: a :class:`~murk.models.lite.network.LiteNet` (training form: folded here into a new module; or
            already folded: used as is and moved to ``device``), or an
            :class:`~murk.models.lite.onnx_export.OnnxLite` runner.
        device: where the torch network runs (ONNX runners always run on the CPU).
        batch: at most this many frames per forward pass; None = as given.
        temporal: inside :meth:`sequence`, average the 12 low-resolution maps (:meth:`LiteNet.maps`) over the
            frames with this weight of the past (:class:`murk.enhance.temporal.FrameEMA`); 0 = off.
        refine, refine_eps, refine_guard: the affine transfer of the restoration onto the input, with the particle
            guard, after the network (:mod:`murk.enhance.refine`; ``refine`` 0 = off, the default: it costs a
            640x480 frame about 1.4x, benchmarks/bench_refine.py).
        exposure: ``input``: the restoration keeps the mean luma of the network's (balanced) input
            (:func:`murk.models.lite.network.keep_exposure`, in the maps: every path gets it at no full-resolution
            cost); ``network``: the network's own; None (the default here): as the model holds it (a LiteNet's
            ``keep_exposure``, off unless set; what an ONNX export was made with). The ``lite`` method
            (:func:`create_lite`) turns it on for torch weights.

    Raises:
        TypeError: ``model`` is neither a LiteNet nor an OnnxLite.
        ValueError: a bad ``batch``, ``temporal`` or ``exposure``, ``temporal`` with an ONNX runner, an
            ``exposure`` other than an ONNX export's, or CUDA not available.
    """

    name = "lite"

    def __init__(
        self,
        model: nn.Module | Any,
        *,
        device: str | torch.device = "cpu",
        batch: int | None = None,
        temporal: float = 0.0,
        refine: float = 0.0,
        refine_eps: float = 1e-4,
        refine_guard: float = DEFAULT_REFINE_GUARD,
        exposure: Exposure | None = None,
    ) -> None:
        from murk.models.lite.onnx_export import OnnxLite

        if exposure is not None and exposure not in get_args(Exposure):
            raise ValueError(f"exposure: expected input, network or None, got {exposure!r}")
        if batch is not None and (isinstance(batch, bool) or batch < 1):
            raise ValueError(f"batch: expected None or a positive integer, got {batch!r}")
        self.batch = batch
        self.refine_settings = RefineSettings(refine, refine_eps, refine_guard)
        """The ``refine`` step after the network (:mod:`murk.enhance.refine`)."""
        self.weights: str | None = None
        """The weights file this restorer was loaded from (set by the ``lite`` factory)."""
        ema = FrameEMA(temporal)
        self.temporal_state = ema if ema.weight > 0 else None
        self.input_balance_pct: float | None = getattr(
            unwrap(model) if isinstance(model, nn.Module) else model, "input_balance_pct", None
        )
        """The simplest colour balance the network's input takes (from the checkpoint; None: none)."""
        levels_ema = FrameEMA(temporal)
        self.levels_state = levels_ema if levels_ema.weight > 0 and self.input_balance_pct is not None else None
        """Inside :meth:`sequence` with a ``temporal`` weight the balance's levels are averaged over the frames as the
        maps are (a per-frame balance alone flickers when the scene's extremes move)."""
        if isinstance(model, OnnxLite):
            if self.temporal_state is not None:
                raise ValueError(
                    "temporal: needs the torch network (an ONNX export computes its maps inside); give the .pt "
                    "checkpoint, or leave temporal out"
                )
            baked = "input" if model.keep_exposure else "network"
            if exposure is not None and exposure != baked:
                how = "its murk.exposure metadata" if model.exposure_recorded else "an earlier murk: no murk.exposure"
                raise ValueError(
                    f"exposure: {model.path} was exported with exposure {baked} ({how}); export it again with "
                    f"'murk export --exposure {exposure}', or leave exposure out"
                )
            self.device = torch.device("cpu")
            self.model: nn.Module | None = None
            self._backend: Any = model
            self.work_area_px = model.work_area_px
            self.keep_exposure = model.keep_exposure
            return
        if not isinstance(model, nn.Module):
            raise TypeError(f"model: expected a LiteNet or an OnnxLite, got {type(model).__name__}")
        dev = torch_device(device)
        self.device = dev
        # Channels-last memory: a numpy frame (H, W, 3) already is, so nothing is transposed on the way in or out,
        # and the full-resolution steps (pooling, upsampling, gain * x + offset) run faster (about 15%, CPU).
        net = reparameterize(unwrap(model))
        if exposure is not None:
            if net is unwrap(model):  # already folded: the caller's module; the flag is set on a shallow copy
                net = copy.copy(net)
            net.keep_exposure = exposure == "input"
        else:
            net.keep_exposure = unwrap(model).keep_exposure  # reparameterize makes a new module
        self.keep_exposure = net.keep_exposure
        """Whether the restoration keeps the input's exposure (the ``exposure`` option)."""
        channels_last = net.float().to(dev).to(memory_format=torch.channels_last)  # type: ignore[call-overload]
        self.model = channels_last.eval()  # (valid: torch's stubs lack memory_format on Module.to)
        self._backend = self.model
        self.work_area_px = net.config.work_area_px
        """Frames with more pixels are area-downsampled to about this many for the coefficients (0: never)."""

    def _restore_network(self, images: Tensor, x: Tensor) -> RestoredTensor:
        """The enhanced batch: balance, the network's maps (averaged over time inside :meth:`sequence` with a
        ``temporal`` weight) applied at full resolution, refine."""
        if self.input_balance_pct is not None:  # the input the network was trained on
            levels = _balance_levels(x, self.input_balance_pct)
            if self.levels_state is not None and self.temporal_hook() is not None:
                levels = self.levels_state(levels)
            x = _apply_levels(x, levels)
        step = self.batch or x.shape[0]
        model = self.model
        if model is None:  # an ONNX export: working image, padding and clamping are in its graph
            outs = [self._backend(x[i : i + step]) for i in range(0, x.shape[0], step)]
            out = outs[0] if len(outs) == 1 else torch.cat(outs)
            return RestoredTensor(refine_restoration(images, out, self.refine_settings), None)
        native = work_size(x.shape[-2], x.shape[-1], self.work_area_px) is None
        if native:  # the frame itself is the working image: its sides must be multiples of 16
            x, pad = pad_to_multiple(x, SIZE_MULTIPLE, "reflect")
        x = x.contiguous(memory_format=torch.channels_last)
        outs = []
        for i in range(0, x.shape[0], step):
            chunk = x[i : i + step]
            work = chunk if native else work_image(chunk, self.work_area_px)
            ema = self.temporal_hook()
            if self.device.type == "cpu":
                outs.append(_forward_cpu(model, chunk, work, ema))
            elif ema is not None:
                lo = ema(model.maps(work))  # type: ignore[operator]
                maps = F.interpolate(lo, size=chunk.shape[-2:], mode="bilinear")
                outs.append(apply_maps(maps, chunk))  # LiteNet.forward with the averaged maps
            else:
                outs.append(model(chunk, work))
        out = outs[0] if len(outs) == 1 else torch.cat(outs)
        if self.device.type != "cpu":  # the CPU step clamps strip by strip
            out = out.clamp_(0.0, 1.0)
        enhanced = pad.crop(out) if native else out
        enhanced = refine_restoration(images, enhanced, self.refine_settings)
        return RestoredTensor(enhanced, None)

    def restore_u8(self, frames: np.ndarray, out_dtype: type = np.uint8) -> np.ndarray | None:
        """The restoration of a batch of uint8 RGB frames (B, H, W, 3) as uint8 (``out_dtype``) or float32, by the
        fused 8-bit path (:mod:`murk.enhance.lite_u8`: equal to :meth:`restore` of ``to_float(frames)`` within
        float rounding, then rounded); None where that path does not apply (an ONNX runner, CUDA, ``refine``, or
        frames the network sees at their own resolution): the caller then takes :meth:`restore`."""
        from murk.enhance.lite_u8 import frame_levels, restore_frame

        model = self.model
        if model is None or self.device.type != "cpu" or self.refine_settings.on or frames.dtype != np.uint8:
            return None
        if work_size(frames.shape[1], frames.shape[2], self.work_area_px) is None:
            return None
        out = []
        with torch.inference_mode():
            for frame in frames:
                levels = None
                if self.input_balance_pct is not None:
                    levels = frame_levels(frame, self.input_balance_pct)
                    if self.levels_state is not None and self.temporal_hook() is not None:
                        levels = self.levels_state(torch.from_numpy(levels)[None])[0].numpy()
                restored = restore_frame(
                    model, frame, levels, self.work_area_px, out_dtype=out_dtype, ema=self.temporal_hook()
                )
                if restored is None:
                    return None
                out.append(restored)
        return out[0][None] if len(out) == 1 else np.stack(out)

    @contextlib.contextmanager
    def sequence(self) -> Iterator[None]:
        """:meth:`Restorer.sequence`, the balance's levels averaged afresh too."""
        if self.levels_state is not None:
            self.levels_state.reset()
        with super().sequence():
            yield

    def __repr__(self) -> str:
        backend = self._backend if self.model is None else "LiteNet (folded)"
        return (
            f"LiteRestorer({backend}, device={self.device}, batch={self.batch}, refine={self.refine_settings.radius}, "
            f"keep_exposure={self.keep_exposure})"
        )


def _forward_cpu(model: nn.Module, x: Tensor, work: Tensor, ema: FrameEMA | None = None) -> Tensor:
    """The network's forward on the CPU with the full-resolution upsampling done by OpenCV, clamped to [0, 1]: the
    same result as ``model(x, work).clamp(0, 1)`` (bilinear with half-pixel centres, as torch's; equal within 5e-5,
    pinned by tests) and about 9x faster for the 12 maps of a 1280x720 frame than ``F.interpolate`` on 2 threads.
    The maps are applied and the result clamped in strips of :data:`STRIP_ROWS` rows, so that the temporaries stay
    in the cache (2x faster at 1280x720; the clamp saves a pass over the frame).
    ``ema`` averages the low-resolution maps over consecutive frames first."""
    import cv2

    maps = model.maps(work)  # type: ignore[operator]
    if ema is not None:
        maps = ema(maps)
    h, w = x.shape[-2:]
    out = torch.empty((x.shape[0], h, w, 3), dtype=x.dtype)
    for i in range(x.shape[0]):
        lo = maps[i].permute(1, 2, 0).numpy()
        # four 3-channel resizes: OpenCV's 12-channel path is 2.2x slower at 640x480 (0.60 against 0.27 ms)
        a_gain, a_offset, b_gain, b_offset = (
            torch.from_numpy(cv2.resize(np.ascontiguousarray(lo[:, :, k : k + 3]), (w, h))) for k in (0, 3, 6, 9)
        )
        frame = x[i].permute(1, 2, 0)
        frame_np = frame.numpy()
        for r0 in range(0, h, STRIP_ROWS):
            rows = slice(r0, r0 + STRIP_ROWS)
            luma = torch.from_numpy(cv2.transform(frame_np[rows], _LUMA_ROW))[..., None]  # one SIMD pass
            maps_at = (a_gain[rows], a_offset[rows], b_gain[rows], b_offset[rows])
            apply_maps_hwc(*maps_at, frame[rows], luma=luma, out=out[i, rows]).clamp_(0.0, 1.0)
    return out.permute(0, 3, 1, 2)  # (B, 3, H, W) in channels-last memory


_LUMA_ROW = np.array([LUMA], np.float32)
"""The guide's luma weights as OpenCV's 1x3 colour transform."""


def _balance_levels(x: Tensor, pct: float) -> Tensor:
    """The levels (B, 2, 3) of the simplest colour balance of a batch (B, 3, H, W): on the CPU with the numpy twin
    per frame (numpy's sort of the strided sample against torch's ``topk``), elsewhere with the torch twin; equal
    (tests/twins.py)."""
    if x.device.type != "cpu":
        return balance_levels_torch(x, pct, pct)
    return torch.stack([torch.from_numpy(balance_levels(f.permute(1, 2, 0).numpy(), pct, pct)) for f in x])


def _apply_levels(x: Tensor, levels: Tensor) -> Tensor:
    """The simplest colour balance of a batch (B, 3, H, W) with its levels (B, 2, 3): on the CPU with the numpy twin
    per frame (OpenCV's threaded per-channel arithmetic on the channels-last frame, no transposition), elsewhere
    with the torch twin; equal (tests/twins.py)."""
    if x.device.type != "cpu":
        return apply_levels_torch(x, levels)
    frames = [
        torch.from_numpy(apply_levels(f.permute(1, 2, 0).numpy(), lv.numpy())).permute(2, 0, 1)
        for f, lv in zip(x, levels, strict=True)
    ]
    return frames[0][None] if len(frames) == 1 else torch.stack(frames).contiguous(memory_format=torch.channels_last)


STRIP_ROWS = 128
"""Rows per strip when the coefficient maps are applied on the CPU (measured: 16-128 rows all about 2x faster
than the whole frame at 1280x720; 128 the fastest)."""


def create_lite(o: Checked) -> LiteRestorer:
    """Implementation of ``lite`` (declared in :mod:`murk.enhance.methods`): load ``checkpoint`` (or the ``onnx``
    file), fold it and wrap it.

    Without either, the weights shipped with murk are used (``murk.data.shipped_lite_weights()``, model card
    ``docs/models.md``); the restorer's ``weights`` attribute names the file used. A checkpoint path ending in
    ``.onnx`` runs with ONNX Runtime.

    Raises:
        ValueError: no checkpoint given and no shipped weights, both checkpoint and onnx, or a precision other
            than fp32.
        InputFileError: the checkpoint cannot be loaded (see ``murk.models.lite.checkpoint.read_lite_checkpoint``).
    """
    from murk.data import shipped_lite_weights
    from murk.models.lite.checkpoint import load_lite
    from murk.models.lite.onnx_export import OnnxLite

    if o.precision != "fp32":
        raise ValueError(f"precision: the lite network runs in fp32 only, got {o.precision!r}; leave precision out")
    path = weights_file(
        o.checkpoint,
        o.onnx,
        shipped_lite_weights,
        "checkpoint: no shipped lite weights exist in this installation ({path} is missing); pass --checkpoint FILE "
        "(a 'murk train' checkpoint with model.kind: lite, or its .onnx export)",
    )
    onnx_file = o.onnx is not None or str(path).lower().endswith(".onnx")
    restorer = LiteRestorer(
        OnnxLite(path, threads=o.threads) if onnx_file else load_lite(path, trust=o.trust_checkpoint, fold=True),
        device="cpu" if onnx_file else o.device,
        batch=o.batch,
        temporal=o.temporal,
        refine=o.refine,
        refine_eps=o.refine_eps,
        refine_guard=o.refine_guard,
        exposure=o.exposure if onnx_file else o.exposure or "input",
    )
    restorer.weights = str(path)
    return restorer
