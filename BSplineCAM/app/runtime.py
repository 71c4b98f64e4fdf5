# SPDX-License-Identifier: LGPL-2.1-or-later
"""Which Python runs which OCCT: FreeCAD's and cadquery's are kept in separate processes.

FreeCAD 0.20 on Debian runs Debian's python3 with numpy 1.24; cadquery lives in the project's
virtual environment with numpy 2.x.  Work that needs the other one goes to a worker process
(:mod:`BSplineCAM.orchestration.worker`) through JSON files.
It lives in app, below the command line, because the surface object's cross-check
(:mod:`BSplineCAM.app.crosscheck`) reaches cadquery's OCCT through it too; the worker module
is started by name, never imported here.

A worker runs in a session of its own under a time limit; when the limit passes or the caller
is interrupted (Ctrl-C, SIGTERM, any exception) its whole process group is killed before
:func:`run_worker` returns or raises.  A worker that ends without a reply after it started
(killed by a signal such as a SIGSEGV inside OCCT, or an exit of its own) raises
:class:`WorkerStopped`, which says how it ended.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from ..core.errors import BSplineCAMError
from .compat import ensure_freecad

REPO_ROOT = Path(__file__).resolve().parents[2]
WORKER_TIMEOUT_S = 1800


class BackendUnavailable(RuntimeError):
    """The Python for a backend (FreeCAD or cadquery) is not installed here."""


class WorkerStopped(RuntimeError):
    """A worker that started but ended without a reply: killed by a signal (``signum``),
    ended with an exit status of its own (``returncode``), or stopped by the caller after
    ``time_limit`` seconds (``timed_out``)."""

    def __init__(self, backend: str, returncode: int | None, time_limit: float,
                 timed_out: bool = False, detail: str = "") -> None:
        self.backend = backend
        self.returncode = returncode
        self.time_limit = time_limit
        self.timed_out = timed_out
        self.detail = detail
        super().__init__(f"{backend} worker {self.how()}" + (f": {detail}" if detail else ""))

    @property
    def signum(self) -> int | None:
        """The signal that killed the worker (None for an exit status or a time-out)."""
        if self.timed_out or self.returncode is None or self.returncode >= 0:
            return None
        return -self.returncode

    def ending(self) -> str:
        """``signal 11 (SIGSEGV)`` or ``exit status 1`` (empty for a time-out)."""
        if self.timed_out or self.returncode is None:
            return ""
        signum = self.signum
        if signum is None:
            return f"exit status {self.returncode}"
        try:
            return f"signal {signum} ({signal.Signals(signum).name})"
        except ValueError:
            return f"signal {signum}"

    def how(self) -> str:
        """``stopped with signal 11 (SIGSEGV)``, ``stopped with exit status 1`` or
        ``did not finish within 300 s``."""
        if self.timed_out:
            return f"did not finish within {self.time_limit:g} s"
        return f"stopped with {self.ending()}"


def freecad_python() -> str:
    return os.environ.get("BSPLINECAM_FREECAD_PYTHON", "/usr/bin/python3")


def cadquery_python() -> str:
    return os.environ.get("BSPLINECAM_CADQUERY_PYTHON", str(REPO_ROOT / ".venv" / "bin" / "python"))


def freecad_in_process() -> bool:
    """True when FreeCAD is loaded here, or this is FreeCAD's own Python and it loads.

    Any other interpreter (the cadquery venv) reaches FreeCAD through a worker, so that
    FreeCAD's libraries never load into a Python they were not built for.
    """
    if "FreeCAD" in sys.modules:
        return True
    if "OCP" in sys.modules or os.path.realpath(sys.executable) != os.path.realpath(freecad_python()):
        return False
    try:
        ensure_freecad()
    except ImportError:
        return False
    return True


def cadquery_in_process() -> bool:
    """True when OCP is importable here and FreeCAD's OCCT is not loaded in this process."""
    if "FreeCAD" in sys.modules:
        return False
    return importlib.util.find_spec("OCP") is not None


def run_worker(backend: str, request: dict, timeout: float | None = None) -> dict:
    """Run one request in the Python of ``backend`` ("freecad" or "cadquery"); return its reply.

    ``timeout`` (s, default :data:`WORKER_TIMEOUT_S`) bounds the worker's run.  Raises
    :class:`WorkerStopped` when the worker started but gave no reply (a signal, an exit, the
    time limit), :class:`BackendUnavailable` when it could not start, BSplineCAMError for the
    bad input it reports and RuntimeError for its other errors.
    """
    python = freecad_python() if backend == "freecad" else cadquery_python()
    if not Path(python).exists():
        raise BackendUnavailable(f"{backend}: no Python at {python} (run the README's set-up command)")
    limit = WORKER_TIMEOUT_S if timeout is None else float(timeout)
    with tempfile.TemporaryDirectory(prefix="bsplinecam-") as tmp:
        req = Path(tmp) / "request.json"
        rep = Path(tmp) / "reply.json"
        req.write_text(json.dumps({**request, "backend": backend}))
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
        command = [python, "-m", "BSplineCAM.orchestration.worker", str(req), str(rep)]
        try:
            returncode, output = _run_child(command, env, limit)
        except subprocess.TimeoutExpired:
            raise WorkerStopped(backend, None, limit, timed_out=True) from None
        if not rep.exists():
            tail = "\n".join(output.strip().splitlines()[-8:])
            if started_marker(rep).exists():  # the worker ran: it was killed or exited
                raise WorkerStopped(backend, returncode, limit, detail=tail)
            raise BackendUnavailable(f"{backend} worker failed (exit {returncode}): {tail}")
        reply = json.loads(rep.read_text())
    if "error" in reply:
        if reply.get("input_error"):  # bad input found by the other Python: exit status 2
            raise BSplineCAMError(f"{backend} worker: {reply['error']}")
        raise RuntimeError(f"{backend} worker: {reply['error']}")
    return reply


def started_marker(reply: Path) -> Path:
    """The file a worker creates next to its reply once it runs (its imports done)."""
    return reply.with_name(reply.name + ".started")


def _run_child(command: list[str], env: dict, limit: float) -> tuple[int, str]:
    """(exit status, stderr or else stdout) of ``command`` run in a new session; its process
    group is killed on a time-out (subprocess.TimeoutExpired) and on any exception or signal
    that reaches the caller meanwhile (KeyboardInterrupt, cli.Interrupted)."""
    proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            env=env, start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=limit)
    finally:
        if proc.poll() is None:
            _kill_group(proc)
    return proc.returncode, stderr or stdout


def _kill_group(proc: subprocess.Popen) -> None:
    """SIGKILL to the worker's process group (its own session), then reap it."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    # a process stuck in the kernel may outlive SIGKILL for a while: init reaps it later
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.communicate(timeout=10)
