"""Temporal smoothing of per-frame estimates over the frames of one video (``--temporal S``).

A method that estimates something global or smooth from each frame (``post``: the equalisation tables; ``lite``:
its low-resolution coefficient maps) makes a steady scene flicker when the estimate moves a little from frame to
frame. :class:`FrameEMA` replaces the estimate of frame ``t`` by the exponential average

    ``E_t = S E_(t-1) + (1 - S) e_t``, ``E_0 = e_0``,

so it follows real changes with a time constant of about ``1 / (1 - S)`` frames (S = 0.8: 5 frames, 0.17 s at
30 frames/s) instead of jumping. Frames are only ever mixed with earlier frames of the same video: the restorer
applies it inside :meth:`murk.enhance.restorer.Restorer.sequence` and starts afresh there.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    import torch


class FrameEMA:
    """The exponential average of an estimate over consecutive frames; numpy and torch twins with the same
    float32 arithmetic (pinned equal by tests).

    Call it with one frame's estimate as a numpy array, or with the estimates of B consecutive frames as a torch
    tensor (B, ...), oldest first; it returns the averaged estimates in the same form. A shape that differs from
    the previous frame's (another resolution) starts afresh.

    Raises:
        ValueError: ``weight`` outside [0, 1).
    """

    def __init__(self, weight: float) -> None:
        if isinstance(weight, bool) or not 0.0 <= float(weight) < 1.0:
            raise ValueError(f"temporal: expected a weight in [0, 1) (0 = off), got {weight!r}")
        self.weight = float(weight)
        self._keep = np.float32(self.weight)
        self._take = np.float32(1.0) - self._keep
        self._last: np.ndarray | torch.Tensor | None = None

    def reset(self) -> None:
        """Forget the previous frames (the next frame is the first of a video)."""
        self._last = None

    def __call__(self, estimate: Any) -> Any:
        import torch

        if isinstance(estimate, torch.Tensor):
            return self._torch(estimate)
        cur = np.asarray(estimate, np.float32)
        prev = self._previous(cur.shape)
        last = cur.copy() if prev is None else self._keep * _numpy(prev) + self._take * cur
        self._last = last
        return last

    def _torch(self, batch: torch.Tensor) -> torch.Tensor:
        import torch

        out = torch.empty_like(batch, dtype=torch.float32)
        prev = self._previous(tuple(batch.shape[1:]))
        last = None if prev is None else torch.as_tensor(prev, device=batch.device)
        for i in range(batch.shape[0]):
            cur = batch[i].float()
            last = cur if last is None else float(self._keep) * last + float(self._take) * cur
            out[i] = last
        self._last = last
        return out

    def _previous(self, shape: tuple[int, ...]) -> np.ndarray | torch.Tensor | None:
        last = self._last
        return last if last is not None and tuple(last.shape) == tuple(shape) else None


def _numpy(a: np.ndarray | torch.Tensor) -> np.ndarray:
    import torch

    return a.cpu().numpy() if isinstance(a, torch.Tensor) else a
