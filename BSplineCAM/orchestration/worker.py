# SPDX-License-Identifier: LGPL-2.1-or-later
"""Worker entry point: ``python -m BSplineCAM.orchestration.worker REQUEST.json REPLY.json``.

Runs one request against FreeCAD's or cadquery's OCCT in this process and writes a JSON reply
(``{"error": ...}`` on failure), so that the two OCCTs never share a process.
"""

from __future__ import annotations

import json
import sys
import traceback

import numpy as np

from ..core import Surface
from ..core.netio import net_from_dict

#: Request kinds of :mod:`BSplineCAM.orchestration.parts` (kept here so that a net request
#: never imports it).
PART_REQUESTS = ("part_faces", "part_check", "evaluate_faces")


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
        impl.save_document(surface, request["path"], bool(request.get("solid", True)))
        return {"path": request["path"]}
    raise ValueError(f"operation {op!r} is not available for backend {backend!r}")


def backend_version(backend: str) -> str:
    if backend == "freecad":
        from ..app.compat import freecad_version

        return ".".join(map(str, freecad_version()))
    import OCP

    return getattr(OCP, "__version__", "unknown")


def main(argv: list[str]) -> int:
    request_path, reply_path = argv[1], argv[2]
    try:
        with open(request_path, encoding="utf-8") as stream:
            reply = handle(json.load(stream))
    except Exception as exc:  # reported to the parent process, which raises it with context
        reply = {"error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc(),
                 "input_error": isinstance(exc, ValueError)}
    with open(reply_path, "w", encoding="utf-8") as stream:
        json.dump(reply, stream)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
