# SPDX-License-Identifier: LGPL-2.1-or-later
"""Which Python runs which OCCT: FreeCAD's and cadquery's are kept in separate processes.

FreeCAD 0.20 on Debian runs Debian's python3 with numpy 1.24; cadquery lives in the project's
virtual environment with numpy 2.x.  Work that needs the other one goes to a worker process
(:mod:`BSplineCAM.orchestration.worker`) through JSON files.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parents[2]
WORKER_TIMEOUT_S = 1800


class BackendUnavailable(RuntimeError):
    """The Python for a backend (FreeCAD or cadquery) is not installed here."""


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
        from ..app.compat import ensure_freecad

        ensure_freecad()
    except ImportError:
        return False
    return True


def cadquery_in_process() -> bool:
    """True when OCP is importable here and FreeCAD's OCCT is not loaded in this process."""
    if "FreeCAD" in sys.modules:
        return False
    return importlib.util.find_spec("OCP") is not None


def run_worker(backend: str, request: dict) -> dict:
    """Run one request in the Python of ``backend`` ("freecad" or "cadquery"); return its reply."""
    python = freecad_python() if backend == "freecad" else cadquery_python()
    if not Path(python).exists():
        raise BackendUnavailable(f"{backend}: no Python at {python} (run the README's set-up command)")
    with tempfile.TemporaryDirectory(prefix="bsplinecam-") as tmp:
        req = Path(tmp) / "request.json"
        rep = Path(tmp) / "reply.json"
        req.write_text(json.dumps({**request, "backend": backend}))
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
        proc = subprocess.run(
            [python, "-m", "BSplineCAM.orchestration.worker", str(req), str(rep)],
            capture_output=True, text=True, env=env, timeout=WORKER_TIMEOUT_S, check=False,
        )
        if not rep.exists():
            tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-8:])
            raise BackendUnavailable(f"{backend} worker failed (exit {proc.returncode}): {tail}")
        reply = json.loads(rep.read_text())
    if "error" in reply:
        if reply.get("input_error"):  # bad input found by the other Python: exit status 2
            from ..core.errors import BSplineCAMError

            raise BSplineCAMError(f"{backend} worker: {reply['error']}")
        raise RuntimeError(f"{backend} worker: {reply['error']}")
    return reply
