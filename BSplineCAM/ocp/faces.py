# SPDX-License-Identifier: LGPL-2.1-or-later
"""The face extraction of :mod:`BSplineCAM.app.faces`, in cadquery's OCCT (OCP).

Run on the same STEP part, the two OCCT builds must give the same NURBS faces (poles, knots,
weights, trims): one confirms the other.  The reader is :mod:`BSplineCAM.core.geometry.part_reader`;
this module is its adapter to OCP (:class:`OCPPart`) and reads STEP and BREP files
(:func:`read_part`).  B-spline and Bézier faces are read directly, any other surface through
BRepBuilderAPI_NurbsConvert measured against the original (GeomAPI_ProjectPointOnSurf),
periodic or unclamped knots clamped by Geom_BSplineSurface::Segment, trims from the pcurves
(BRepAdaptor_Curve2d, edges in BRepTools_WireExplorer's order), "up" from BRepGProp_Face's
oriented normals.  Shapes handed to :func:`faces_from_shape` are not checked by BRepCheck
(:func:`read_part` checks the files it reads).  Import only in a Python that has cadquery
(the project venv).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from OCP.Bnd import Bnd_Box
from OCP.BRep import BRep_Builder, BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve2d
from OCP.BRepBndLib import BRepBndLib
from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp_Face
from OCP.BRepTools import BRepTools, BRepTools_WireExplorer
from OCP.Geom import Geom_BezierSurface, Geom_BSplineSurface
from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
from OCP.gp import gp_Pnt, gp_Vec
from OCP.IFSelect import IFSelect_RetDone
from OCP.STEPControl import STEPControl_Reader
from OCP.TopAbs import (
    TopAbs_EDGE,
    TopAbs_FACE,
    TopAbs_REVERSED,
    TopAbs_SOLID,
    TopAbs_VERTEX,
    TopAbs_WIRE,
)
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Shape
from OCP.TopTools import TopTools_IndexedMapOfShape

from ..core.geometry import faces as core_faces
from ..core.geometry import part_reader
from ..core.geometry.face_import import DEFAULT_CHORDAL_TOLERANCE
from ..core.geometry.faces import DEFAULT_TOLERANCE, Face, FaceError
from ..core.typing import FloatArray


def read_part(path: str | os.PathLike) -> TopoDS_Shape:
    """The shape of a STEP or BREP file; FaceError naming the file if unreadable, without a
    solid, or invalid by BRepCheck."""
    path = Path(path)
    suffix = path.suffix.lower()
    if not path.is_file():
        raise FaceError(f"{path}: no such file")
    if suffix in (".step", ".stp"):
        reader = STEPControl_Reader()
        if reader.ReadFile(str(path)) != IFSelect_RetDone:
            raise FaceError(f"{path}: cannot read the STEP file")
        reader.TransferRoots()
        shape = reader.OneShape()
    elif suffix in (".brep", ".brp"):
        shape = TopoDS_Shape()
        if not BRepTools.Read_s(shape, str(path), BRep_Builder()):
            raise FaceError(f"{path}: cannot read the BREP file")
    else:
        raise FaceError(f"{path}: unknown part type {suffix!r} (expected .step, .stp, .brep)")
    if shape.IsNull() or not TopExp_Explorer(shape, TopAbs_SOLID).More():
        raise FaceError(f"{path}: holds no solid")
    if not BRepCheck_Analyzer(shape).IsValid():
        raise FaceError(f"{path}: broken geometry: BRepCheck reports it invalid")
    return shape


def shape_faces(shape: TopoDS_Shape) -> list:
    """The faces in FreeCAD's order (``Shape.Faces``: TopExp::MapShapes, first occurrence)."""
    fmap = TopTools_IndexedMapOfShape()
    TopExp.MapShapes_s(shape, TopAbs_FACE, fmap)
    return [TopoDS.Face_s(fmap.FindKey(i)) for i in range(1, fmap.Extent() + 1)]


