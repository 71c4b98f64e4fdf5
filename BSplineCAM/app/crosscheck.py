# SPDX-License-Identifier: LGPL-2.1-or-later
"""Cross-check: the matrix evaluator against Cox–de Boor, FreeCAD's OCCT and cadquery's OCCT.

Every figure is a maximum deviation computed on a dense parameter grid (boundaries included).
The exact route must agree to ``EXACT_TOLERANCE`` of the net's size; the paper's own route
(sampled points → curves → loft) is measured beside it for comparison.
"""

from __future__ import annotations

import time

import numpy as np

from ..core import Surface
from ..core.geometry.basis import cox_de_boor_surface
from . import runtime
from .compat import freecad_version

EXACT_TOLERANCE = 1e-9
DEFAULT_SAMPLES = 101
#: Points per side of the .dat grid the paper's route starts from.
PAPER_ROUTE_POINTS = 21


def _params(samples: int) -> tuple[np.ndarray, np.ndarray]:
    t = np.linspace(0.0, 1.0, samples)
    u, w = np.meshgrid(t, t, indexing="ij")
    return u.ravel(), w.ravel()


def _net_request(surface: Surface) -> dict:
    return {"net": surface.to_net().to_json_dict()}


def occt_points(surface: Surface, backend: str, u: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, str]:
    """OCCT's evaluation by ``backend``, in this process when possible, else in a worker."""
    if backend == "freecad" and runtime.freecad_in_process():
        from . import part

        return part.evaluate(surface, u, w), ".".join(map(str, freecad_version()))
    if backend == "cadquery" and runtime.cadquery_in_process():
        import OCP

        from ..ocp import occ

        return occ.evaluate(surface, u, w), getattr(OCP, "__version__", "unknown")
    reply = runtime.run_worker(backend, {"op": "evaluate", "u": u.tolist(), "w": w.tolist(), **_net_request(surface)})
    return np.array(reply["points"], dtype=float), reply.get("version", "unknown")


def paper_route_deviation(surface: Surface, points: int = PAPER_ROUTE_POINTS) -> dict:
    """Deviation of the paper's route, rebuilt in FreeCAD from a points x points .dat grid."""
    grid = surface.grid(points, points)
    if runtime.freecad_in_process():
        from . import part

        result = part.deviation_between(part.paper_route(grid), surface)
    else:
        result = runtime.run_worker("freecad", {"op": "paper_route", "points": grid.tolist(), **_net_request(surface)})
    result["points"] = [points, points]
    return result


def crosscheck(
    surface: Surface,
    samples: int = DEFAULT_SAMPLES,
    backends: tuple[str, ...] = ("freecad", "cadquery"),
    paper_route: bool = True,
) -> dict:
    """Evaluate ``samples`` x ``samples`` parameters every way and report the deviations (mm)."""
    started = time.perf_counter()
    u, w = _params(samples)
    reference = surface.evaluate(u, w)
    size = surface.size() or 1.0
    ku, kw = surface.knot_vectors()
    deviations: dict[str, float | None] = {
        "cox_de_boor": float(np.abs(cox_de_boor_surface(surface.control_points, ku, kw, u, w) - reference).max())
    }
    versions: dict[str, str] = {}
    unavailable: dict[str, str] = {}
    for backend in backends:
        key = f"{backend}_occt"
        try:
            points, versions[backend] = occt_points(surface, backend, u, w)
        except runtime.BackendUnavailable as exc:
            deviations[key] = None
            unavailable[key] = str(exc)
            continue
        deviations[key] = float(np.abs(points - reference).max())
    measured = {k: v for k, v in deviations.items() if v is not None}
    report = {
        "name": surface.name,
        "knots": surface.knots.value,
        "control_net": list(surface.shape),
        "size_mm": size,
        "samples": [samples, samples],
        "max_deviation_mm": deviations,
        "relative_deviation": {k: (v / size if v is not None else None) for k, v in deviations.items()},
        "tolerance_relative": EXACT_TOLERANCE,
        "exact_route_ok": bool(measured) and not unavailable and all(v <= EXACT_TOLERANCE * size for v in measured.values()),
        "versions": versions,
    }
    if unavailable:
        report["unavailable"] = unavailable
    if paper_route and "freecad" in backends and "freecad_occt" not in unavailable:
        report["paper_route"] = paper_route_deviation(surface)
    report["seconds"] = round(time.perf_counter() - started, 3)
    return report
