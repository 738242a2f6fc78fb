"""Relighting a particle bank: its particles as a lamp or the sun lights them, fixed in the bank.

Particles cut from dark footage (the ROV frames of ``builtin:snow-real``: mean luma 27 of 255) keep their shapes,
sizes and luma patterns but are too dim for Eq. (7), which composites each particle with its own colour: on a
bright scene they draw dark blots. Real marine snow is bright (luma median 162 on the development snow pairs,
docs/snow.md). :func:`relight_bank` rescales each particle once, as ``marine_snow.particle_luma`` does at every
draw: its pixels become neutral grey with their own luma pattern, scaled so that the particle's mean luma is
``U[a, b]`` (one draw per particle, seeded), clipped at 255. Eq. (7) then composites the bank as the paper
writes it. The default bank of ``murk synth`` (``builtin:snow``) is ``builtin:snow-real`` relit to 120-230.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from murk._checks import check_interval
from murk.snow.bank import BANK_FORMAT, BANK_VERSION, ParticleBank, content_id, load_bank, save_bank
from murk.snow.composite import particle_lumas, relit_grey


def relight_bank(bank: ParticleBank, luma: tuple[float, float], *, seed: int = 0) -> ParticleBank:
    """``bank`` with each particle relit to a mean luma ``U[luma[0], luma[1]]`` (0-255; module docstring).

    The result is a new bank (its own ``bank_id``) whose ``meta.relight`` records the range, the seed and the id
    of the bank it came from; sources and extraction settings are kept.

    Raises:
        ValueError: ``luma`` is not an interval within [1, 255], or the bank is empty.
    """
    check_interval("luma", luma, 1.0, 255.0)
    if len(bank) == 0:
        raise ValueError("bank: expected at least one particle, got an empty bank")
    target = np.random.default_rng(seed).uniform(float(luma[0]), float(luma[1]), size=len(bank))
    gain = target / np.maximum(particle_lumas(bank), 1.0)
    owner = np.repeat(np.arange(len(bank)), bank.areas_px)
    rgb = np.rint(relit_grey(bank.pixel_rgb, gain[owner])).astype(np.uint8)
    meta: dict[str, Any] = {
        **bank.meta,
        "format": BANK_FORMAT,
        "version": BANK_VERSION,
        "bank_id": content_id([bank.offsets, bank.pixel_yx, rgb]),
        "relight": {"luma": [float(luma[0]), float(luma[1])], "seed": int(seed), "from_bank_id": bank.bank_id},
    }
    return ParticleBank(
        offsets=bank.offsets,
        pixel_yx=bank.pixel_yx,
        pixel_rgb=rgb,
        source_index=bank.source_index,
        source_xy=bank.source_xy,
        bbox_hw=bank.bbox_hw,
        meta=meta,
    )


def relight_bank_file(bank: str | Path, out: str | Path, luma: tuple[float, float], *, seed: int = 0) -> ParticleBank:
    """``murk snow relight``: load ``bank`` (a path or ``builtin:...``), relight it (:func:`relight_bank`) and write
    the result atomically to ``out``; returns the new bank.

    Raises:
        InputFileError: ``bank`` cannot be read or is not a valid bank, or ``out`` cannot be written (the message
            names the file).
        ValueError: a bad ``luma`` range; ``out`` is ``bank``.
    """
    from murk.io.paths import check_output_file

    if not str(bank).startswith("builtin:"):
        check_output_file(out, [bank])  # the bank as cut: relighting cannot be undone
    relit = relight_bank(load_bank(bank), luma, seed=seed)
    save_bank(relit, out)
    return relit
