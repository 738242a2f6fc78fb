"""Worker processes that die with their parent (``murk synth --workers N``, ``murk scenes --workers N``).

A pool worker outlives a parent killed with SIGKILL (or by the OOM killer): nothing tells it, so it finishes
the item it holds, then the items already queued to it, writing files for seconds into a folder whose run is
over. Two mechanisms, both started from the pool initializer:

- Linux: ``prctl(PR_SET_PDEATHSIG, SIGKILL)``. The kernel kills the worker the moment its parent dies, in the
  middle of an item; that is safe because every output is written atomically (a killed worker leaves only a
  ``.murk-tmp-`` file, which the next run deletes) and only the parent appends to the resume logs. It needs no
  polling and cannot be blocked by a long item. The death signal is tied to the thread that created the worker:
  pools must be created and submitted to from the main thread (as murk does).
- Everywhere (and for the race where the parent dies before ``prctl`` ran): :func:`stop_if_orphaned`, a check
  that workers make between units of work (one variant in ``murk synth``, one scene in ``murk scenes``), so on
  macOS and Windows a worker stops within one unit. It polls multiprocessing's parent sentinel (a pipe or
  handle that the parent's death closes), which works for fork and spawn and on Windows, where ``os.getppid()``
  keeps the dead parent's pid.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from typing import Any

PR_SET_PDEATHSIG = 1
"""From <linux/prctl.h>."""


def die_with_parent() -> None:
    """Call first thing in a pool worker: arrange to be killed when the pool's owner dies.

    Exits at once when the parent is already gone (it died before this worker got here). Does nothing in a
    process that multiprocessing did not start (the single-process path of a command calls the same
    initializer: the main process must not die with the shell that started it).
    """
    if multiprocessing.parent_process() is None:
        return
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl+C is the parent's to handle (see worker_pool)
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):  # no libc prctl (unusual builds): the parent check still works
            pass
    stop_if_orphaned()


def parent_alive() -> bool:
    """False in a child process whose parent has died; True in the main process."""
    parent = multiprocessing.parent_process()
    return parent is None or parent.is_alive()


def stop_if_orphaned() -> None:
    """Exit the worker process at once when its parent has died (the portable check between units of work)."""
    if not parent_alive():
        os._exit(1)


def _pdeathsig_term() -> None:  # runs in the child between fork and exec
    import ctypes

    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
    except (OSError, AttributeError):
        pass


def subprocess_dies_with_parent() -> Callable[[], None] | None:
    """``preexec_fn`` for :class:`subprocess.Popen`: on Linux the child gets SIGTERM when this process dies
    (however it dies, SIGKILL included); None elsewhere (there the owner's ``finally`` is the only guard)."""
    return _pdeathsig_term if sys.platform.startswith("linux") else None


class TerminateAsExit:
    """Context manager: while active in the main thread, SIGTERM raises SystemExit(143) like Ctrl+C raises
    KeyboardInterrupt, so ``finally`` blocks (stopping child processes) run; the old handler is restored."""

    def __enter__(self) -> TerminateAsExit:
        import threading

        self._old = None
        if threading.current_thread() is threading.main_thread():
            self._old = signal.signal(signal.SIGTERM, _raise_exit)
        return self

    def __exit__(self, *exc: object) -> None:
        if self._old is not None:
            signal.signal(signal.SIGTERM, self._old)


def _raise_exit(signum: int, frame: object) -> None:
    raise SystemExit(128 + signum)


@contextlib.contextmanager
def sigint_ignored() -> Iterator[None]:
    """Ignore Ctrl+C (SIGINT) in the main thread for the block, then restore the handler; elsewhere a no-op.

    Processes started inside the block inherit the ignored signal (through fork and through exec), so a pool's
    workers never see the terminal's Ctrl+C, which the shell sends to the whole process group: the parent alone
    handles it, and no worker prints a ``KeyboardInterrupt`` traceback while it starts up.
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


@contextlib.contextmanager
def worker_pool(
    workers: int,
    *,
    initializer: Callable[..., None],
    initargs: tuple[Any, ...] = (),
    mp_context: Any = None,
) -> Iterator[ProcessPoolExecutor]:
    """A :class:`~concurrent.futures.ProcessPoolExecutor` of ``workers`` processes that leave Ctrl+C to the
    parent, for the main thread of a batch command.

    - The workers are started at once with SIGINT ignored (:func:`sigint_ignored`).
    - Leaving the block normally waits for the submitted work.
    - Leaving it with an exception (Ctrl+C, SIGTERM as SystemExit, a full disk) cancels what is queued and
      terminates the workers without waiting for their current item. Every output is written atomically, so a
      terminated worker leaves at most a temporary file, which the next run deletes. A second Ctrl+C during
      that cleanup is ignored: it cannot interrupt the shutdown half-way and leave the process waiting for
      workers that were never told to stop.
    """
    from concurrent.futures import ProcessPoolExecutor

    pool = ProcessPoolExecutor(workers, mp_context=mp_context, initializer=initializer, initargs=initargs)
    try:
        with sigint_ignored():  # a submit starts a worker while fewer than `workers` run: start them all now
            for _ in range(workers):
                pool.submit(_idle)
        yield pool
    except BaseException:
        with sigint_ignored():
            _stop_now(pool)
        raise
    pool.shutdown(wait=True)


def _idle() -> None:
    """The no-op item that makes the pool start its workers."""


def _stop_now(pool: ProcessPoolExecutor) -> None:
    processes = list((getattr(pool, "_processes", None) or {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    for p in processes:
        p.join(timeout=5)
        if p.is_alive():  # still starting up or stuck in I/O under load: SIGTERM was not enough
            p.kill()
            p.join(timeout=5)
