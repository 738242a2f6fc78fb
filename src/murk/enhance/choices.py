"""The option strings of restoration and ``murk enhance`` as ``Literal`` types, and the defaults the methods'
factories declare, in one light module.

The library annotates with them and the CLI uses them directly as its choices (typer turns a ``Literal``
annotation into a choice list), so the two never drift apart; importing this module pulls in neither torch nor
OpenCV, so ``murk --help`` stays fast, and the registry's declarations (:mod:`murk.enhance.methods`) can name
them without importing the networks.
"""

from __future__ import annotations

from typing import Literal, get_args

HEMode = Literal["y", "rgb", "clahe"]
"""Histogram equalisation of the ``post`` method: luma only, each channel, or CLAHE on luma."""
Precision = Literal["fp32", "bf16", "fp16"]
"""Arithmetic of the network restorers: fp32, or bf16/fp16 autocast."""
PostPreset = Literal["real", "paper"]
"""Named settings of the ``post`` method: see :data:`murk.enhance.post.POST_PRESETS`."""
Policy = Literal["native", "official"]
"""Input policy of the comparison baselines (:mod:`murk.enhance.baseline`)."""
ImageFormat = Literal["png", "jpg"]
"""Image format of ``murk enhance`` outputs."""
VideoBackendChoice = Literal["auto", "opencv", "av"]
"""Video writer of ``murk enhance``: auto picks av for live streams when installed."""
BagStorage = Literal["mcap", "sqlite3"]
"""Storage of a ROS 2 bag written by ``murk enhance`` (default: the input's)."""
Exposure = Literal["input", "network"]
"""The exposure a network restoration keeps (``lite`` and ``jointid``'s ``exposure``): the mean luma of the
network's (balanced) input, or the network's own (:mod:`murk.restore_ops.exposure`)."""

HE_MODES: tuple[str, ...] = get_args(HEMode)
POLICIES: tuple[str, ...] = get_args(Policy)

DEFAULT_OVERLAP = 64
"""Tile overlap in pixels of the network restorers (``jointid``, ``udaformer``, ``ursct``) unless set."""
DEFAULT_REFINE = 0.125
"""Default ``refine`` of ``jointid``: the affine transfer's window radius as a fraction of the long side."""
DEFAULT_LITE_BLEND = 0.5
"""Default ``lite_blend`` of ``jointid``: the weight of the shipped ``lite``'s restoration in the output (the rest
is Joint-ID's own; docs/enhance.md, "jointid?lite_blend")."""
DEFAULT_DEPTH_AREA_PX = 76800
"""Default ``depth_area`` of ``jointid``: a frame of more than twice this many pixels (320x240) gets its depth from a
second pass of the network at about this area, upsampled (docs/enhance.md, "jointid?depth_area")."""
DEFAULT_REFINE_GUARD = 0.04
"""Default ``refine_guard`` of ``jointid`` and ``lite``: the top-hat luma from which the input counts as a particle
(about 10 of 255)."""
