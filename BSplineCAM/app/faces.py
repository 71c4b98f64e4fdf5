# SPDX-License-Identifier: LGPL-2.1-or-later
"""Faces as FreeCAD holds them, into the core's plain NURBS faces (BSplineCAM.core.faces).

B-spline and Bézier faces give their poles, weights, knots and multiplicities directly; any
other surface (plane, cylinder, cone, sphere, torus, revolved, extruded, offset, trimmed) is
converted by OCCT (``Part.Face.toNurbs``, i.e. BRepBuilderAPI_NurbsConvert) and the result is
measured against OCCT's evaluation of the original surface.  Periodic or unclamped knot
vectors are made clamped by OCCT's exact knot insertion (``Geom_BSplineSurface::Segment``),
which keeps the parameterisation; the trim's parameter curves (pcurves) are discretised by
:func:`BSplineCAM.core.faces.densify_edge` within a 3-D chord tolerance.

A face is accepted when its NURBS, as the core evaluates it, lies within 1 % of the
machining's chordal tolerance from OCCT's original surface (``core.face_import``).

"up" (:func:`reaches_from_above`): OCCT's outward normals at the sampled points of the trimmed
domain (a grid inside the trim and the trim's own points) go to the core's rule
(:func:`BSplineCAM.core.faces.reach`): a face whose normal points down only as far as the
model's own tolerance at the face (the largest tolerance of the face, its edges and vertices)
can tell -- the foot of a blend tangent to a wall -- is reached from above; an undercut face
and a vertical wall are not.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..core import faces as core_faces
from ..core.errors import BSplineCAMError
from ..core.face_import import DEFAULT_CHORDAL_TOLERANCE, checked_face, segment_box
from ..core.faces import DEFAULT_TOLERANCE, REACH_SAMPLES, UP_TOLERANCE, Face, FaceError
from ..core.typing import FloatArray
from .compat import ensure_freecad

FreeCAD = ensure_freecad()
import Part  # noqa: E402  (needs FreeCAD on sys.path first)

#: Part file types :func:`read_part` reads.
PART_SUFFIXES = (".step", ".stp", ".brep", ".brp", ".fcstd")


# --------------------------------------------------------------------------- reading


def read_part(path: str | os.PathLike) -> Part.Shape:
    """The solid(s) of a STEP, BREP or FreeCAD document as one Part.Shape.

    FCStd: the visible objects' shapes that hold solids.  Errors (FaceError) name the file:
    missing, unknown type, unreadable, no solid, or geometry OCCT reports invalid.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in PART_SUFFIXES:
        raise FaceError(f"{path}: unknown part type {suffix!r} (expected one of "
                        f"{', '.join(PART_SUFFIXES)})")
    if not path.is_file():
        raise FaceError(f"{path}: no such file")
    try:
        if suffix == ".fcstd":
            shape = _read_fcstd(path)
        else:
            shape = Part.Shape()
            shape.read(str(path))
    except BSplineCAMError:
        raise
    except Exception as exc:  # OCCT's reader errors come as Part.OCCError / RuntimeError
        raise FaceError(f"{path}: cannot read the part ({_occ_message(exc)})") from None
    if shape.isNull() or not shape.Solids:
        raise FaceError(f"{path}: holds no solid")
    check_shape(shape, str(path))
    return shape


def _read_fcstd(path: Path) -> Part.Shape:
    try:
        doc = FreeCAD.openDocument(str(path), True)  # hidden: no 3D view (FreeCAD >= 0.20)
    except TypeError:
        doc = FreeCAD.openDocument(str(path))
    try:
        shapes = []
        for obj in doc.Objects:
            shape = getattr(obj, "Shape", None)
            if shape is None or shape.isNull() or not shape.Solids or not _visible(obj):
                continue
            shapes.append(shape.copy())
        if not shapes:
            raise FaceError(f"{path}: no visible object holds a solid")
        return shapes[0] if len(shapes) == 1 else Part.makeCompound(shapes)
    finally:
        FreeCAD.closeDocument(doc.Name)


def _visible(obj) -> bool:
    """Visibility as saved in the document (headless FreeCAD has no view providers)."""
    try:
        return bool(obj.Visibility)
    except AttributeError:
        return True


