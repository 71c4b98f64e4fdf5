# SPDX-License-Identifier: LGPL-2.1-or-later
"""The reader of parts: the faces of an OCCT shape into core Faces, through an adapter.

FreeCAD's Part (``app/faces.py``) and cadquery's OCP (``ocp/faces.py``) reach OCCT by
different APIs.  Each answers the small set of questions of :class:`PartAdapter` (the shape's
faces, a surface's type, its B-spline arrays, a wire's edges and their parameter curves, the
face's normals and tolerances...) with plain Python and numpy values; this module holds the
logic once and never touches either API:

* :func:`extract` -- one face: a B-spline or Bézier surface as it is, any other through
  OCCT's NURBS conversion (BRepBuilderAPI_NurbsConvert); the trim's parameter curves
  densified into loops (:func:`loops`, :func:`BSplineCAM.core.geometry.faces.densify_edge`); the
  surface's arrays with periodic or unclamped knots segmented to clamped ones
  (:func:`nurbs_arrays`); the result checked against OCCT's surfaces
  (:func:`BSplineCAM.core.geometry.face_import.checked_face` with :func:`measure`);
* :func:`reaches_from_above` -- OCCT's outward normals at the sampled points of the trimmed
  domain, given to :func:`BSplineCAM.core.geometry.faces.reach` with the model's tolerance at the face;
* :func:`faces_from_shape`, :func:`faces_and_reach` -- every face of a shape, with the
  selection ("up" or face numbers) applied.

Errors are FaceError naming the face ("Face7 (Cylinder): ...") or the shape (``where``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import Any, Protocol

import numpy as np

from ..typing import FloatArray
from . import faces as core_faces
from .face_import import DEFAULT_CHORDAL_TOLERANCE, checked_face, segment_box
from .faces import DEFAULT_TOLERANCE, REACH_SAMPLES, Face, FaceError

#: Surface types (FreeCAD's Part class names) whose arrays are read as they are.
NURBS_KINDS = ("BSplineSurface", "BezierSurface")


class PartAdapter(Protocol):
    """The questions the reader asks of one OCCT API.  Faces, wires, edges and surfaces are
    the API's own objects, handed back to the adapter unchanged; parameters and lengths are
    floats (mm for lengths)."""

    # -- shape
    def faces(self, shape: Any) -> Sequence[Any]:
        """The shape's faces in FreeCAD's order (``Shape.Faces``); [] for a null shape."""

    def check(self, shape: Any, where: str) -> None:
        """FaceError naming ``where`` when the shape is to be refused as invalid."""

    # -- face
    def surface(self, face: Any) -> Any:
        """The face's OCCT surface (placed as the face is)."""

    def nurbs_faces(self, face: Any) -> Sequence[Any]:
        """The faces of OCCT's NURBS conversion of ``face`` (any exception: it failed)."""

    def reversed(self, face: Any) -> bool:
        """Whether the face's orientation is Reversed."""

    def diagonal(self, face: Any) -> float:
        """The diagonal (mm) of the face's bounding box."""

    def model_tolerance(self, face: Any) -> float:
        """The largest OCCT tolerance (mm) of the face, its edges and its vertices."""

    def wires(self, face: Any) -> Sequence[tuple[Any, bool]]:
        """The face's wires, each with whether it is the outer wire."""

    def edges(self, face: Any, wire: Any) -> Sequence[Any]:
        """The wire's edges in the order they follow each other on the face."""

    def vertex_tolerance(self, wire: Any) -> float:
        """The largest OCCT tolerance (mm) of the wire's vertices (0 without vertices)."""

    def degenerated(self, edge: Any) -> bool:
        """Whether the edge is degenerated (a pole: one 3-D point)."""

    def pcurve(self, face: Any, edge: Any, surface: Any,
               ) -> tuple[Callable[[FloatArray], FloatArray], float, float]:
        """The edge's parameter curve on the face: (ts -> (k, 2) parameters, t0, t1)."""

    def normals_z(self, face: Any, u: FloatArray, v: FloatArray) -> list[float | None]:
        """The z of the face's outward unit normal at each OCCT parameter point (u, v);
        None where OCCT gives no normal."""

    def original_distances(self, face: Any, points: FloatArray, name: str) -> Iterable[float]:
        """The distance (mm) of each of ``points`` (k, 3) from the face's surface; FaceError
        naming the face ``name`` when a point has none."""

    # -- surface
    def kind(self, surface: Any) -> str:
        """The surface's type as FreeCAD's Part module names it ("Plane", "BSplineSurface"...)."""

    def points(self, surface: Any, uv: Iterable[Sequence[float]]) -> FloatArray:
        """OCCT's points (k, 3) of the surface at the parameter points ``uv``."""

    def degrees(self, surface: Any) -> tuple[int, int]:
        """The surface's degrees in u and v."""

    def knots(self, surface: Any) -> tuple[Sequence[float], Sequence[int],
                                           Sequence[float], Sequence[int]]:
        """A B-spline surface's distinct knots and multiplicities: (u, mu, v, mv)."""

    def periods(self, surface: Any) -> tuple[float, float]:
        """A B-spline surface's periods in u and v, 0.0 for a direction not periodic."""

    def bounds(self, surface: Any) -> tuple[float, float, float, float]:
        """A B-spline surface's parameter bounds (u0, u1, v0, v1)."""

    def segmented(self, surface: Any, u0: float, u1: float, v0: float, v1: float) -> Any:
        """A copy of a B-spline surface segmented to [u0, u1] x [v0, v1] (exact knot
        insertion, same parameters)."""

    def poles(self, surface: Any) -> tuple[FloatArray, FloatArray]:
        """A B-spline or Bézier surface's poles (n, m, 3) and weights (n, m)."""


