# SPDX-License-Identifier: LGPL-2.1-or-later
"""Faces as FreeCAD holds them, into the core's plain NURBS faces (BSplineCAM.core.geometry.faces).

The reader is :mod:`BSplineCAM.core.geometry.part_reader`; this module is its adapter to FreeCAD's
Part API (:class:`FreeCADPart`) and reads part files (:func:`read_part`).

B-spline and Bézier faces give their poles, weights, knots and multiplicities directly; any
other surface (plane, cylinder, cone, sphere, torus, revolved, extruded, offset, trimmed) is
converted by OCCT (``Part.Face.toNurbs``, i.e. BRepBuilderAPI_NurbsConvert) and the result is
measured against OCCT's evaluation of the original surface (``Surface.parameter``, OCCT's
projection, then its evaluation at the projected parameters).  Periodic or unclamped knot
vectors are made clamped by OCCT's exact knot insertion (``Geom_BSplineSurface::Segment``),
which keeps the parameterisation; the trim's parameter curves (pcurves, or the 3-D edge
projected onto the surface where the face stores none) are discretised by
:func:`BSplineCAM.core.geometry.faces.densify_edge` within a 3-D chord tolerance.

A face is accepted when its NURBS, as the core evaluates it, lies within 1 % of the
machining's chordal tolerance from OCCT's original surface (``core.face_import``).

"up" (:func:`reaches_from_above`): OCCT's outward normals (``Face.normalAt``) at the sampled
points of the trimmed domain (a grid inside the trim and the trim's own points) go to the
core's rule (:func:`BSplineCAM.core.geometry.faces.reach`): a face whose normal points down only as far
as the model's own tolerance at the face (the largest tolerance of the face, its edges and
vertices) can tell -- the foot of a blend tangent to a wall -- is reached from above; an
undercut face and a vertical wall are not.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..core.errors import BSplineCAMError
from ..core.geometry import faces as core_faces
from ..core.geometry import part_reader
from ..core.geometry.face_import import DEFAULT_CHORDAL_TOLERANCE
from ..core.geometry.faces import DEFAULT_TOLERANCE, UP_TOLERANCE, Face, FaceError
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


# --------------------------------------------------------------------------- the adapter


def _xy(point) -> tuple[float, float]:
    return float(point.x), float(point.y)


class FreeCADPart:
    """:class:`BSplineCAM.core.geometry.part_reader.PartAdapter` in FreeCAD's Part API: Part.Shape,
    Part.Face, Part.Wire, Part.Edge and Part's surfaces."""

    # -- shape
    def faces(self, shape: Part.Shape) -> list[Part.Face]:
        return [] if shape.isNull() else shape.Faces

    def check(self, shape: Part.Shape, where: str) -> None:
        check_shape(shape, where)

    # -- face
    def surface(self, face: Part.Face):
        return face.Surface

    def nurbs_faces(self, face: Part.Face) -> list[Part.Face]:
        return face.toNurbs().Faces

    def reversed(self, face: Part.Face) -> bool:
        return face.Orientation == "Reversed"

    def diagonal(self, face: Part.Face) -> float:
        return float(face.BoundBox.DiagonalLength)

    def model_tolerance(self, face: Part.Face) -> float:
        return max([float(face.Tolerance)] + [float(e.Tolerance) for e in face.Edges]
                   + [float(v.Tolerance) for v in face.Vertexes])

    def wires(self, face: Part.Face) -> list[tuple[Part.Wire, bool]]:
        outer = face.OuterWire
        return [(wire, wire.isSame(outer)) for wire in face.Wires]

    def edges(self, face: Part.Face, wire: Part.Wire) -> list[Part.Edge]:
        return wire.OrderedEdges

    def vertex_tolerance(self, wire: Part.Wire) -> float:
        return max([v.Tolerance for v in wire.Vertexes] + [0.0])

    def degenerated(self, edge: Part.Edge) -> bool:
        return bool(edge.Degenerated)

    def pcurve(self, face: Part.Face, edge: Part.Edge, surface):
        found = face.curveOnSurface(edge)
        if found:
            curve, t0, t1 = found

            def pcurve(ts):
                return np.array([_xy(curve.value(float(t))) for t in ts], dtype=float)
        else:  # no pcurve stored: project the 3-D edge onto the surface
            t0, t1 = edge.ParameterRange

            def pcurve(ts):
                return np.array([surface.parameter(edge.valueAt(float(t))) for t in ts],
                                dtype=float)
        return pcurve, t0, t1

    def normals_z(self, face: Part.Face, u, v) -> list[float | None]:
        out: list[float | None] = []
        for a, b in zip(u, v):
            try:
                n = face.normalAt(float(a), float(b))
            except Exception:  # a pole or another point without a normal
                out.append(None)
                continue
            out.append(n.z / n.Length if n.Length > 0.5 else None)
        return out

    def original_distances(self, face: Part.Face, points: FloatArray, name: str):
        original = face.Surface
        for p in points:
            pt = FreeCAD.Vector(*map(float, p))
            a, b = original.parameter(pt)
            yield float((original.value(a, b) - pt).Length)

    # -- surface
    def kind(self, surface) -> str:
        return type(surface).__name__

    def points(self, surface, uv) -> FloatArray:
        return np.array([tuple(surface.value(float(a), float(b))) for a, b in uv], dtype=float)

    def degrees(self, surface) -> tuple[int, int]:
        return surface.UDegree, surface.VDegree

    def knots(self, surface):
        return (surface.getUKnots(), surface.getUMultiplicities(), surface.getVKnots(),
                surface.getVMultiplicities())

    def periods(self, surface) -> tuple[float, float]:
        return (surface.UPeriod() if surface.isUPeriodic() else 0.0,
                surface.VPeriod() if surface.isVPeriodic() else 0.0)

    def bounds(self, surface) -> tuple[float, float, float, float]:
        return surface.bounds()

    def segmented(self, surface, u0: float, u1: float, v0: float, v1: float):
        surface = surface.copy()
        surface.segment(u0, u1, v0, v1)
        return surface

    def poles(self, surface) -> tuple[FloatArray, FloatArray]:
        poles = np.array([[tuple(pt) for pt in row] for row in surface.getPoles()], dtype=float)
        return poles, np.array(surface.getWeights(), dtype=float)


