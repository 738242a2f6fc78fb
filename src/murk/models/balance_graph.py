"""The simplest colour balance (:mod:`murk.restore_ops.balance`) written to trace into an ONNX graph with dynamic
batch, height and width, for exports of networks trained on balanced inputs (``model.input_balance_pct``).

The same computation as :func:`murk.restore_ops.balance.color_balance_torch`, with the size arithmetic on tensors
(so that the graph follows each frame's size): the stride of the sampled pixels (``ceil(sqrt(H W / STATS_PX))``,
at least 1), the rows and columns sampled, a full sort of the sample (ONNX TopK; about 20,000 values per channel
at most) and the two order statistics each percentile interpolates between, gathered by index.
"""

from __future__ import annotations

import torch
from torch import Tensor

from murk.restore_ops.balance import FLAT_RANGE, STATS_PX


def _percentile(ordered: Tensor, n: Tensor, pct: float) -> Tensor:
    """The ``pct`` percentile of ``ordered`` (B, 3, n) ascending, linear between order statistics."""
    pos = (n - 1).to(torch.float64) * (float(pct) / 100.0)
    i0 = torch.minimum(torch.floor(pos).to(torch.int64), n - 1)
    i1 = torch.minimum(i0 + 1, n - 1)
    frac = pos - i0.to(torch.float64)
    v0 = ordered.index_select(2, i0.reshape(1)).to(torch.float64)
    v1 = ordered.index_select(2, i1.reshape(1)).to(torch.float64)
    return (v0 + frac * (v1 - v0)).to(torch.float32)  # (B, 3, 1)


def color_balance_graph(image: Tensor, low: float, high: float) -> Tensor:
    """Simplest colour balance of frames (B, 3, H, W) in [0, 1], traceable with dynamic sizes (module doc)."""
    shape = torch._shape_as_tensor(image)
    h, w = shape[2], shape[3]
    stride = torch.ceil(torch.sqrt((h * w).to(torch.float64) / STATS_PX)).to(torch.int64).clamp(min=1)
    rows = torch.arange(0, h, stride)  # type: ignore[call-overload]  # 0-dim tensors: traced as ONNX Range
    cols = torch.arange(0, w, stride)  # type: ignore[call-overload]
    sample = image[:, :, rows][:, :, :, cols].flatten(2)
    n = torch._shape_as_tensor(sample)[2]
    ordered = sample.sort(dim=2).values
    lo = _percentile(ordered, n, low)[..., None]
    hi = _percentile(ordered, n, 100.0 - high)[..., None]
    flat = (hi - lo) < FLAT_RANGE  # a flat channel is left as it is (murk.restore_ops.balance)
    scale = 1.0 / torch.where(flat, torch.ones_like(lo), hi - lo)
    return ((image - torch.where(flat, torch.zeros_like(lo), lo)) * scale).clamp(0.0, 1.0)