# --------------------------------------------------------------------------- one face


def _clamped(adapter: PartAdapter, surface: Any) -> bool:
    pu, pv = adapter.periods(surface)
    if pu > 0 or pv > 0:
        return False
    p, q = adapter.degrees(surface)
    _, mu, _, mv = adapter.knots(surface)
    return mu[0] == p + 1 and mu[-1] == p + 1 and mv[0] == q + 1 and mv[-1] == q + 1


def nurbs_arrays(adapter: PartAdapter, surface: Any, uv_box: Sequence[float],
                 name: str) -> dict:
    """Poles (n, m, 3), weights (n, m), full clamped knot vectors and degrees of a B-spline or
    Bézier ``surface`` (core.faces.make_surface's keywords).  A periodic direction is cut to
    the trim's range ``uv_box`` (u0, u1, v0, v1) by exact knot insertion, keeping the
    parameters; an unclamped one is clamped to its bounds."""
    if adapter.kind(surface) == "BezierSurface":
        p, q = adapter.degrees(surface)
        poles, weights = adapter.poles(surface)
        return {"poles": poles, "weights": weights,
                "knots_u": np.array([0.0] * (p + 1) + [1.0] * (p + 1)),
                "knots_v": np.array([0.0] * (q + 1) + [1.0] * (q + 1)),
                "degree_u": int(p), "degree_v": int(q)}
    shift = (0.0, 0.0)
    if not _clamped(adapter, surface):
        periods = adapter.periods(surface)
        u0, u1, v0, v1 = segment_box(adapter.bounds(surface), uv_box, periods, name)
        surface = adapter.segmented(surface, u0, u1, v0, v1)
        shift = core_faces.period_shift(adapter.bounds(surface), (u0, v0), periods)
        if not _clamped(adapter, surface):
            raise FaceError(f"{name}: OCCT could not clamp the surface's knot vectors")
    p, q = adapter.degrees(surface)
    ku, mu, kv, mv = adapter.knots(surface)
    poles, weights = adapter.poles(surface)
    knots_u = np.repeat(np.asarray(ku, dtype=float), np.asarray(mu, dtype=int))
    knots_v = np.repeat(np.asarray(kv, dtype=float), np.asarray(mv, dtype=int))
    # Segment may land a whole period away from the trim: translate the knots back.
    return {"poles": poles, "weights": weights, "knots_u": knots_u - shift[0],
            "knots_v": knots_v - shift[1], "degree_u": int(p), "degree_v": int(q)}


