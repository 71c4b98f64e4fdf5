# SPDX-License-Identifier: LGPL-2.1-or-later
"""Worker entry point: ``python -m BSplineCAM.orchestration.worker REQUEST.json REPLY.json``.

Runs one request against FreeCAD's or cadquery's OCCT in this process and writes a JSON reply
(``{"error": ...}`` on failure), so that the two OCCTs never share a process.  Once its
imports are done it creates ``REPLY.json.started``: a worker that then ends without a reply
was stopped (by a signal, its own exit or the caller's time limit), not unable to start.

Part files are read here, never in the process that asked (see
:mod:`BSplineCAM.orchestration.parts`).  Before a part is read, SIGSEGV gets its default action
back (FreeCAD's handler ends the process with status 1 and no message, which would hide the
signal from the caller) and core dumps are switched off.  Two variables, read only here, stand
in for a broken reader in tests: ``BSPLINECAM_TEST_CRASH_READ=1`` makes the worker kill itself
with SIGSEGV and ``BSPLINECAM_TEST_HANG_READ=1`` makes it sleep, where it would read the part.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
import traceback
from pathlib import Path

import numpy as np

from ..app.compat import freecad_version
from ..core import Surface
from ..core.geometry.netio import net_from_dict

#: Request kinds of :mod:`BSplineCAM.orchestration.parts` (kept here so that a net request
#: never imports it).
PART_REQUESTS = ("part_faces", "part_check", "evaluate_faces")
#: The requests that read a part file with FreeCAD's OCCT.
READ_REQUESTS = ("part_faces", "part_check")
#: Test hooks (see the module's docstring).
TEST_CRASH_READ = "BSPLINECAM_TEST_CRASH_READ"
TEST_HANG_READ = "BSPLINECAM_TEST_HANG_READ"


def prepare_part_read(request: dict) -> None:
    """For a request that reads a part: FreeCAD and Part loaded, SIGSEGV at its default action
    (the process dies by the signal and the caller names it), no core file; then the test
    hooks."""
    if request.get("op") not in READ_REQUESTS or request.get("backend") != "freecad":
        return
    from ..app import faces  # noqa: F401  (FreeCAD and Part: their signal handlers are set)

    signal.signal(signal.SIGSEGV, signal.SIG_DFL)
    try:
        import resource

        resource.setrlimit(resource.RLIMIT_CORE, (0, resource.getrlimit(resource.RLIMIT_CORE)[1]))
    except (ImportError, ValueError, OSError):
        pass
    if os.environ.get(TEST_CRASH_READ) == "1":
        os.kill(os.getpid(), signal.SIGSEGV)
    if os.environ.get(TEST_HANG_READ) == "1":
        while True:
            time.sleep(60)


def handle(request: dict) -> dict:
    if request.get("op") in PART_REQUESTS:  # parts and faces (orchestration/parts.py)
        from .parts import handle as handle_part

        return handle_part(request)
    surface = Surface.from_net(net_from_dict(request["net"], "request"))
    backend = request["backend"]
    op = request["op"]
    if backend == "freecad":
        from ..app import part as impl
    elif backend == "cadquery":
        from ..ocp import occ as impl
    else:
        raise ValueError(f"unknown backend {backend!r}")
    if op == "evaluate":
        points = impl.evaluate(surface, np.array(request["u"]), np.array(request["w"]))
        return {"points": points.tolist(), "version": backend_version(backend)}
    if op == "export":
        if backend == "freecad":
            impl.export_shape(impl.to_face(surface), request["path"])
        else:
            impl.export(surface, request["path"])
        return {"path": request["path"]}
    if op == "paper_route" and backend == "freecad":
        grid = np.array(request["points"], dtype=float)
        face = impl.paper_route(grid)
        return impl.deviation_between(face, surface, int(request.get("samples", 41)))
    if op == "save_document" and backend == "freecad":
        from ..app.surface_feature import save_document

        save_document(surface, request["path"], bool(request.get("solid", True)))
        return {"path": request["path"]}
    raise ValueError(f"operation {op!r} is not available for backend {backend!r}")


def backend_version(backend: str) -> str:
    if backend == "freecad":
        return ".".join(map(str, freecad_version()))
    import OCP

    return getattr(OCP, "__version__", "unknown")


def main(argv: list[str]) -> int:
    request_path, reply_path = argv[1], argv[2]
    Path(reply_path + ".started").touch()  # runtime.started_marker
    try:
        with open(request_path, encoding="utf-8") as stream:
            request = json.load(stream)
        prepare_part_read(request)
        reply = handle(request)
    except Exception as exc:  # reported to the parent process, which raises it with context
        reply = {"error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc(),
                 "input_error": isinstance(exc, ValueError)}
    with open(reply_path, "w", encoding="utf-8") as stream:
        json.dump(reply, stream)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