#: The adapter :mod:`BSplineCAM.core.geometry.part_reader` reads FreeCAD's shapes with.
ADAPTER = FreeCADPart()


# --------------------------------------------------------------------------- the reader


def extract_face(source: Part.Face, index: int, tolerance: float = DEFAULT_TOLERANCE,
                 selected: bool = True,
                 chordal_tolerance: float | None = DEFAULT_CHORDAL_TOLERANCE) -> Face:
    """The core :class:`Face` of one Part.Face (``index`` 1-based in its shape), accepted for
    machining to ``chordal_tolerance`` (mm; None: measured, never refused)."""
    return part_reader.extract(ADAPTER, source, index, tolerance, selected,
                               chordal_tolerance)[0]


def measure(face: Face, source: Part.Face, work: Part.Face) -> float:
    """Max distance (mm) of the core NURBS from OCCT's surfaces at points of the face.

    At the same (u, v) against the B-spline OCCT holds (``work``); when ``source`` was
    converted, also the distance to its original surface (OCCT's projection, then its
    evaluation at the projected parameters).
    """
    return part_reader.measure(ADAPTER, face, source, work)


def model_tolerance(face: Part.Face) -> float:
    """The model's own tolerance at a face (mm): the largest of the face's, its edges' and its
    vertices' OCCT tolerances."""
    return ADAPTER.model_tolerance(face)


def reaches_from_above(face: Face, work: Part.Face) -> tuple[bool, str]:
    """Whether a 3-axis tool reaches the face from above, and why not (module docstring).

    ``work`` is the OCCT B-spline face the core face was taken from (OCCT's normals, which
    follow the face's orientation, and the model's tolerance there).
    """
    return part_reader.reaches_from_above(ADAPTER, face, work)


def faces_from_shape(shape: Part.Shape, selection: core_faces.Selection = "up",
                     tolerance: float = DEFAULT_TOLERANCE, where: str = "shape",
                     chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE) -> list[Face]:
    """Every face of ``shape`` as a core :class:`Face` (mm), in the shape's face order.

    ``selection``: "up" (every face a 3-axis tool reaches from above) or 1-based face numbers;
    the other faces come back with ``selected=False`` (check surfaces).  ``tolerance`` is the
    trim polylines' 3-D chord tolerance in mm, ``chordal_tolerance`` the machining's (mm),
    which sets how far a face's NURBS may be from OCCT's (``core.face_import``).  Errors
    (FaceError) name the face; the shape is checked by OCCT's BRepCheck (:func:`check_shape`).
    """
    return part_reader.faces_from_shape(ADAPTER, shape, selection, tolerance, where,
                                        chordal_tolerance)


def faces_and_reach(shape: Part.Shape, tolerance: float = DEFAULT_TOLERANCE,
                    where: str = "shape", chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE,
                    ) -> tuple[list[Face], list[tuple[bool, str]]]:
    """Every face of ``shape`` (unselected, mm) and whether a 3-axis tool reaches it from
    above (:func:`reaches_from_above`): what :func:`faces_from_shape` selects from, for
    callers that combine the faces of several shapes (the finishing op's ``Base``)."""
    return part_reader.faces_and_reach(ADAPTER, shape, tolerance, where, chordal_tolerance)


__all__ = [
    "ADAPTER", "PART_SUFFIXES", "UP_TOLERANCE", "FreeCADPart", "check_shape", "extract_face",
    "faces_and_reach", "faces_from_shape", "measure", "model_tolerance", "reaches_from_above",
    "read_part",
]
