"""Probe (issue 46, 2026-12-07, night; measured, not kept): a restorer averaged over mirrored copies of its input
(test-time augmentation; not the test-time adaptation of ``tta.py``).

``flip_average?base=lite,views=h``: the mean of ``base(x)`` and ``mirror(base(mirror(x)))`` (left-right);
``views=v`` the same up-down, ``views=hv`` all four mirrors; ``views=none`` is ``base`` itself; ``views=vonly`` is
the up-down pass alone, ``mirror(base(mirror(x)))``: the base on upside-down frames, to see how much it reads from
the layout (the far water at the top). Depth, where the base has it, is the first pass's, mirrored back.
``checkpoint=PATH`` loads other weights into a base whose network takes a checkpoint (``lite``; not the ``jointid``
preset or ``water``). Left-right is a symmetry of underwater scenes; up-down is not (the far water is often at the
top): docs/train.md, "How much of the synthetic gain is the frame's layout", measures how much the networks lean on
that.

Run: the two commands of docs/train.md, "Mirrored copies averaged", e.g.
     PYTHONPATH=src python benchmarks/bench_arms.py --probe benchmarks/probes/flip_average.py lite=lite
     "lh=flip_average?base=lite,views=h" "lv=flip_average?base=lite,views=v" --ref lite --real-pairs <pairs>
"""

from __future__ import annotations

import numpy as np

from murk.enhance.restorer import Restored, Restorer, create, register

_VIEWS = {"none": [()], "h": [(), (2,)], "v": [(), (1,)], "hv": [(), (2,), (1,), (1, 2)], "vonly": [(1,)]}
"""The axes of a batch (B, H, W, 3) each pass mirrors (``()``: the input as it is)."""


class FlipAverage(Restorer):
    name = "flip_average"

    def __init__(self, base: str, views: str, checkpoint: str = "") -> None:
        if views not in _VIEWS:
            raise ValueError(f"views: expected one of {', '.join(_VIEWS)}, got {views!r}")
        self.base = create(base, checkpoint=checkpoint) if checkpoint else create(base)
        self.flips = _VIEWS[views]

    def restore(self, images: np.ndarray) -> Restored:
        images = np.asarray(images, np.float32)
        first = self.base.restore(np.ascontiguousarray(np.flip(images, self.flips[0])))
        total = np.flip(first.images, self.flips[0]).astype(np.float64)
        for axes in self.flips[1:]:
            out = self.base.restore(np.ascontiguousarray(np.flip(images, axes))).images
            total += np.flip(out, axes)
        depth = None if first.depth_m is None else np.ascontiguousarray(np.flip(first.depth_m, self.flips[0]))
        return Restored((total / len(self.flips)).astype(np.float32), depth, first.facts)


@register("flip_average")
def make_flip_average(*, base: str = "lite", views: str = "h", checkpoint: str = "") -> FlipAverage:
    """``base`` (with ``checkpoint``, a checkpoint of it, when given) averaged over ``views`` mirrored copies of its
    input."""
    return FlipAverage(base, views, checkpoint)
