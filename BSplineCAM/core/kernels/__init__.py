# SPDX-License-Identifier: LGPL-2.1-or-later
"""Compiled kernels: one algorithm, two engines.

The hot loops of the core (the drop-cutter's de Casteljau splits and bounds, the NURBS
evaluator's Bernstein rows, the Z-map's stamping) are written twice: as vectorised numpy (the
*numpy engine*, always there) and as small numba ``@njit`` functions over plain arrays (the
*numba engine*).  Both compute the same arithmetic in the same order; the tests run shared
cases through both and require the same answers.

The engine is chosen once, at the first kernel a process asks for:

* ``BSPLINECAM_KERNELS=numpy`` (or ``off``) takes the numpy engine;
* ``BSPLINECAM_KERNELS=numba`` asks for numba, and ``auto`` (the default) takes it when it
  imports.

A numba that is missing or fails to import or to compile (a numpy it was not built for, a
cache folder it cannot write) never stops a job: the numpy engine runs and one notice line on
standard error says why and that it runs slower (:func:`notice`).

Compiled code is cached in the user's cache folder (``$BSPLINECAM_CACHE``, else
``$XDG_CACHE_HOME/bsplinecam/numba``, else ``~/.cache/bsplinecam/numba``), never in the
add-on's folder, which may be read-only; where no cache folder can be written the kernels are
compiled in memory at every start.

A kernel module declares its compiled twin with :class:`Kernel` at import (nothing compiles
then) and dispatches with :func:`use_numba`::

    _split = kernels.Kernel(_split_loops)
    ...
    if kernels.use_numba():
        try:
            return _split(work, ...)            # the first call compiles
        except kernels.KernelUnavailable:
            pass                                # numba failed: the numpy engine from now on
    ...numpy code...
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

ENV = "BSPLINECAM_KERNELS"
CACHE_ENV = "BSPLINECAM_CACHE"
CHOICES = ("auto", "numba", "numpy", "off")


@dataclass
class Engine:
    """The engine this process runs (see the module docstring)."""

    #: "numba" or "numpy"
    name: str = "numpy"
    #: why the numpy engine runs ("" under numba)
    reason: str = ""
    #: numba's version, if it imported
    numba_version: str = ""
    #: the compile cache folder ("" when compiling in memory)
    cache: str = ""
    #: seconds spent compiling, per kernel name (first calls of this process)
    compile_seconds: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"engine": self.name, "reason": self.reason, "numba": self.numba_version,
                "cache": self.cache,
                "compile_seconds": {k: round(v, 3) for k, v in self.compile_seconds.items()}}


_engine: Engine | None = None
_numba = None
_lock = threading.RLock()
_noticed = False


def _numba_version() -> str:
    """numba's version from its package metadata (without importing it), or "unknown"."""
    try:
        from importlib import metadata  # noqa: PLC0415

        return metadata.version("numba")
    except Exception:  # noqa: BLE001
        return "unknown"


def _cache_folder() -> str:
    """A writable cache folder for numba's compiled kernels, or "" if none can be written."""
    candidates = []
    if os.environ.get(CACHE_ENV):
        candidates.append(Path(os.environ[CACHE_ENV]))
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg:
        candidates.append(Path(xdg) / "bsplinecam" / "numba")
    candidates.append(Path.home() / ".cache" / "bsplinecam" / "numba")
    candidates.append(Path(tempfile.gettempdir()) / f"bsplinecam-numba-{os.getuid()}"
                      if hasattr(os, "getuid") else Path(tempfile.gettempdir()) / "bsplinecam")
    # one sub-folder per Python and numba: two numbas of one Python (Debian's and the venv's)
    # would overwrite each other's index files and recompile at every switch
    tag = f"py{sys.version_info[0]}{sys.version_info[1]}-numba{_numba_version()}"
    for base in candidates:
        folder = base / tag
        try:
            folder.mkdir(parents=True, exist_ok=True)
            probe = folder / f".probe-{os.getpid()}"
            probe.write_text("")
            probe.unlink()
            return str(folder)
        except OSError:
            continue
    return ""