def check_shape(shape: Part.Shape, where: str = "shape") -> None:
    """FaceError naming ``where`` if OCCT's checker (BRepCheck) finds the shape invalid."""
    if shape.isValid():
        return
    findings = []
    bad = [f"Face{i}" for i, f in enumerate(shape.Faces, start=1) if not f.isValid()]
    if bad:
        findings.append(f"invalid faces {', '.join(bad[:10])}{' ...' if len(bad) > 10 else ''}")
    if any(not shell.isClosed() for shell in shape.Shells) and shape.Solids:
        findings.append("a solid whose shell is not closed")
    try:
        shape.check(True)
    except Exception as exc:  # Part.OCCError with BRepCheck's findings
        text = " ".join(w for w in str(exc).replace("No error", " ").split())
        if text:
            findings.append(text[:200])
    detail = "; ".join(findings) or "OCCT's BRepCheck reports the shape invalid"
    raise FaceError(f"{where}: broken geometry: {detail}")


def _occ_message(exc: BaseException) -> str:
    """The message of an OCCT/FreeCAD exception (0.20 passes a dict of fields as its text)."""
    arg = exc.args[0] if exc.args else exc
    if isinstance(arg, dict):
        return str(arg.get("sErrMsg") or arg.get("swhat") or type(exc).__name__)
    return " ".join(str(arg).split()) or type(exc).__name__


# --------------------------------------------------------------------------- one face


def _flat(knots: Sequence[float], mults: Sequence[int]) -> FloatArray:
    return np.repeat(np.asarray(knots, dtype=float), np.asarray(mults, dtype=int))


def _clamped(surface: Part.BSplineSurface) -> bool:
    return (not surface.isUPeriodic() and not surface.isVPeriodic()
            and surface.getUMultiplicities()[0] == surface.UDegree + 1
            and surface.getUMultiplicities()[-1] == surface.UDegree + 1
            and surface.getVMultiplicities()[0] == surface.VDegree + 1
            and surface.getVMultiplicities()[-1] == surface.VDegree + 1)


def _nurbs_arrays(surface, uv_box: tuple[float, float, float, float], name: str):
    """Poles (n, m, 3), weights (n, m), full clamped knot vectors and degrees of a Part
    B-spline or Bézier surface.  A periodic direction is cut to the trim's range ``uv_box``
    (exact knot insertion, same parameters); an unclamped one is clamped to its bounds."""
    shift = (0.0, 0.0)
    if isinstance(surface, Part.BezierSurface):
        p, q = surface.UDegree, surface.VDegree
        knots_u = np.array([0.0] * (p + 1) + [1.0] * (p + 1))
        knots_v = np.array([0.0] * (q + 1) + [1.0] * (q + 1))
    else:
        if not _clamped(surface):
            surface = surface.copy()
            periods = (surface.UPeriod() if surface.isUPeriodic() else 0.0,
                       surface.VPeriod() if surface.isVPeriodic() else 0.0)
            u0, u1, v0, v1 = segment_box(surface.bounds(), uv_box, periods, name)
            surface.segment(u0, u1, v0, v1)
            shift = core_faces.period_shift(surface.bounds(), (u0, v0), periods)
            if not _clamped(surface):
                raise FaceError(f"{name}: OCCT could not clamp the surface's knot vectors")
        p, q = surface.UDegree, surface.VDegree
        knots_u = _flat(surface.getUKnots(), surface.getUMultiplicities())
        knots_v = _flat(surface.getVKnots(), surface.getVMultiplicities())
    poles = np.array([[tuple(pt) for pt in row] for row in surface.getPoles()], dtype=float)
    weights = np.array(surface.getWeights(), dtype=float)
    # Segment may land a whole period away from the trim: translate the knots back.
    return {"poles": poles, "weights": weights, "knots_u": knots_u - shift[0],
            "knots_v": knots_v - shift[1], "degree_u": int(p), "degree_v": int(q)}


def _xy(point) -> tuple[float, float]:
    return float(point.x), float(point.y)


def _edge_polyline(face: Part.Face, edge, surface, tolerance: float, name: str) -> FloatArray:
    found = face.curveOnSurface(edge)
    if found:
        curve, t0, t1 = found

        def pcurve(ts):
            return np.array([_xy(curve.value(float(t))) for t in ts], dtype=float)
    else:  # no pcurve stored: project the 3-D edge onto the surface
        t0, t1 = edge.ParameterRange

        def pcurve(ts):
            return np.array([surface.parameter(edge.valueAt(float(t))) for t in ts], dtype=float)

    def point(uv):
        return np.array([tuple(surface.value(float(a), float(b))) for a, b in uv], dtype=float)

    if edge.Degenerated:  # a pole: a straight parameter segment, one 3-D point
        return pcurve(np.array([t0, t1]))
    return core_faces.densify_edge(pcurve, point, t0, t1, tolerance, name=name)