def loops(adapter: PartAdapter, face: Any, tolerance: float,
          name: str) -> tuple[FloatArray, list[FloatArray]]:
    """The outer loop and the hole loops ((k, 2) parameters) of a face's trim: each edge's
    parameter curve densified to the 3-D chord ``tolerance`` (mm), the edges of a wire
    joined in order; FaceError naming the face ``name`` for a wire that does not close."""
    surface = adapter.surface(face)
    size = max(adapter.diagonal(face), 1e-300)

    def point(uv):
        return adapter.points(surface, uv)

    def gap_mm(a: FloatArray, b: FloatArray) -> float:
        """Distance on the surface (mm) of two parameter points."""
        ends = point([a, b])
        return float(np.linalg.norm(ends[0] - ends[1]))

    holes, outer = [], None
    for n, (wire, is_outer) in enumerate(adapter.wires(face), start=1):
        which = "outer wire" if is_outer else f"wire {n}"
        pieces = []
        for edge in adapter.edges(face, wire):
            pcurve, t0, t1 = adapter.pcurve(face, edge, surface)
            if adapter.degenerated(edge):  # a pole: a straight parameter segment
                pieces.append(np.asarray(pcurve(np.array([t0, t1])), dtype=float))
            else:
                pieces.append(core_faces.densify_edge(pcurve, point, t0, t1, tolerance,
                                                      name=name))
        # edges meet at a vertex within its tolerance (OCCT leaves the parameter curves of
        # fillets meeting at a corner up to ~0.01 mm apart): measured on the surface, in mm
        gap = adapter.vertex_tolerance(wire) + 1e-7 * size
        loop = core_faces.join_edges(pieces, name, which, gap, gap_mm, "on the surface (mm)")
        if is_outer:
            outer = loop
        else:
            holes.append(loop)
    if outer is None:
        raise FaceError(f"{name}: has no outer wire")
    return outer, holes


def occt_v(face: Face, v):
    """OCCT's v of the core face's parameter ``v`` (the face is flipped in v when OCCT's is
    reversed)."""
    if not face.flipped_v:
        return v
    k = np.asarray(face.surface.knots_v, dtype=float)
    return k[0] + k[-1] - v


def extract(adapter: PartAdapter, source: Any, index: int,
            tolerance: float = DEFAULT_TOLERANCE, selected: bool = True,
            chordal_tolerance: float | None = DEFAULT_CHORDAL_TOLERANCE) -> tuple[Face, Any]:
    """(the core Face of the OCCT face ``source``, ``index`` 1-based in its shape; OCCT's
    B-spline face it was taken from: ``source`` itself or its NURBS conversion).  The face is
    accepted for machining to ``chordal_tolerance`` (mm; None: measured, never refused)."""
    name = f"Face{index}"
    kind = adapter.kind(adapter.surface(source))
    if kind in NURBS_KINDS:
        work = source
    else:
        try:
            converted = adapter.nurbs_faces(source)
        except Exception as exc:  # OCCT's Standard_Failure, as the API raises it
            raise FaceError(f"{name} ({kind}): OCCT's NURBS conversion failed ({exc})") from None
        if (len(converted) != 1
                or adapter.kind(adapter.surface(converted[0])) != "BSplineSurface"):
            raise FaceError(f"{name} ({kind}): OCCT's NURBS conversion gave no B-spline face")
        work = converted[0]
    outer, holes = loops(adapter, work, tolerance, name)
    box = np.concatenate([outer, *holes])
    uv_box = (float(box[:, 0].min()), float(box[:, 0].max()),
              float(box[:, 1].min()), float(box[:, 1].max()))
    data = nurbs_arrays(adapter, adapter.surface(work), uv_box, name)
    face = checked_face(data, outer, holes, adapter.reversed(work),
                        lambda face: measure(adapter, face, source, work),
                        max(adapter.diagonal(source), 1e-300), index=index, name=name,
                        kind=kind, selected=selected, tolerance=tolerance,
                        chordal_tolerance=chordal_tolerance)
    return face, work


def measure(adapter: PartAdapter, face: Face, source: Any, work: Any) -> float:
    """Max distance (mm) of the core NURBS from OCCT's surfaces at points of the face.

    At the same (u, v) against the B-spline OCCT holds (``work``); when ``source`` was
    converted, also the distance to its original surface.
    """
    uv = core_faces.sample_points(face)
    ours = np.asarray(face.surface.evaluate(uv[:, 0], uv[:, 1]), dtype=float)
    vo = occt_v(face, uv[:, 1])
    theirs = adapter.points(adapter.surface(work), zip(uv[:, 0], vo))
    deviation = float(np.linalg.norm(ours - theirs, axis=1).max())
    if work is not source:
        for distance in adapter.original_distances(source, ours, face.name):
            deviation = max(deviation, float(distance))
    return deviation


