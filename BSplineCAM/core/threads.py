# SPDX-License-Identifier: LGPL-2.1-or-later
"""How many threads this process runs: ``BSPLINECAM_THREADS``, read once.

Every part of core that splits work over threads asks here: the drop-cutter over faces' pool
(:mod:`.toolpath.parallel`), and the numpy work split into independent parts (the net
drop-cutter, the Z-map simulation, the faces' height grid, the distance transform, the
evaluator's grid products), which :func:`numpy_threads` caps lower.

* ``BSPLINECAM_THREADS=N`` (an integer >= 1) runs N threads; 1 runs everything on the
  caller's thread;
* ``BSPLINECAM_THREADS=auto`` (the default) runs one thread per core this process may use,
  at most :data:`AUTO_CAP`.

Any other value never stops a job: the default runs and one notice line on standard error
names the variable and the value (:func:`notice`).
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Iterator
from dataclasses import dataclass

ENV = "BSPLINECAM_THREADS"
#: Most threads ``auto`` runs: a chunk's Python glue between its array operations holds the
#: GIL (about a fifth of its time in docs/benchmarks.md), so threads beyond this add little;
#: a larger N can still be asked for.
AUTO_CAP = 8
#: Most threads for numpy work split into parts (numpy releases the GIL inside its loops, but
#: the parts' memory traffic stops paying beyond this).
NUMPY_CAP = 4


@dataclass(frozen=True)
class Setting:
    """The threads this process runs and how they were chosen."""

    threads: int
    #: the value read ("auto" or a count) or, for a value not understood, why the default runs
    source: str
    #: whether BSPLINECAM_THREADS held a value not understood
    bad: bool = False


_lock = threading.RLock()
_setting: Setting | None = None


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
    global _setting
    if _setting is None:
        with _lock:
            if _setting is None:
                chosen = _choose()
                _setting = chosen
                if chosen.bad:
                    print(notice(), file=sys.stderr)
    return _setting


def threads() -> int:
    """The number of threads work may be split over (1: the caller's thread alone)."""
    return setting().threads


def numpy_threads() -> int:
    """Threads for numpy work split into independent parts: :func:`threads`, at most
    :data:`NUMPY_CAP`."""
    return min(NUMPY_CAP, threads())


def notice() -> str:
    """The one-line notice when ``BSPLINECAM_THREADS`` holds a value not understood ("" else)."""
    s = setting()
    if not s.bad:
        return ""
    return (f"BSplineCAM: {s.source}; {s.threads} thread{'s' if s.threads > 1 else ''} "
            f"run (auto)")


@contextlib.contextmanager
def forced(value: int | str) -> Iterator[Setting]:
    """Run a block with ``BSPLINECAM_THREADS=value`` read afresh (tests and benchmarks compare
    thread counts in one process), then restore the setting chosen before."""
    global _setting
    with _lock:
        before_env = os.environ.get(ENV)
        before = _setting
        os.environ[ENV] = str(value)
        _setting = None
    try:
        yield setting()
    finally:
        with _lock:
            if before_env is None:
                os.environ.pop(ENV, None)
            else:
                os.environ[ENV] = before_env
            _setting = before


__all__ = ["AUTO_CAP", "ENV", "NUMPY_CAP", "Setting", "cores", "forced", "notice",
           "numpy_threads", "setting", "threads"]