def _loops(face: Part.Face, tolerance: float, name: str) -> tuple[FloatArray, list[FloatArray]]:
    surface = face.Surface
    outer_wire = face.OuterWire
    size = max(face.BoundBox.DiagonalLength, 1e-300)

    def gap_mm(a: FloatArray, b: FloatArray) -> float:
        return float((surface.value(*map(float, a)) - surface.value(*map(float, b))).Length)

    loops, outer = [], None
    for n, wire in enumerate(face.Wires, start=1):
        is_outer = wire.isSame(outer_wire)
        which = "outer wire" if is_outer else f"wire {n}"
        pieces = [_edge_polyline(face, e, surface, tolerance, name) for e in wire.OrderedEdges]
        # edges meet at a vertex within its tolerance (OCCT leaves the parameter curves of
        # fillets meeting at a corner up to ~0.01 mm apart): measured on the surface, in mm
        gap = max([v.Tolerance for v in wire.Vertexes] + [0.0]) + 1e-7 * size
        loop = core_faces.join_edges(pieces, name, which, gap, gap_mm, "on the surface (mm)")
        if is_outer:
            outer = loop
        else:
            loops.append(loop)
    if outer is None:
        raise FaceError(f"{name}: has no outer wire")
    return outer, loops


def _occt_v(face: Face, v):
    if not face.flipped_v:
        return v
    k = np.asarray(face.surface.knots_v, dtype=float)
    return k[0] + k[-1] - v


def extract_face(source: Part.Face, index: int, tolerance: float = DEFAULT_TOLERANCE,
                 selected: bool = True,
                 chordal_tolerance: float | None = DEFAULT_CHORDAL_TOLERANCE) -> Face:
    """The core :class:`Face` of one Part.Face (``index`` 1-based in its shape), accepted for
    machining to ``chordal_tolerance`` (mm; None: measured, never refused)."""
    return _extract(source, index, tolerance, selected, chordal_tolerance)[0]


def _extract(source: Part.Face, index: int, tolerance: float, selected: bool,
             chordal_tolerance: float | None = DEFAULT_CHORDAL_TOLERANCE):
    """(Face, OCCT's B-spline face it was taken from)."""
    name = f"Face{index}"
    kind = type(source.Surface).__name__
    if isinstance(source.Surface, (Part.BSplineSurface, Part.BezierSurface)):
        work = source
    else:
        try:
            converted = source.toNurbs().Faces
        except Exception as exc:  # Part.OCCError
            raise FaceError(f"{name} ({kind}): OCCT's NURBS conversion failed ({exc})") from None
        if len(converted) != 1 or not isinstance(converted[0].Surface, Part.BSplineSurface):
            raise FaceError(f"{name} ({kind}): OCCT's NURBS conversion gave no B-spline face")
        work = converted[0]
    outer, holes = _loops(work, tolerance, name)
    box = np.concatenate([outer, *holes])
    uv_box = (float(box[:, 0].min()), float(box[:, 0].max()),
              float(box[:, 1].min()), float(box[:, 1].max()))
    data = _nurbs_arrays(work.Surface, uv_box, name)
    face = checked_face(data, outer, holes, work.Orientation == "Reversed",
                        lambda face: measure(face, source, work),
                        max(source.BoundBox.DiagonalLength, 1e-300), index=index, name=name,
                        kind=kind, selected=selected, tolerance=tolerance,
                        chordal_tolerance=chordal_tolerance)
    return face, work


def measure(face: Face, source: Part.Face, work: Part.Face) -> float:
    """Max distance (mm) of the core NURBS from OCCT's surfaces at points of the face.

    At the same (u, v) against the B-spline OCCT holds (``work``); when ``source`` was
    converted, also the distance to its original surface (OCCT's projection, then its
    evaluation at the projected parameters).
    """
    uv = core_faces.sample_points(face)
    ours = np.asarray(face.surface.evaluate(uv[:, 0], uv[:, 1]), dtype=float)
    vo = _occt_v(face, uv[:, 1])
    theirs = np.array([tuple(work.Surface.value(float(a), float(b)))
                       for a, b in zip(uv[:, 0], vo)])
    deviation = float(np.linalg.norm(ours - theirs, axis=1).max())
    if work is not source:
        original = source.Surface
        for p in ours:
            pt = FreeCAD.Vector(*map(float, p))
            a, b = original.parameter(pt)
            deviation = max(deviation, float((original.value(a, b) - pt).Length))
    return deviation


