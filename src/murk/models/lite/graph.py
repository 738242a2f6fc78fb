"""The ``lite`` restorer's whole computation on one input, written to trace into an ONNX graph with dynamic batch,
height and width (:mod:`murk.models.lite.onnx_export`), and the plain torch reference it is verified against.

:class:`LiteImageGraph` takes frames (B, 3, H, W), RGB in [0, 1], of any H, W >= 1 and returns what the ``lite``
restorer (:class:`murk.enhance.lite_restorer.LiteRestorer`) returns: the restored frames, clamped to [0, 1].
Everything the restorer does around the network happens inside, with the size arithmetic done on tensors (so the
tracer records it and the graph follows each frame's size). Two paths, as in the restorer:

- ``native`` (a frame of at most ``work_area_px`` pixels): the frame is its own working image, reflect-padded to
  multiples of 16 (:func:`murk.models.padding.reflect_rows`: one gather per axis); the maps are upsampled to
  the padded size and cropped back;
- ``downsample`` (larger frames): the working image is the frame area-downsampled to
  :func:`~murk.models.lite.network.work_size` (:func:`~murk.models.lite.network.work_size_tensor`) with
  ``F.interpolate(mode="area")``'s windows (rows ``floor(i H / h)`` to ``ceil((i + 1) H / h)``): one gather of
  the windows' rows (columns) per axis, summed, divided by the window's area.

Then the network's 12 low-resolution maps (:meth:`~murk.models.lite.network.LiteNet.maps`) are split into the
four 3-channel maps (``a`` and ``b`` of gain and offset) before they are upsampled bilinearly, so that the
full-resolution steps are whole-tensor products and sums (no channel slices, which ONNX Runtime copies):
``gain = up(a_gain) Y + up(b_gain)``, ``offset = up(a_offset) Y + up(b_offset)``, ``gain * x + offset``
(:func:`~murk.models.lite.network.apply_maps`, reordered), clamped.

:func:`restore_reference` is the same computation written plainly with the network's own ``forward`` (as the
restorer runs it, with torch's bilinear upsampling where the CPU restorer uses OpenCV's: equal within 5e-5).
"""

from __future__ import annotations

from typing import Literal

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from murk.models.balance_graph import color_balance_graph
from murk.models.lite.network import LUMA, SIZE_MULTIPLE, LiteNet, work_image, work_size, work_size_tensor
from murk.models.padding import pad_to_multiple, reflect_rows
from murk.restore_ops.balance import color_balance_torch

LitePath = Literal["native", "downsample"]


def lite_path(height: int, width: int, work_area_px: int) -> LitePath:
    """Which path a frame of ``height`` x ``width`` takes (the restorer's choice)."""
    return "native" if work_size(height, width, work_area_px) is None else "downsample"


def restore_reference(net: LiteNet, x: Tensor) -> Tensor:
    """What the ``lite`` restorer computes for frames ``x`` (B, 3, H, W) in [0, 1] with the torch network ``net``
    (folded, eval mode), written plainly: reflect-pad a frame that is its own working image, the network's
    ``forward`` with :func:`~murk.models.lite.network.work_image`, clamp, crop; the frames balanced first when
    the network was trained so (``input_balance_pct``)."""
    if net.input_balance_pct is not None:
        x = color_balance_torch(x, net.input_balance_pct, net.input_balance_pct)
    native = lite_path(int(x.shape[2]), int(x.shape[3]), net.config.work_area_px) == "native"
    if native:
        x, pad = pad_to_multiple(x, SIZE_MULTIPLE, "reflect")
    out = net(x, x if native else work_image(x, net.config.work_area_px)).clamp(0.0, 1.0)
    return pad.crop(out) if native else out


def _area_axis(x: Tensor, dim: int, n: Tensor, n_out: Tensor) -> tuple[Tensor, Tensor]:
    """Window sums along ``dim`` (2 or 3) of ``x`` (axis length ``n``) for ``n_out`` windows of
    ``F.interpolate(mode="area")``, and the windows' sizes."""
    i = torch.arange(n_out)  # type: ignore[call-overload]  # 0-dim tensors: traced as ONNX Range
    start = torch.div(i * n, n_out, rounding_mode="floor")
    size = torch.div((i + 1) * n + n_out - 1, n_out, rounding_mode="floor") - start
    k = torch.arange(size.max())  # type: ignore[call-overload]
    rows = start[:, None] + torch.minimum(k[None, :], size[:, None] - 1)  # (n_out, K); a short window repeats ...
    weight = (k[None, :] < size[:, None]).to(x.dtype)  # ... its last row with weight 0
    if dim == 2:
        return (x[:, :, rows] * weight[:, :, None]).sum(3), size
    return (x[:, :, :, rows] * weight).sum(4), size


class LiteImageGraph(nn.Module):
    """The ``lite`` restorer as one module (see the module docstring): frames (B, 3, H, W) RGB in [0, 1] of any
    size -> restored frames, clamped to [0, 1].

    Args:
        net: a folded :class:`~murk.models.lite.network.LiteNet` (used as is: fp32, eval mode).
        path: trace only this path (the exporter traces each into a branch of one graph); None: choose per frame
            size as the restorer does.
    """

    luma: Tensor

    def __init__(self, net: LiteNet, path: LitePath | None = None) -> None:
        super().__init__()
        self.net = net
        self.path = path
        self.work_area_px = int(net.config.work_area_px)
        self.balance_pct: float | None = net.input_balance_pct
        self.register_buffer("luma", torch.tensor(LUMA).view(1, 3, 1, 1), persistent=False)

    def forward(self, image: Tensor) -> Tensor:
        if self.balance_pct is not None:  # the input the network was trained on (model.input_balance_pct)
            image = color_balance_graph(image, self.balance_pct, self.balance_pct)
        shape = torch._shape_as_tensor(image)  # traced: the graph computes every size from the frame's
        h, w = shape[2], shape[3]
        path = self.path or lite_path(int(image.shape[2]), int(image.shape[3]), self.work_area_px)
        if path == "native":
            h_pad = h + torch.remainder(-h, SIZE_MULTIPLE)
            w_pad = w + torch.remainder(-w, SIZE_MULTIPLE)
            top = torch.div(h_pad - h, 2, rounding_mode="floor")  # as murk.models.padding.padding_for
            left = torch.div(w_pad - w, 2, rounding_mode="floor")
            work = image[:, :, reflect_rows(h, h_pad, top)][:, :, :, reflect_rows(w, w_pad, left)]
        else:
            h_work, w_work = work_size_tensor(h, w, self.work_area_px)
            rows, h_size = _area_axis(image, 2, h, h_work)
            work, w_size = _area_axis(rows, 3, w, w_work)
            work = work / (h_size[:, None] * w_size[None, :]).to(image.dtype)
            h_pad, w_pad = h, w
        lo = self.net.maps(work)  # (B, 12, h / 4, w / 4): a of gain, a of offset, b of gain, b of offset

        def up(maps: Tensor) -> Tensor:
            size = (h_pad, w_pad)  # tensors: traced, the graph upsamples to each frame's size
            full = F.interpolate(maps, size=size, mode="bilinear", align_corners=False)  # type: ignore[arg-type]
            return full[:, :, top : top + h, left : left + w] if path == "native" else full

        y = (image * self.luma).sum(1, keepdim=True)
        gain = up(lo[:, 0:3]) * y + up(lo[:, 6:9])
        offset = up(lo[:, 3:6]) * y + up(lo[:, 9:12])
        return (gain * image + offset).clamp(0.0, 1.0)  # Eq. (1) inverted, per channel (apply_maps)
