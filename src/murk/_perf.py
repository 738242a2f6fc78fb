"""Process-level performance settings.

numpy and OpenCV allocate a few large temporaries per image. glibc serves allocations above its mmap threshold
(128 KiB at first) with fresh ``mmap`` pages and returns them on ``free``, so every call pays page faults to
zero the same memory again: measured here, marine-snow compositing of one 640x480 image took 10.6 ms with the
default and 4.5 ms with the thresholds below. :func:`tune_allocator` raises the mmap and trim thresholds to
32 MiB (glibc's maximum mmap threshold on 64-bit), so freed buffers are reused, and the top pad (what the heap
grows by and keeps when it shrinks) to 64 MiB: without it a ``murk synth`` process still took 100,000 page
faults for 64 variants with marine snow at 640x480, with it 28,000, and the whole command 1.02 s against 1.16 s
(best of 4, 2026-12-03). It is a no-op on non-glibc platforms. The cost: freed memory kept for reuse, up to about
100 MiB in the main heap and up to the 64 MiB pad in each further arena glibc gives a busy thread (murk's writer
threads may have their own).

:func:`prefer_passive_openmp` lets torch's idle OpenMP threads sleep instead of spinning (``OMP_WAIT_POLICY=PASSIVE``).
By default GNU OpenMP keeps a thread that waits at the end of a parallel region spinning for about 3 ms, which is
harmless on idle cores but ruinous when other processes share them: every one of the thousands of small parallel
regions of a Joint-ID forward pass then waits for a thread the kernel has descheduled. Measured with the shipped
``jointid`` on 20 real photos of mixed sizes (long side <= 256 px), 2 threads, on the 2-core development box with
three other users (load average 4-5, 2026-12-03): 260-2,550 ms per image with the default against 50-92 ms with
the passive policy, and 45-87 ms with one thread (``benchmarks/bench_mixed_sizes.py`` measures it through
``murk enhance``). On idle cores it costs 1.27x for such small images (39 against 31 ms) and about 5 % at 640x480;
a short spin (``GOMP_SPINCOUNT=2000``) keeps the idle speed but is twice as slow as passive next to another torch
job (BENCHMARKS.md). Every ``murk`` command applies it before torch is imported, unless the user chose a policy.
"""

from __future__ import annotations

import ctypes
import os
import sys
from collections.abc import MutableMapping

_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3
_THRESHOLD = 32 * 1024 * 1024
_TOP_PAD = 64 * 1024 * 1024
_done = False


def tune_allocator() -> bool:
    """Raise glibc's mmap and trim thresholds and its top pad once per process (module doc); returns True when
    applied."""
    global _done
    if _done:
        return True
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None)  # the process's own symbols, libc's among them (no ldconfig run: ~10 ms)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    ok = mallopt(_M_MMAP_THRESHOLD, _THRESHOLD) == 1 and mallopt(_M_TRIM_THRESHOLD, _THRESHOLD) == 1
    ok = ok and mallopt(_M_TOP_PAD, _TOP_PAD) == 1
    _done = ok
    return ok


OPENMP_WAIT_VARIABLES = ("OMP_WAIT_POLICY", "GOMP_SPINCOUNT", "KMP_BLOCKTIME")
"""Environment variables through which a user chooses how idle OpenMP threads wait (GNU and Intel OpenMP)."""


def prefer_passive_openmp(environ: MutableMapping[str, str] | None = None) -> bool:
    """Set ``OMP_WAIT_POLICY=PASSIVE`` in ``environ`` (default: this process's environment, so child processes
    inherit it) unless the user set one of :data:`OPENMP_WAIT_VARIABLES`, or torch is already imported (the OpenMP
    runtime reads its environment once, when torch loads it: setting it later would change only the children).
    Returns True when set."""
    env = os.environ if environ is None else environ
    if any(k in env for k in OPENMP_WAIT_VARIABLES) or "torch" in sys.modules:
        return False
    env["OMP_WAIT_POLICY"] = "PASSIVE"
    return True
