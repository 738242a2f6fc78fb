"""Random-number handling: one normalisation point and order-independent per-sample seeds.

Per-sample seeds come from a hash of (global seed, sample keys), so a result never depends on worker count,
shard layout or processing order (DESIGN.md rule 3).
"""

from __future__ import annotations

import hashlib

import numpy as np

RngLike = np.random.Generator | int | None


def as_generator(rng: RngLike) -> np.random.Generator:
    """Normalise ``rng`` (a Generator, an int seed, or None for fresh entropy) to a numpy Generator."""
    if isinstance(rng, np.random.Generator):
        return rng
    if rng is None or (isinstance(rng, (int, np.integer)) and not isinstance(rng, bool)):
        return np.random.default_rng(rng)
    raise TypeError(f"rng: expected numpy.random.Generator, int or None, got {type(rng).__name__}")


def derive_seed(seed: int, *keys: str | int) -> int:
    """A 63-bit seed derived from ``seed`` and ``keys`` (stable across processes, platforms and versions).

    Example: ``derive_seed(0, "img_001", 3)`` is the seed of variant 3 of image ``img_001`` in a run with
    global seed 0.
    """
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise TypeError(f"seed: expected an int, got {type(seed).__name__}")
    text = "\x1f".join([str(int(seed)), *(str(k) for k in keys)])
    digest = hashlib.blake2b(text.encode("utf-8"), digest_size=8).digest()
    return int.from_bytes(digest, "little") >> 1