#: OCCT's surface class names as FreeCAD's Part module calls them (``Face.source``).
FREECAD_NAMES = {
    "Geom_Plane": "Plane", "Geom_CylindricalSurface": "Cylinder", "Geom_ConicalSurface": "Cone",
    "Geom_SphericalSurface": "Sphere", "Geom_ToroidalSurface": "Toroid",
    "Geom_SurfaceOfRevolution": "SurfaceOfRevolution",
    "Geom_SurfaceOfLinearExtrusion": "SurfaceOfExtrusion", "Geom_OffsetSurface": "OffsetSurface",
    "Geom_BSplineSurface": "BSplineSurface", "Geom_BezierSurface": "BezierSurface",
    "Geom_RectangularTrimmedSurface": "RectangularTrimmedSurface",
}


def _bspline(surface):
    return Geom_BSplineSurface.DownCast(surface) if hasattr(
        Geom_BSplineSurface, "DownCast") else surface


def _bezier(surface):
    return Geom_BezierSurface.DownCast(surface) if hasattr(
        Geom_BezierSurface, "DownCast") else surface


def _xyz(p) -> tuple[float, float, float]:
    return p.X(), p.Y(), p.Z()


def _diagonal(shape) -> float:
    """The diagonal (mm) of the shape's bounding box (BRepBndLib, without triangulation)."""
    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)
    x0, y0, z0, x1, y1, z1 = box.Get()
    return max(math.dist((x0, y0, z0), (x1, y1, z1)), 1e-300)


def _tolerances(shape, kind, cast):
    """BRep_Tool's tolerances of the sub-shapes of type ``kind`` of ``shape``."""
    explorer = TopExp_Explorer(shape, kind)
    while explorer.More():
        yield float(BRep_Tool.Tolerance_s(cast(explorer.Current())))
        explorer.Next()