def _choose() -> Engine:
    global _numba
    choice = os.environ.get(ENV, "auto").strip().lower() or "auto"
    if choice not in CHOICES:
        return Engine("numpy", f"{ENV}={os.environ.get(ENV)!r} is not one of "
                      f"{', '.join(CHOICES)}")
    if choice in ("numpy", "off"):
        return Engine("numpy", f"{ENV}={choice}")
    cache = os.environ.get("NUMBA_CACHE_DIR") or _cache_folder()
    if cache and not os.environ.get("NUMBA_CACHE_DIR"):
        # numba reads it when it first imports
        os.environ["NUMBA_CACHE_DIR"] = cache
    try:
        import numba  # noqa: PLC0415
    except Exception as exc:  # noqa: BLE001  (any import failure: missing, wrong numpy, ...)
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        return Engine("numpy", f"numba does not import ({text})")
    _numba = numba
    return Engine("numba", "", numba.__version__, cache)


def engine() -> Engine:
    """The engine of this process, chosen at the first call."""
    global _engine
    if _engine is None:
        with _lock:
            if _engine is None:
                _engine = _choose()
    return _engine


def use_numba() -> bool:
    """Whether the compiled kernels run (else the numpy engine, and its notice is printed
    once)."""
    if engine().name == "numba":
        return True
    _say_once()
    return False


def notice() -> str:
    """The one-line notice when the numpy engine runs ("" under numba)."""
    e = engine()
    if e.name == "numba":
        return ""
    return (f"BSplineCAM: compiled kernels off ({e.reason}); the numpy engine runs, "
            "the same answers, slower")


def _say_once() -> None:
    global _noticed
    if not _noticed:
        _noticed = True
        text = notice()
        if text:
            print(text, file=sys.stderr)


def fall_back(reason: str) -> None:
    """Switch this process to the numpy engine (a kernel failed to compile), with a notice."""
    global _engine, _noticed
    with _lock:
        e = engine()
        _engine = Engine("numpy", reason, e.numba_version, e.cache, e.compile_seconds)
        if e.name == "numba":
            _noticed = False  # the switch is news: say it
    _say_once()


class Kernel:
    """The compiled twin of a loop-style ``function`` (``@njit(nogil, cache)``), made at its
    first call under the numba engine.  Calling it runs the compiled code; its first call
    compiles (timed into the engine's ``compile_seconds``).  A kernel that fails to compile
    switches the process to the numpy engine and raises :class:`KernelUnavailable`, for the
    caller to take its numpy path.  ``py`` is the plain Python function (tests)."""

    def __init__(self, function, parallel: bool = False):
        self.py = function
        self.name = function.__name__
        self.parallel = parallel
        self._compiled = None

    def _get(self):
        if self._compiled is None:
            with _lock:
                if self._compiled is None:
                    e = engine()
                    options = {"nogil": True, "cache": bool(e.cache),
                               "parallel": self.parallel, "error_model": "numpy"}
                    _compile_helpers(self.py, options)
                    try:
                        self._compiled = _numba.njit(**options)(self.py)
                    except Exception:  # noqa: BLE001  (no cache for it: compile in memory)
                        options["cache"] = False
                        try:
                            self._compiled = _numba.njit(**options)(self.py)
                        except Exception as exc:  # noqa: BLE001
                            fall_back(f"numba could not wrap {self.name}: {exc}")
                            raise KernelUnavailable(self.name) from exc
        return self._compiled

    def __call__(self, *args):
        if not use_numba():
            raise KernelUnavailable(self.name)
        e = engine()
        if self.name in e.compile_seconds:
            return self._get()(*args)
        _tell_first_use(self.name)
        compiled = self._get()
        start = time.perf_counter()
        try:
            out = compiled(*args)
        except Exception as exc:  # noqa: BLE001
            if _is_compile_error(exc):
                first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
                fall_back(f"numba could not compile {self.name}: {first}")
                raise KernelUnavailable(self.name) from exc
            raise
        e.compile_seconds[self.name] = time.perf_counter() - start
        return out


