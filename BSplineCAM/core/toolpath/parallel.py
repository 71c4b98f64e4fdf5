# SPDX-License-Identifier: LGPL-2.1-or-later
"""Threads for independent pieces of work: one shared pool, its size chosen once per process.

The drop-cutter over faces answers its queries in chunks, each on its own
(:meth:`.faceset.FaceSet.centre_heights`).  The compiled kernels run without the GIL
(``nogil``, :mod:`..kernels`) and numpy releases it in its array loops, so chunks run on
several threads at once overlap on several cores.  Each piece writes only its own part of the
answer and keeps its own counters, so the answer is the same, bit for bit, on any number of
threads.

The number of threads is this process's setting (:mod:`..threads`, ``BSPLINECAM_THREADS``);
its names are re-exported here for the pool's callers.

:func:`run` runs ``work(0), ..., work(n - 1)`` on the pool and returns their results in order.
When a piece raises, the pieces not started are cancelled, the running ones are waited for
(none keeps running after the call returns) and the exception of the first failed piece is
raised.  A piece that itself calls :func:`run` (from a pool thread) runs its pieces on its own
thread, so the pool never waits on itself.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from concurrent.futures import FIRST_EXCEPTION, Future, ThreadPoolExecutor, wait
from typing import TypeVar

from ..threads import AUTO_CAP, ENV, Setting, cores, forced, notice, setting, threads

T = TypeVar("T")


class _State:
    """The shared pool (one per process; rebuilt after a fork or a new thread count)."""

    def __init__(self):
        self.lock = threading.RLock()
        self.pool: ThreadPoolExecutor | None = None
        self.pool_pid = 0
        self.pool_size = 0


_state = _State()
_local = threading.local()


def in_pool() -> bool:
    """Whether the calling thread is one of the pool's."""
    return bool(getattr(_local, "worker", False))


def _mark_worker() -> None:
    _local.worker = True


def _pool() -> ThreadPoolExecutor:
    size = threads()
    with _state.lock:
        if (_state.pool is None or _state.pool_pid != os.getpid()
                or _state.pool_size != size):
            if _state.pool is not None and _state.pool_pid == os.getpid():
                _state.pool.shutdown(wait=True)
            # after a fork the parent's pool has no threads here: a new one is made
            _state.pool = ThreadPoolExecutor(size, thread_name_prefix="bsplinecam",
                                             initializer=_mark_worker)
            _state.pool_pid = os.getpid()
            _state.pool_size = size
        return _state.pool


def run(work: Callable[[int], T], count: int, first_here: bool = False,
        alone: bool = False) -> list[T]:
    """``[work(0), ..., work(count - 1)]``, the pieces on the shared pool when it has more
    than one thread and there is more than one piece (else, or if ``alone``, in order on the
    caller's thread).

    ``first_here`` runs ``work(0)`` on the caller's thread before the others start (what it
    does once, such as compiling a kernel, then happens on one thread).  An exception of a
    piece cancels the pieces not started and is raised once the running ones have ended (the
    first failed piece's, in the order of the pieces)."""
    if count <= 0:
        return []
    if alone or threads() <= 1 or count == 1 or in_pool():
        return [work(k) for k in range(count)]
    results: list = [None] * count
    start = 0
    if first_here:
        results[0] = work(0)
        start = 1
    pool = _pool()
    futures: list[Future] = []
    try:
        futures = [pool.submit(work, k) for k in range(start, count)]
        wait(futures, return_when=FIRST_EXCEPTION)
    finally:
        # a failed piece, or the caller's thread interrupted: stop what has not started and
        # let the running pieces end, so that nothing of this call runs after it returns
        for f in futures:
            f.cancel()
        wait(futures)
    for f in futures:
        if not f.cancelled() and f.exception() is not None:
            raise f.exception()
    for k, f in enumerate(futures, start):
        results[k] = f.result()
    return results


__all__ = ["AUTO_CAP", "ENV", "Setting", "cores", "forced", "in_pool", "notice", "run",
           "setting", "threads"]
