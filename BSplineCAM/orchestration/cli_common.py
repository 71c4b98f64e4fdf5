# SPDX-License-Identifier: LGPL-2.1-or-later
"""What every command of ``bin/bsplinecam`` shares: exit statuses, signals, the staged output
folder, strict JSON on stdout and the one-line error.

:mod:`BSplineCAM.orchestration.cli` (the entry point and the ``check``/``surface`` commands)
and the stage commands (``cli_toolpath``, ``cli_verify``, ``cli_job``, :mod:`parts`) import
these from here, so that no module of the command line imports the entry point back.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shutil
import signal
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..app import runtime
from ..core import BSplineCAMError, kernels
from ..core.errors import ParameterError
from ..core.toolpath.retracts import ALLOWANCE_RANGE, MARGIN_RANGE
from ..core.validation import check_range

EXIT_INPUT_ERROR = 2
EXIT_CHECK_FAILED = 1
#: Exit status of an unexpected failure (a bug): one line, no traceback unless
#: BSPLINECAM_TRACEBACK=1.
EXIT_INTERNAL_ERROR = 3
DAT_SAMPLES = 51
#: Grid samples per direction of ``check NET`` (the default before parts existed).
NET_SAMPLES = 101
#: Grid samples per direction of the cross-check (each is evaluated by four evaluators).
SAMPLES_RANGE = (2, 501)
#: Points per side of NAME.dat.
DAT_SAMPLES_RANGE = (4, 1001)


class OutputError(BSplineCAMError):
    """An output folder that cannot be written (a file, under a file, not writable)."""


class Interrupted(BaseException):
    """SIGINT or SIGTERM arrived; a BaseException so that no ``except Exception`` swallows it."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


class _Signals:
    """The first SIGINT/SIGTERM received while a command runs (None before)."""

    received: int | None = None


def _on_signal(signum: int, _frame: Any) -> None:
    # Further signals are ignored so that the clean-up of the staging folder runs to its end.
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.SIG_IGN)
    _Signals.received = signum
    raise Interrupted(signum)


def check_interrupted() -> None:
    """Raise Interrupted if a signal arrived while code that swallows exceptions (FreeCAD's
    recompute) was running."""
    if _Signals.received is not None:
        raise Interrupted(_Signals.received)


@contextlib.contextmanager
def signal_handlers() -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`Interrupted` in the main thread (restored after)."""
    _Signals.received = None
    try:
        saved = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread: leave signals alone
        saved = {}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def check_int(value: int, option: str, low: int, high: int) -> int:
    """An integer option in [low, high], else ParameterError naming it."""
    if not low <= value <= high:
        raise ParameterError(f"{option} must lie in [{low}, {high}] (grid points per side), "
                             f"got {value}")
    return value


def add_retract_options(p: argparse.ArgumentParser, start_stock: bool = False) -> None:
    """``--retract`` and ``--retract-margin`` of the finishing commands, and with
    ``start_stock`` (a finishing program alone) ``--start-stock`` and ``--stock-allowance``."""
    options = [
        ("--retract", dict(default="minimum", choices=["minimum", "full"], help=(
            "between finishing passes no stay-down feed joins: climb only as high as the "
            "model and the stock left need (minimum, default) or to the clearance height "
            "(full)"))),
        ("--retract-margin", dict(type=float, default=1.0, help=(
            "how far a minimum retract's rapids clear the model and the stock (mm, "
            "default 1)")))]
    if start_stock:
        options += [
            ("--start-stock", dict(default="job", choices=["job", "model"], help=(
                "the stock a minimum retract clears: job (the raw block, default) or model "
                "(the model raised by --stock-allowance: a part already roughed or cast to "
                "within it)"))),
            ("--stock-allowance", dict(type=float, default=1.0, help=(
                "with --start-stock model: how far above the model the stock reaches, "
                "measured vertically (mm, default 1)")))]
    for name, kwargs in options:
        p.add_argument(name, **kwargs)


def check_retract_options(args: argparse.Namespace) -> None:
    """``--retract-margin`` (and ``--stock-allowance`` where the command has it) within the
    core's ranges (mm)."""
    args.retract_margin = check_range(args.retract_margin, "--retract-margin", "mm",
                                      *MARGIN_RANGE)
    if hasattr(args, "stock_allowance"):
        args.stock_allowance = check_range(args.stock_allowance, "--stock-allowance", "mm",
                                           *ALLOWANCE_RANGE)


def check_output(out_dir: str | Path, option: str = "--out") -> None:
    """Refuse, before any work, an output folder that cannot be made or written: empty, an
    existing file, a path under a file, or a place without write permission."""
    text = str(out_dir)
    if not text.strip() or "\0" in text:
        raise OutputError(f"{option} must name a folder, got {text!r}")
    path = Path(os.path.abspath(out_dir))
    if path.exists() and not path.is_dir():
        raise OutputError(f"{option} {text}: is a file, not a folder")
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            break
        probe = probe.parent
    if probe.exists() and not probe.is_dir():
        raise OutputError(f"{option} {text}: {probe} is a file, not a folder")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {text}: no permission to write in {probe}")
    try:  # the test that holds for root and read-only file systems too
        os.rmdir(tempfile.mkdtemp(prefix=".bsplinecam-probe-", dir=probe))
    except OSError as exc:
        raise OutputError(f"{option} {text}: cannot write in {probe}: "
                          f"{exc.strerror or exc}") from None