class OCPPart:
    """:class:`BSplineCAM.core.geometry.part_reader.PartAdapter` in cadquery's OCP: TopoDS shapes and
    Geom surfaces."""

    # -- shape
    def faces(self, shape: TopoDS_Shape) -> list:
        return shape_faces(shape)

    def check(self, shape: TopoDS_Shape, where: str) -> None:
        """Nothing: the shapes are taken as given (read_part checks files by BRepCheck)."""

    # -- face
    def surface(self, face):
        return BRep_Tool.Surface_s(face)

    def nurbs_faces(self, face) -> list:
        return shape_faces(BRepBuilderAPI_NurbsConvert(face, True).Shape())

    def reversed(self, face) -> bool:
        return face.Orientation() == TopAbs_REVERSED

    def diagonal(self, face) -> float:
        return _diagonal(face)

    def model_tolerance(self, face) -> float:
        out = float(BRep_Tool.Tolerance_s(face))
        for tol in _tolerances(face, TopAbs_EDGE, TopoDS.Edge_s):
            out = max(out, tol)
        for tol in _tolerances(face, TopAbs_VERTEX, TopoDS.Vertex_s):
            out = max(out, tol)
        return out

    def wires(self, face) -> list:
        outer = BRepTools.OuterWire_s(face)
        found, explorer = [], TopExp_Explorer(face, TopAbs_WIRE)
        while explorer.More():
            wire = TopoDS.Wire_s(explorer.Current())
            found.append((wire, wire.IsSame(outer)))
            explorer.Next()
        return found

    def edges(self, face, wire) -> list:
        found, explorer = [], BRepTools_WireExplorer(wire, face)
        while explorer.More():
            found.append(explorer.Current())
            explorer.Next()
        return found

    def vertex_tolerance(self, wire) -> float:
        return max([0.0, *_tolerances(wire, TopAbs_VERTEX, TopoDS.Vertex_s)])

    def degenerated(self, edge) -> bool:
        return bool(BRep_Tool.Degenerated_s(edge))

    def pcurve(self, face, edge, surface):
        curve = BRepAdaptor_Curve2d(edge, face)

        def pcurve(ts):
            return np.array([(curve.Value(float(t)).X(), curve.Value(float(t)).Y())
                             for t in ts])

        return pcurve, curve.FirstParameter(), curve.LastParameter()

    def normals_z(self, face, u, v) -> list[float | None]:
        props, out = BRepGProp_Face(face), []
        for a, b in zip(u, v):
            p, n = gp_Pnt(), gp_Vec()
            props.Normal(float(a), float(b), p, n)
            length = n.Magnitude()
            out.append(n.Z() / length if length > 1e-12 else None)
        return out

    def original_distances(self, face, points: FloatArray, name: str):
        original = BRep_Tool.Surface_s(face)
        for p in points:
            proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, p)), original)
            if proj.NbPoints() == 0:
                raise FaceError(f"{name}: a point of its NURBS does not project onto the "
                                "original surface")
            yield float(proj.LowerDistance())

    # -- surface
    def kind(self, surface) -> str:
        name = surface.DynamicType().Name()
        return FREECAD_NAMES.get(name, name)

    def points(self, surface, uv) -> FloatArray:
        return np.array([_xyz(surface.Value(float(a), float(b))) for a, b in uv], dtype=float)

    def degrees(self, surface) -> tuple[int, int]:
        s = _bezier(surface) if self.kind(surface) == "BezierSurface" else _bspline(surface)
        return s.UDegree(), s.VDegree()

    def knots(self, surface):
        s = _bspline(surface)
        nu, nv = s.NbUKnots(), s.NbVKnots()
        return ([s.UKnot(i) for i in range(1, nu + 1)],
                [s.UMultiplicity(i) for i in range(1, nu + 1)],
                [s.VKnot(i) for i in range(1, nv + 1)],
                [s.VMultiplicity(i) for i in range(1, nv + 1)])

    def periods(self, surface) -> tuple[float, float]:
        s = _bspline(surface)
        return (s.UPeriod() if s.IsUPeriodic() else 0.0,
                s.VPeriod() if s.IsVPeriodic() else 0.0)

    def bounds(self, surface) -> tuple[float, float, float, float]:
        return _bspline(surface).Bounds()

    def segmented(self, surface, u0: float, u1: float, v0: float, v1: float):
        s = _bspline(_bspline(surface).Copy())
        s.Segment(u0, u1, v0, v1)
        return s

    def poles(self, surface) -> tuple[FloatArray, FloatArray]:
        s = _bezier(surface) if self.kind(surface) == "BezierSurface" else _bspline(surface)
        n, m = s.NbUPoles(), s.NbVPoles()
        poles = np.array([[_xyz(s.Pole(i, j)) for j in range(1, m + 1)]
                          for i in range(1, n + 1)])
        weights = np.array([[s.Weight(i, j) for j in range(1, m + 1)] for i in range(1, n + 1)])
        return poles, weights


#: The adapter :mod:`BSplineCAM.core.geometry.part_reader` reads OCP's shapes with.
ADAPTER = OCPPart()


def measure(face: Face, source, work) -> float:
    """Max distance (mm) of the core NURBS from OCCT's B-spline at the same (u, v) and, for a
    converted face, from the original surface (GeomAPI_ProjectPointOnSurf)."""
    return part_reader.measure(ADAPTER, face, source, work)


def model_tolerance(face) -> float:
    """The model's own tolerance at a face (mm): the largest of the face's, its edges' and its
    vertices' OCCT tolerances (as :func:`BSplineCAM.app.faces.model_tolerance`)."""
    return ADAPTER.model_tolerance(face)


def reaches_from_above(face: Face, work) -> tuple[bool, str]:
    """As :func:`BSplineCAM.app.faces.reaches_from_above`, with BRepGProp_Face's normals."""
    return part_reader.reaches_from_above(ADAPTER, face, work)


def faces_from_shape(shape, selection: core_faces.Selection = "up",
                     tolerance: float = DEFAULT_TOLERANCE, where: str = "shape",
                     chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE) -> list[Face]:
    """Every face of ``shape`` as a core Face, selected as in the FreeCAD module."""
    return part_reader.faces_from_shape(ADAPTER, shape, selection, tolerance, where,
                                        chordal_tolerance)


__all__ = ["ADAPTER", "FREECAD_NAMES", "OCPPart", "faces_from_shape", "measure",
           "model_tolerance", "reaches_from_above", "read_part", "shape_faces"]