#: Called with a kernel's name before its first call in the process, which loads it from the
#: cache or compiles it (seconds on a first start): the GUI says so on its progress bar.
_first_use_listener = None


def on_first_use(listener) -> None:
    """Call ``listener(kernel name)`` before each kernel's first call in this process (None:
    nobody).  A listener that fails is dropped; the kernel runs anyway."""
    global _first_use_listener
    _first_use_listener = listener


def _tell_first_use(name: str) -> None:
    global _first_use_listener
    listener = _first_use_listener
    if listener is None:
        return
    try:
        listener(name)
    except Exception:  # noqa: BLE001  (a display hook never stops a computation)
        _first_use_listener = None


_HELPER = "_bsplinecam_kernel_helper"


def helper(function):
    """Mark a loop-style function that kernels call (a clip, a point-in-polygon test).  It
    stays a plain Python function until a kernel that names it compiles: then the module's
    global is replaced by its compiled twin (compiled with the kernel, cached alike), which
    Python callers can still call.  Helpers may call helpers."""
    setattr(function, _HELPER, True)
    return function


def _compile_helpers(function, options: dict, seen: set | None = None) -> None:
    """Replace, in ``function``'s module globals, the helpers it names (and theirs) by their
    compiled twins."""
    seen = set() if seen is None else seen
    names = getattr(function, "py_func", function).__code__.co_names
    scope = getattr(function, "py_func", function).__globals__
    for name in names:
        target = scope.get(name)
        if target is None or id(target) in seen:
            continue
        py = getattr(target, "py_func", target)
        if not getattr(py, _HELPER, False):
            continue
        seen.add(id(target))
        _compile_helpers(py, options, seen)
        if not hasattr(target, "py_func"):
            opts = {k: v for k, v in options.items() if k != "parallel"}
            try:
                scope[name] = _numba.njit(**opts)(py)
            except Exception:  # noqa: BLE001  (no cache for it)
                scope[name] = _numba.njit(**{**opts, "cache": False})(py)


class KernelUnavailable(RuntimeError):
    """A kernel failed to compile; the caller runs its numpy path instead."""


def _is_compile_error(exc: Exception) -> bool:
    if _numba is None:
        return False
    errors = getattr(_numba, "core", None)
    errors = getattr(errors, "errors", None)
    kinds = tuple(k for k in (getattr(errors, "NumbaError", None),
                              getattr(errors, "TypingError", None)) if k is not None)
    return bool(kinds) and isinstance(exc, kinds)


def _reset_for_tests(choice: str | None = None) -> None:
    """Forget the chosen engine (tests switch engines in one process)."""
    global _engine, _noticed
    with _lock:
        if choice is None:
            os.environ.pop(ENV, None)
        else:
            os.environ[ENV] = choice
        _engine = None
        _noticed = False


@contextlib.contextmanager
def forced(choice: str):
    """Run a block under the engine ``choice`` ("numba" or "numpy"), then restore the one
    chosen before (tests compare the two engines in one process)."""
    global _engine, _noticed
    before_env = os.environ.get(ENV)
    before = _engine
    noticed = _noticed
    _reset_for_tests(choice)
    _noticed = noticed  # the notice stays one line per process
    try:
        yield engine()
    finally:
        with _lock:
            if before_env is None:
                os.environ.pop(ENV, None)
            else:
                os.environ[ENV] = before_env
            _engine = before


__all__ = ["Engine", "Kernel", "KernelUnavailable", "engine", "fall_back", "forced", "helper",
           "notice", "on_first_use", "use_numba"]
