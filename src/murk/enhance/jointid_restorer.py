"""The ``jointid_net`` restorer: Joint-ID enhancement + metric depth for images of any size, on CPU or GPU (the
``jointid`` method is the preset ``jointid_net|lite@lite_blend``: this, with the shipped ``lite``'s restoration
blended in; :mod:`murk.enhance.methods`).

Pipeline per batch: the simplest colour balance when the checkpoint's network was trained on a balanced input
(``input_balance_pct``, :mod:`murk.restore_ops.balance`; the shipped weights since 2026-12-03) -> normalise
(training recipe's mean/std) -> reflect-pad to multiples of 32 -> the network
(whole frame, or overlapping tiles blended at the seams when ``tile`` is set) -> crop back. The enhanced image
comes from the frame at its own size; the depth of a frame of more than twice ``depth_area`` pixels comes from a
second pass on the frame shrunk to about that area, upsampled. Backends: a torch
:class:`~murk.models.jointid.JointID` (fp32, or bf16/fp16 autocast; channels-last memory; optional
``torch.compile`` and CUDA-graph replay) or an exported ONNX file run by ONNX Runtime (its graph takes the frame in
[0, 1] and normalises it itself; the restorer pads and tiles as for torch).

Registry options (``murk.enhance.create("jointid_net", **options)``, the same for ``jointid``; any other option is
an error):
``checkpoint`` (murk or official ``.pth``/``.pt``, or an ``.onnx`` file; required), ``onnx`` (an ``.onnx``
path, alternative to ``checkpoint``), ``device`` ("cpu", "cuda", "cuda:N"), ``precision`` ("fp32", "bf16",
"fp16"), ``tile`` (pixels or None), ``overlap`` (pixels, default 64), ``trust_checkpoint`` (bool),
``batch`` (max frames or tiles per forward pass), ``compile`` and ``cuda_graph`` (bool, default False),
``depth_area`` (the depth of a frame of over twice this many pixels comes from a second pass at about that area,
0 = off; the method's
default is :data:`murk.enhance.choices.DEFAULT_DEPTH_AREA_PX`, while a :class:`JointIDRestorer` built directly
defaults to 0), ``refine`` (0 = no transfer: the network's output alone; the method's default is
:data:`murk.enhance.choices.DEFAULT_REFINE`, while a :class:`JointIDRestorer` built directly around a network
defaults to 0), ``refine_eps`` and ``refine_guard``; ``jointid`` adds ``lite_blend`` (the weight of its blend, default
:data:`murk.enhance.choices.DEFAULT_LITE_BLEND`).

``refine`` re-expresses the network's restoration as a locally affine map of the input
(:mod:`murk.restore_ops.affine_transfer`). The window radius is ``refine`` times the frame's long side. The output
then has the restoration's colours and the input's structure: what Eq. (1)'s inverse can do, without the network's
deblurring. ``refine_guard`` (a top-hat luma threshold, 0 = off) keeps the network's own output where it took a
small bright particle out of the input, so that the transfer does not bring marine snow back. Figures and the
trade-off: docs/enhance.md, "jointid?refine". ``exposure`` (``input`` by default with a torch network) then scales
the restoration to the mean luma of the network's balanced input (docs/enhance.md, "exposure").

``jointid``'s ``lite_blend`` averages the shipped ``lite``'s restoration of the same frame into this restorer's
output with that weight (``(1 - w) * jointid_net + w * lite``, after ``refine``; :class:`murk.enhance.restorer.Blend`):
two restorers of different design, both trained on murk's water, err differently on real water, and their mean is
closer to the references than either (figures: docs/enhance.md, "jointid?lite_blend"). Depth is Joint-ID's alone.

Reference: Yang, Kang, Lee, Cho, "Transformer-Based Joint Image Enhancement and Depth Estimation for
Underwater Environments", IEEE Sensors Journal 23(24), 2023, doi:10.1109/JSEN.2023.3338730.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable
from typing import Any, get_args

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from murk.enhance.choices import DEFAULT_OVERLAP, DEFAULT_REFINE_GUARD, Exposure, Precision
from murk.enhance.declare import Checked
from murk.enhance.methods import weights_file
from murk.enhance.refine import RefineSettings, refine_restoration
from murk.enhance.restorer import NetworkRestorer, RestoredTensor, torch_device
from murk.enhance.tiling import Padding, pad_to_multiple, tiled_apply
from murk.models.jointid.network import INPUT_MEAN, INPUT_STD, SIZE_MULTIPLE
from murk.models.padding import area_size
from murk.restore_ops.balance import color_balance_torch
from murk.restore_ops.exposure import keep_exposure_torch

_DTYPES: dict[str, torch.dtype] = {"bf16": torch.bfloat16, "fp16": torch.float16}

Backend = Callable[[Tensor], tuple[Tensor, Tensor]]


class _CudaGraphRunner:
    """Replays a captured CUDA graph of ``fn`` per input shape (static buffers; outputs are cloned)."""

    def __init__(self, fn: Backend) -> None:
        self.fn = fn
        self.graphs: dict[tuple[Any, ...], tuple[Any, Tensor, tuple[Tensor, Tensor]]] = {}

    def __call__(self, x: Tensor) -> tuple[Tensor, Tensor]:
        key = (tuple(x.shape), x.dtype, tuple(x.stride()), x.device)
        if key not in self.graphs:
            static_in = x.clone()
            stream = torch.cuda.Stream(x.device)
            stream.wait_stream(torch.cuda.current_stream(x.device))
            with torch.cuda.stream(stream):
                for _ in range(3):  # warm-up (cuDNN autotuning, lazy initialisation) outside the capture
                    self.fn(static_in)
            torch.cuda.current_stream(x.device).wait_stream(stream)
            graph = torch.cuda.CUDAGraph()
            with torch.cuda.graph(graph):
                static_out = self.fn(static_in)
            self.graphs[key] = (graph, static_in, static_out)
        graph, static_in, static_out = self.graphs[key]
        static_in.copy_(x)
        graph.replay()
        return static_out[0].clone(), static_out[1].clone()


class JointIDRestorer(NetworkRestorer):
    """Joint-ID as a :class:`~murk.enhance.restorer.Restorer` (enhanced image + depth in metres).

    Args:
        model: an in-memory :class:`~murk.models.jointid.JointID` (moved to ``device`` in place and used as
            is: the trainer can validate with its own model), or an
            :class:`~murk.models.jointid.onnx_export.OnnxJointID` runner.
        device: where the torch model runs (ONNX runners always exchange CPU tensors).
        precision: ``"fp32"``, or ``"bf16"``/``"fp16"`` autocast (torch backend only).
        tile: tile size in pixels (a multiple of 32) for large frames; None or 0 = whole frames.
        overlap: overlap of neighbouring tiles in pixels (also the blending-ramp width); None = 64.
        batch: at most this many frames (or tiles) per forward pass; None = as given.
        channels_last: run convolutions in channels-last memory (default: on CUDA only).
        compile: wrap the model with ``torch.compile`` (first call per shape compiles).
        cuda_graph: capture and replay a CUDA graph per input shape (CUDA only; for fixed-size video).
        refine: window radius of the affine transfer onto the input, as a fraction of the long side; 0 (the
            default here: the network's output alone). The ``jointid_net`` method (:func:`create_jointid`) turns it
            on (:data:`murk.enhance.choices.DEFAULT_REFINE`).
        refine_eps: the transfer's regulariser.
        refine_guard: top-hat luma from which the network's particle removal is kept against the transfer
            (0: off).
        exposure: ``input``: the restoration is scaled to the mean luma of the network's balanced input, after
            refine (:func:`murk.restore_ops.exposure.keep_exposure_torch`); ``network`` (the default here: the
            network's output alone): the network's own. The ``jointid_net`` method (:func:`create_jointid`) turns
            it on, except for an ONNX export from before murk recorded its input's balance.
        depth_area: a frame of more than twice these pixels gets its depth from a second pass of the network (whole,
            never tiled) on the frame shrunk (area resampling) to about this many pixels, each side a multiple of 32
            and the aspect kept, and the depth upsampled (bilinear) to the frame; the enhanced image is the full
            pass's. 0 (the default here): the full pass's depth. The ``jointid_net`` method
            (:func:`create_jointid`) sets :data:`murk.enhance.choices.DEFAULT_DEPTH_AREA_PX`: the network's metric
            scale follows the frame size, and it was trained near 320x240 (docs/enhance.md, "jointid?depth_area").

    Raises:
        TypeError: ``model`` is neither a JointID nor an ONNX runner.
        ValueError: bad precision/tile/overlap/batch, CUDA-only options on the CPU, or CUDA not available.
    """

    name = "jointid"

    def __init__(
        self,
        model: nn.Module | Any,
        *,
        device: str | torch.device = "cpu",
        precision: Precision = "fp32",
        tile: int | None = None,
        overlap: int | None = DEFAULT_OVERLAP,
        batch: int | None = None,
        channels_last: bool | None = None,
        compile: bool = False,
        cuda_graph: bool = False,
        refine: float = 0.0,
        refine_eps: float = 1e-4,
        refine_guard: float = DEFAULT_REFINE_GUARD,
        exposure: Exposure = "network",
        depth_area: int = 0,
    ) -> None:
        from murk.models.jointid.checkpoint import unwrap
        from murk.models.jointid.onnx_export import OnnxJointID

        tile = tile or None  # 0 = off, as None
        overlap = DEFAULT_OVERLAP if overlap is None else overlap
        if precision not in ("fp32", "bf16", "fp16"):
            raise ValueError(f"precision: expected 'fp32', 'bf16' or 'fp16', got {precision!r}")
        if tile is not None and (isinstance(tile, bool) or tile < SIZE_MULTIPLE or tile % SIZE_MULTIPLE):
            raise ValueError(f"tile: expected None or a positive multiple of {SIZE_MULTIPLE} pixels, got {tile!r}")
        if tile is not None and not 0 <= overlap < tile:
            raise ValueError(f"overlap: expected 0 <= overlap < tile ({tile}), got {overlap}")
        if overlap < 0:
            raise ValueError(f"overlap: expected >= 0 pixels, got {overlap}")
        if batch is not None and (isinstance(batch, bool) or batch < 1):
            raise ValueError(f"batch: expected None or a positive integer, got {batch!r}")
        if isinstance(depth_area, bool) or not isinstance(depth_area, int) or depth_area < 0:
            raise ValueError(f"depth_area: expected 0 (off) or a number of pixels, got {depth_area!r}")
        self.depth_area = depth_area
        """Pixels above which the depth comes from a pass at about this area (0: the frame's own pass)."""
        if exposure not in get_args(Exposure):
            raise ValueError(f"exposure: expected input or network, got {exposure!r}")
        if exposure == "input" and isinstance(model, OnnxJointID) and not model.balance_recorded:
            raise ValueError(
                f"exposure: input needs to know the balance of the network's input, which {model.path} does not "
                "record (an export from an earlier murk); export it again with 'murk export', or leave exposure out"
            )
        self.keep_exposure = exposure == "input"
        """Whether the restoration keeps the exposure of the network's balanced input (the ``exposure`` option)."""
        self._graph_balance_pct = model.graph_balance_pct if isinstance(model, OnnxJointID) else None
        self.refine_settings = RefineSettings(refine, refine_eps, refine_guard)
        """The ``refine`` step after the network (:mod:`murk.enhance.refine`)."""
        self.precision = precision
        self.weights: str | None = None
        """The weights file this restorer was loaded from (set by :func:`create_jointid`)."""
        self._mean: Tensor | None = None
        self._std: Tensor | None = None
        self.tile = tile
        self.overlap = int(overlap)
        self.batch = batch
        self.input_balance_pct: float | None = getattr(
            unwrap(model) if isinstance(model, nn.Module) else model, "input_balance_pct", None
        )
        """The simplest colour balance the network's input takes (from the checkpoint; None: none)."""
        if isinstance(model, OnnxJointID):
            if precision != "fp32":
                raise ValueError(
                    f"precision: ONNX models run in fp32, got {precision!r}; leave precision out or give a .pt"
                )
            if compile or cuda_graph:
                raise ValueError(
                    "compile/cuda_graph: only for the torch backend, not for ONNX models; leave them out or give a .pt"
                )
            self.device = torch.device("cpu")
            self.model: nn.Module | None = None
            self.channels_last = False
            self._backend: Backend = model
            self._depth_backend: Callable[[Tensor], Tensor] | None = None  # the graph runs whole
            return
        if not isinstance(model, nn.Module):
            raise TypeError(f"model: expected a JointID or an OnnxJointID, got {type(model).__name__}")
        net = unwrap(model)
        self.device = torch_device(device)
        if cuda_graph and self.device.type != "cuda":
            raise ValueError("cuda_graph: needs device cuda; add --device cuda, or leave cuda_graph out")
        self.channels_last = self.device.type == "cuda" if channels_last is None else bool(channels_last)
        net.to(self.device)
        if self.channels_last:
            net.to(memory_format=torch.channels_last)  # type: ignore[call-overload]  # valid; torch's stubs lack it
        self.model = net
        fn: Callable[[Tensor], Any] = torch.compile(net, dynamic=False) if compile else net  # one kernel set per shape

        def run(x: Tensor) -> tuple[Tensor, Tensor]:
            with self._autocast():
                out = fn(x)
            return out[0].float(), out[1].float()

        def run_depth(x: Tensor) -> Tensor:
            with self._autocast():
                return net.depth(x).float()

        self._backend = _CudaGraphRunner(run) if cuda_graph else run
        # The depth pass of ``depth_area`` runs the depth alone (a fifth less work), except where a compiled graph or
        # a captured CUDA graph of the whole forward is what runs
        self._depth_backend = None if compile or cuda_graph else run_depth

    def _autocast(self) -> contextlib.AbstractContextManager[Any]:
        if self.precision == "fp32":
            return contextlib.nullcontext()
        # No weight-cast cache: each weight is used once per forward, and CUDA-graph capture requires it off.
        return torch.autocast(self.device.type, dtype=_DTYPES[self.precision], cache_enabled=False)

    def _normalize(self, images: Tensor) -> Tensor:
        """``normalize_input`` with the mean/std kept on the device (no host-to-device copy per call)."""
        if self._mean is None or self._std is None or self._mean.device != images.device:
            self._mean = torch.tensor(INPUT_MEAN, device=images.device).view(1, 3, 1, 1)
            self._std = torch.tensor(INPUT_STD, device=images.device).view(1, 3, 1, 1)
        return (images - self._mean) / self._std

    def _tiled(self, x: Tensor) -> bool:
        """Whether a batch of this size runs in tiles."""
        return self.tile is not None and (x.shape[2] > self.tile or x.shape[3] > self.tile)

    def _forward_padded(self, x: Tensor, *, tiled: bool) -> tuple[Tensor, Tensor]:
        """Normalised, padded batch -> (depth_m, enhanced), whole or ``tiled``, in chunks of ``batch``."""
        if tiled and self.tile is not None:
            depth, enhanced = tiled_apply(self._backend, x, tile=self.tile, overlap=self.overlap, max_batch=self.batch)
            return depth, enhanced
        step = self.batch or x.shape[0]
        outs = [self._backend(x[i : i + step]) for i in range(0, x.shape[0], step)]
        return torch.cat([o[0] for o in outs]), torch.cat([o[1] for o in outs])

    def _restore_network(self, images: Tensor, x: Tensor) -> RestoredTensor:
        """The enhanced batch and its depth (m): the network's pass (:meth:`_pass`), ``refine``, the exposure step;
        the depth from a second pass at about :attr:`depth_area` pixels for a frame of more than twice that
        (:func:`depth_pass_size`)."""
        depth, enhanced, balanced = self._pass(x, keep_balanced=self.keep_exposure)
        enhanced = refine_restoration(images, enhanced, self.refine_settings)
        if balanced is not None:
            enhanced = keep_exposure_torch(enhanced, balanced.to(enhanced.device, enhanced.dtype))
        size = depth_pass_size(x.shape[2], x.shape[3], self.depth_area)
        if size is not None:  # whole, never in tiles: each tile would see a part of the scene at the wrong scale
            depth_small = self._depth_pass(F.interpolate(x, size=size, mode="area"))
            depth = F.interpolate(depth_small, size=x.shape[2:], mode="bilinear", align_corners=False)
        return RestoredTensor(enhanced, depth)

    def _pass(
        self, x: Tensor, *, keep_balanced: bool = False, whole: bool = False
    ) -> tuple[Tensor, Tensor, Tensor | None]:
        """One pass of the network over a batch in [0, 1] (:meth:`_prepared`, the network, crop) -> (depth in m,
        enhanced, the balanced input when ``keep_balanced``: the exposure step's reference)."""
        x, pad, tiled, balanced = self._prepared(x, keep_balanced=keep_balanced, whole=whole)
        depth, enhanced = self._forward_padded(x, tiled=tiled)
        return pad.crop(depth).contiguous(), pad.crop(enhanced).clamp(0.0, 1.0).contiguous(), balanced

    def _depth_pass(self, x: Tensor) -> Tensor:
        """The depth (m) of a batch in [0, 1] from one whole (never tiled) pass: the network's depth alone
        (:meth:`murk.models.jointid.JointID.depth`, bit for bit its forward's) where it can run it, else the whole
        forward (an ONNX graph, a compiled or CUDA-graph backend)."""
        if self._depth_backend is None:
            return self._pass(x, whole=True)[0]
        x, pad, _, _ = self._prepared(x, whole=True)
        step = self.batch or x.shape[0]
        depth = torch.cat([self._depth_backend(x[i : i + step]) for i in range(0, x.shape[0], step)])
        return pad.crop(depth).contiguous()

    def _prepared(
        self, x: Tensor, *, keep_balanced: bool = False, whole: bool = False
    ) -> tuple[Tensor, Padding, bool, Tensor | None]:
        """A batch in [0, 1] made ready for the network: balanced, normalised, padded (and channels-last) -> (the
        batch, its padding, whether it runs in tiles: ``tile`` is set, the frame exceeds it and not ``whole``, the
        balanced input when ``keep_balanced``)."""
        if self.input_balance_pct is not None:  # the input the network was trained on
            x = color_balance_torch(x, self.input_balance_pct, self.input_balance_pct)
        balanced = x if keep_balanced else None  # the exposure step's reference (kept only when it runs)
        if keep_balanced and self._graph_balance_pct is not None:
            pct = self._graph_balance_pct  # an ONNX graph balances inside: the same balance, for the exposure step
            balanced = color_balance_torch(x, pct, pct)
        if self.model is not None:  # an ONNX export normalises inside its graph
            x = self._normalize(x)
        # An ONNX export takes whole frames of any size and balances, normalises and pads them itself: padded
        # here first, its balance would take its levels from the padding too. Tiles are padded here.
        tiled = not whole and self._tiled(x)
        whole_onnx = self.model is None and not tiled
        x, pad = pad_to_multiple(x, 1 if whole_onnx else SIZE_MULTIPLE, "reflect")
        if self.channels_last:
            x = x.contiguous(memory_format=torch.channels_last)
        return x, pad, tiled, balanced

    def __repr__(self) -> str:
        backend = self._backend if self.model is None else type(self.model).__name__
        return (
            f"JointIDRestorer({backend}, device={self.device}, precision={self.precision}, tile={self.tile}, "
            f"overlap={self.overlap}, batch={self.batch}, refine={self.refine_settings.radius}, "
            f"keep_exposure={self.keep_exposure}, depth_area={self.depth_area})"
        )


def depth_pass_size(height: int, width: int, area: int) -> tuple[int, int] | None:
    """The size (h, w) of the depth pass for a ``height`` x ``width`` frame: the frame shrunk to about ``area``
    pixels, each side a multiple of 32 and the aspect kept (:func:`murk.models.padding.area_size`); None (the
    frame's own pass gives the depth) when ``area`` is 0, or when that pass would have more than half the frame's
    pixels (it would cost nearly another full pass for little change in scale; so frames up to about twice
    ``area`` keep their own depth)."""
    size = area_size(height, width, area, SIZE_MULTIPLE)
    if size is None or 2 * size[0] * size[1] > height * width:
        return None
    return size


def create_jointid(o: Checked) -> JointIDRestorer:
    """Implementation of ``jointid_net`` (declared in :mod:`murk.enhance.methods`; ``jointid`` blends ``lite`` into
    it): load ``checkpoint`` (or the ``onnx`` file) and wrap it.

    Without either, the weights shipped with murk are used (``murk.data.shipped_jointid_weights()``: the
    ``small`` Joint-ID murk trained itself, model card ``docs/models.md``). The restorer's ``weights``
    attribute names the file used. A checkpoint path ending in ``.onnx`` runs with ONNX Runtime. Other options: see
    :class:`JointIDRestorer`.

    Raises:
        ValueError: no checkpoint given, or bad options.
        InputFileError: the checkpoint cannot be loaded (see ``murk.models.jointid.load_checkpoint``).
    """
    from murk.data import shipped_jointid_weights
    from murk.models.jointid.checkpoint import load_checkpoint
    from murk.models.jointid.onnx_export import OnnxJointID

    path = weights_file(
        o.checkpoint,
        o.onnx,
        shipped_jointid_weights,
        "checkpoint: the shipped weights {path} are missing from this installation; give --checkpoint FILE (a murk "
        "or the official Joint-ID checkpoint, or an .onnx export)",
    )
    if o.onnx is not None or str(path).lower().endswith(".onnx"):
        model: nn.Module | OnnxJointID = OnnxJointID(path, device=str(o.device))
        dev = torch.device("cpu")
        exposure: Exposure = o.exposure or ("input" if model.balance_recorded else "network")
    else:
        dev = torch_device(o.device)
        model = load_checkpoint(path, trust=o.trust_checkpoint, device="cpu")
        exposure = o.exposure or "input"
    settings = {k: o[k] for k in ("precision", "tile", "overlap", "batch", "compile", "cuda_graph")}
    restorer = JointIDRestorer(
        model,
        device=dev,
        refine=o.refine,
        refine_eps=o.refine_eps,
        refine_guard=o.refine_guard,
        exposure=exposure,
        depth_area=o.depth_area,
        **settings,
    )
    restorer.weights = str(path)
    return restorer