def _make_folder(out_dir: Path, option: str) -> list[Path]:
    """Create ``out_dir`` and missing parents; return the created ones, outermost first."""
    check_output(out_dir, option)
    path = Path(os.path.abspath(out_dir))
    missing = []
    probe = path
    while not probe.exists():
        missing.append(probe)
        probe = probe.parent
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        _remove_folders(missing[::-1])
        raise OutputError(f"{option} {out_dir}: cannot create the folder: "
                          f"{exc.strerror or exc}") from None
    return missing[::-1]


def _remove_folders(created: list[Path]) -> None:
    """Remove the folders a failed command created, innermost first, if still empty."""
    for folder in reversed(created):
        with contextlib.suppress(OSError):
            folder.rmdir()


@contextlib.contextmanager
def staged_output(out_dir: Path, option: str = "--out") -> Iterator[Path]:
    """A staging folder inside ``out_dir`` whose files are moved in only if all succeeded.

    On an error, SIGINT or SIGTERM the staging folder is removed, and so are the folders this
    call created; a file in ``out_dir`` is never half-written (each is moved in whole).
    """
    created = _make_folder(out_dir, option)
    committed = False
    try:
        try:
            stage = Path(tempfile.mkdtemp(prefix=".staging-", dir=out_dir))
        except OSError as exc:
            raise OutputError(f"{option} {out_dir}: cannot write there: "
                              f"{exc.strerror or exc}") from None
        try:
            yield stage
            check_interrupted()
            items = sorted(stage.iterdir())
            for item in items:
                target = out_dir / item.name
                if target.is_dir() and not target.is_symlink():
                    raise OutputError(f"{option} {out_dir}: {item.name} is a folder there; "
                                      "nothing was written")
            try:
                for item in items:
                    os.replace(item, out_dir / item.name)
            except OSError as exc:
                raise OutputError(f"{option} {out_dir}: cannot write {item.name}: "
                                  f"{exc.strerror or exc}") from None
            committed = True
        finally:
            shutil.rmtree(stage, ignore_errors=True)
    finally:
        if not committed:
            _remove_folders(created)


def strict(value: Any) -> Any:
    """``value`` with every non-finite float replaced by None (JSON null), recursively; numpy
    scalars and arrays become plain Python."""
    if isinstance(value, dict):
        return {str(k): strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return strict(value.tolist())
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return value


def json_text(value: Any) -> str:
    """Strict JSON (no NaN or Infinity) of a command's result."""
    return json.dumps(strict(value), indent=1, allow_nan=False) + "\n"


def flush_all() -> None:
    """Flush Python's streams and C's stdio buffers (FreeCAD's C++ console writes there)."""
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL(None).fflush(None)


@contextlib.contextmanager
def captured_console() -> Iterator[None]:
    """Hold what FreeCAD writes on descriptors 1 and 2 (its console, tracebacks of a refused
    recompute) while the block runs; pass it on to stderr only if the block succeeds, so a
    refusal prints the command's one line and nothing else."""
    flush_all()
    saved = (os.dup(1), os.dup(2))
    ok = False
    with tempfile.TemporaryFile() as log:
        os.dup2(log.fileno(), 1)
        os.dup2(log.fileno(), 2)
        try:
            yield
            ok = True
        finally:
            flush_all()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            # a signal FreeCAD swallowed (it prints the traceback and carries on) is not success
            if ok and _Signals.received is None:
                log.seek(0)
                with contextlib.suppress(OSError):
                    os.write(2, log.read())


def with_engine(result: dict) -> dict:
    """``result`` with the engine that computed it (``kernels``: numba or numpy, why, the
    compile seconds of this run), set once so that the JSON written to a file and the one
    printed agree."""
    if isinstance(result, dict) and "kernels" not in result:
        result["kernels"] = kernels.engine().to_dict()
    return result


def emit(result: dict) -> None:
    """Print a command's JSON result on stdout (descriptor BSPLINECAM_RESULT_FD when set, so
    FreeCAD's own console output cannot mix into it), with the engine that computed it
    (``kernels``: numba or numpy, why, the compile seconds of this run)."""
    text = json_text(with_engine(result))
    fd = os.environ.get("BSPLINECAM_RESULT_FD")
    if fd:
        os.write(int(fd), text.encode())
    else:
        sys.stdout.write(text)
        sys.stdout.flush()


def _safe_name(name: str) -> str:
    clean = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name).strip("._")
    return clean or "surface"


class OneLineParser(argparse.ArgumentParser):
    """argparse with a one-line error on stderr (``bsplinecam SUB: error: ...``), status 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        text = " ".join(message.split())
        self.exit(EXIT_INPUT_ERROR, f"{self.prog}: error: {text}\n")


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, (ValueError, runtime.BackendUnavailable)):  # messages for users
        return text
    if isinstance(exc, OSError) and exc.filename is not None:
        return f"{exc.filename}: {exc.strerror or text}"
    if isinstance(exc, MemoryError):
        return "out of memory (a smaller request would fit: see the README's limits)"
    return f"{type(exc).__name__}: {text}"


def _exit_status(exc: BaseException) -> int:
    """2 for bad input (the project's errors, ValueError, unreadable or unwritable paths,
    memory), 3 for anything else (a bug to report)."""
    expected = (ValueError, OSError, MemoryError, OverflowError, runtime.BackendUnavailable)
    return EXIT_INPUT_ERROR if isinstance(exc, expected) else EXIT_INTERNAL_ERROR