# --------------------------------------------------------------------------- "up"


def reaches_from_above(adapter: PartAdapter, face: Face, work: Any) -> tuple[bool, str]:
    """Whether a 3-axis tool reaches the face from above, and why not
    (:func:`BSplineCAM.core.geometry.faces.reach`).

    ``work`` is the OCCT B-spline face the core face was taken from (OCCT's normals, which
    follow the face's orientation, and the model's tolerance there).
    """
    uv = core_faces.sample_points(face, REACH_SAMPLES)
    normals = adapter.normals_z(work, uv[:, 0], occt_v(face, uv[:, 1]))
    keep = [k for k, z in enumerate(normals) if z is not None]
    nz = [normals[k] for k in keep]
    if not keep:
        return core_faces.reach([], [], adapter.model_tolerance(work), 0.0)
    points = np.asarray(face.surface.evaluate(uv[keep, 0], uv[keep, 1]), dtype=float)
    spacing = float(np.linalg.norm(np.ptp(points, axis=0))) / REACH_SAMPLES
    return core_faces.reach(nz, points[:, 2], adapter.model_tolerance(work), spacing)


# --------------------------------------------------------------------------- a shape


def checked_faces(adapter: PartAdapter, shape: Any, tolerance: float,
                  where: str) -> Sequence[Any]:
    """The faces of ``shape`` once the trim ``tolerance`` (mm) and the shape are found fit
    (FaceError naming ``where`` otherwise), before any face is extracted."""
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise FaceError(f"{where}: trim tolerance must be a positive length in mm, "
                        f"got {tolerance!r}")
    sources = adapter.faces(shape)
    if not sources:
        raise FaceError(f"{where}: has no faces")
    adapter.check(shape, where)
    return sources


def _faces_with_reach(adapter: PartAdapter, sources: Sequence[Any], tolerance: float,
                      chordal_tolerance: float) -> tuple[list[Face], list[tuple[bool, str]]]:
    """Every source face as an unselected core Face, and whether it is reached from above."""
    pairs = [extract(adapter, f, i, tolerance, False, chordal_tolerance)
             for i, f in enumerate(sources, 1)]
    return ([face for face, _ in pairs],
            [reaches_from_above(adapter, face, work) for face, work in pairs])


def faces_from_shape(adapter: PartAdapter, shape: Any,
                     selection: core_faces.Selection = "up",
                     tolerance: float = DEFAULT_TOLERANCE, where: str = "shape",
                     chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE) -> list[Face]:
    """Every face of ``shape`` as a core :class:`Face` (mm), in the shape's face order.

    ``selection``: "up" (every face a 3-axis tool reaches from above) or 1-based face numbers;
    the other faces come back with ``selected=False`` (check surfaces).  ``tolerance`` is the
    trim polylines' 3-D chord tolerance in mm, ``chordal_tolerance`` the machining's (mm),
    which sets how far a face's NURBS may be from OCCT's (``core.face_import``).  Errors
    (FaceError) name the face.
    """
    sources = checked_faces(adapter, shape, tolerance, where)
    chosen = core_faces.parse_selection(selection, len(sources), where)
    faces, reach = _faces_with_reach(adapter, sources, tolerance, chordal_tolerance)
    return core_faces.apply_selection(faces, reach, chosen, where)


def faces_and_reach(adapter: PartAdapter, shape: Any, tolerance: float = DEFAULT_TOLERANCE,
                    where: str = "shape", chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE,
                    ) -> tuple[list[Face], list[tuple[bool, str]]]:
    """Every face of ``shape`` (unselected, mm) and whether a 3-axis tool reaches it from
    above (:func:`reaches_from_above`): what :func:`faces_from_shape` selects from."""
    return _faces_with_reach(adapter, checked_faces(adapter, shape, tolerance, where),
                             tolerance, chordal_tolerance)


__all__ = [
    "NURBS_KINDS", "PartAdapter", "checked_faces", "extract", "faces_and_reach",
    "faces_from_shape", "loops", "measure", "nurbs_arrays", "occt_v", "reaches_from_above",
]