# --------------------------------------------------------------------------- "up"


def model_tolerance(face: Part.Face) -> float:
    """The model's own tolerance at a face (mm): the largest of the face's, its edges' and its
    vertices' OCCT tolerances."""
    return max([float(face.Tolerance)] + [float(e.Tolerance) for e in face.Edges]
               + [float(v.Tolerance) for v in face.Vertexes])


def reaches_from_above(face: Face, work: Part.Face) -> tuple[bool, str]:
    """Whether a 3-axis tool reaches the face from above, and why not (module docstring).

    ``work`` is the OCCT B-spline face the core face was taken from (OCCT's normals, which
    follow the face's orientation, and the model's tolerance there).
    """
    uv = core_faces.sample_points(face, REACH_SAMPLES)
    vo = _occt_v(face, uv[:, 1])
    nz, keep = [], []
    for k, (a, b) in enumerate(zip(uv[:, 0], vo)):
        try:
            n = work.normalAt(float(a), float(b))
        except Exception:  # a pole or another point without a normal
            continue
        if n.Length > 0.5:
            nz.append(n.z / n.Length)
            keep.append(k)
    points = np.asarray(face.surface.evaluate(uv[keep, 0], uv[keep, 1]), dtype=float)
    spacing = float(np.linalg.norm(np.ptp(points, axis=0))) / REACH_SAMPLES if keep else 0.0
    return core_faces.reach(nz, points[:, 2] if keep else [], model_tolerance(work), spacing)


# --------------------------------------------------------------------------- a shape


def faces_from_shape(shape: Part.Shape, selection: core_faces.Selection = "up",
                     tolerance: float = DEFAULT_TOLERANCE, where: str = "shape",
                     chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE) -> list[Face]:
    """Every face of ``shape`` as a core :class:`Face` (mm), in the shape's face order.

    ``selection``: "up" (every face a 3-axis tool reaches from above) or 1-based face numbers;
    the other faces come back with ``selected=False`` (check surfaces).  ``tolerance`` is the
    trim polylines' 3-D chord tolerance in mm, ``chordal_tolerance`` the machining's (mm),
    which sets how far a face's NURBS may be from OCCT's (``core.face_import``).  Errors
    (FaceError) name the face.
    """
    sources = _checked_faces(shape, tolerance, where)
    chosen = core_faces.parse_selection(selection, len(sources), where)
    faces, reach = _faces_with_reach(sources, tolerance, chordal_tolerance)
    return core_faces.apply_selection(faces, reach, chosen, where)


def faces_and_reach(shape: Part.Shape, tolerance: float = DEFAULT_TOLERANCE,
                    where: str = "shape", chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE,
                    ) -> tuple[list[Face], list[tuple[bool, str]]]:
    """Every face of ``shape`` (unselected, mm) and whether a 3-axis tool reaches it from
    above (:func:`reaches_from_above`): what :func:`faces_from_shape` selects from, for
    callers that combine the faces of several shapes (the finishing op's ``Base``)."""
    return _faces_with_reach(_checked_faces(shape, tolerance, where), tolerance,
                             chordal_tolerance)


def _checked_faces(shape: Part.Shape, tolerance: float, where: str) -> list[Part.Face]:
    """The faces of ``shape`` once the trim ``tolerance`` (mm) and the shape are found fit
    (FaceError naming ``where`` otherwise), before any face is extracted."""
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise FaceError(f"{where}: trim tolerance must be a positive length in mm, "
                        f"got {tolerance!r}")
    if shape.isNull() or not shape.Faces:
        raise FaceError(f"{where}: has no faces")
    check_shape(shape, where)
    return shape.Faces


def _faces_with_reach(sources: list[Part.Face], tolerance: float,
                      chordal_tolerance: float) -> tuple[list[Face], list[tuple[bool, str]]]:
    """Every source face as an unselected core Face, and whether it is reached from above."""
    pairs = [_extract(f, i, tolerance, False, chordal_tolerance)
             for i, f in enumerate(sources, 1)]
    return [face for face, _ in pairs], [reaches_from_above(face, work) for face, work in pairs]


__all__ = [
    "PART_SUFFIXES", "UP_TOLERANCE", "check_shape", "extract_face", "faces_and_reach",
    "faces_from_shape", "measure", "model_tolerance", "reaches_from_above", "read_part",
]
