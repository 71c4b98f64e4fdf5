# SPDX-License-Identifier: LGPL-2.1-or-later
"""Threads for independent pieces of work: one shared pool, its size chosen once per process.

The drop-cutter over faces answers its queries in chunks, each on its own
(:meth:`.faceset.FaceSet.centre_heights`).  The compiled kernels run without the GIL
(``nogil``, :mod:`..kernels`) and numpy releases it in its array loops, so chunks run on
several threads at once overlap on several cores.  Each piece writes only its own part of the
answer and keeps its own counters, so the answer is the same, bit for bit, on any number of
threads.

The number of threads is read once, at the first :func:`threads`:

* ``BSPLINECAM_THREADS=N`` (an integer >= 1) runs N threads; 1 runs everything on the
  caller's thread;
* ``BSPLINECAM_THREADS=auto`` (the default) runs one thread per core this process may use,
  at most :data:`AUTO_CAP`.

Any other value never stops a job: the default runs and one notice line on standard error
names the variable and the value (:func:`notice`).

:func:`run` runs ``work(0), ..., work(n - 1)`` on the pool and returns their results in order.
When a piece raises, the pieces not started are cancelled, the running ones are waited for
(none keeps running after the call returns) and the exception of the first failed piece is
raised.  A piece that itself calls :func:`run` (from a pool thread) runs its pieces on its own
thread, so the pool never waits on itself.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_EXCEPTION, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import TypeVar

ENV = "BSPLINECAM_THREADS"
#: Most threads ``auto`` runs: a chunk's Python glue between its array operations holds the
#: GIL (about a fifth of its time in docs/benchmarks.md), so threads beyond this add little;
#: a larger N can still be asked for.
AUTO_CAP = 8

T = TypeVar("T")


@dataclass(frozen=True)
class Setting:
    """The threads this process runs and how they were chosen."""

    threads: int
    #: the value read ("auto" or a count) or, for a value not understood, why the default runs
    source: str
    #: whether BSPLINECAM_THREADS held a value not understood
    bad: bool = False


class _State:
    """The chosen setting and the shared pool (one per process; rebuilt after a fork)."""

    def __init__(self):
        self.lock = threading.RLock()
        self.setting: Setting | None = None
        self.pool: ThreadPoolExecutor | None = None
        self.pool_pid = 0
        self.pool_size = 0


_state = _State()
_local = threading.local()


def cores() -> int:
    """The cores this process may run on (its CPU affinity where the system tells it)."""
    count = getattr(os, "process_cpu_count", None)  # Python 3.13+
    if count is not None:
        return max(1, count() or 1)
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


def _choose() -> Setting:
    raw = os.environ.get(ENV)
    text = (raw or "").strip().lower() or "auto"
    auto = max(1, min(AUTO_CAP, cores()))
    if text == "auto":
        return Setting(auto, "auto")
    if text.isdigit() and int(text) >= 1:
        return Setting(int(text), text)
    return Setting(auto, f"{ENV}={raw!r} is not an integer >= 1 or 'auto'", bad=True)


def setting() -> Setting:
    """The setting of this process, read from ``BSPLINECAM_THREADS`` at the first call (a
    value not understood is said once on standard error)."""
    if _state.setting is None:
        with _state.lock:
            if _state.setting is None:
                chosen = _choose()
                _state.setting = chosen
                if chosen.bad:
                    print(notice(), file=sys.stderr)
    return _state.setting


def threads() -> int:
    """The number of threads :func:`run` uses (1: the caller's thread alone)."""
    return setting().threads


def notice() -> str:
    """The one-line notice when ``BSPLINECAM_THREADS`` holds a value not understood ("" else)."""
    s = setting()
    if not s.bad:
        return ""
    return (f"BSplineCAM: {s.source}; {s.threads} thread{'s' if s.threads > 1 else ''} "
            f"run (auto)")


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


@contextlib.contextmanager
def forced(value: int | str) -> Iterator[Setting]:
    """Run a block with ``BSPLINECAM_THREADS=value`` read afresh (tests and benchmarks compare
    thread counts in one process), then restore the setting chosen before."""
    with _state.lock:
        before_env = os.environ.get(ENV)
        before = _state.setting
        os.environ[ENV] = str(value)
        _state.setting = None
    try:
        yield setting()
    finally:
        with _state.lock:
            if before_env is None:
                os.environ.pop(ENV, None)
            else:
                os.environ[ENV] = before_env
            _state.setting = before


__all__ = ["AUTO_CAP", "ENV", "Setting", "cores", "forced", "in_pool", "notice", "run",
           "setting", "threads"]
