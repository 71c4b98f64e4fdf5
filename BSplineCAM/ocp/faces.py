# SPDX-License-Identifier: LGPL-2.1-or-later
"""The same face extraction as :mod:`BSplineCAM.app.faces`, in cadquery's OCCT (OCP).

Run on the same STEP part, the two OCCT builds must give the same NURBS faces (poles, knots,
weights, trims): one confirms the other.  The steps mirror the FreeCAD module: B-spline and
Bézier faces directly, any other surface through BRepBuilderAPI_NurbsConvert measured against
the original (GeomAPI_ProjectPointOnSurf), periodic or unclamped knots clamped by
Geom_BSplineSurface::Segment, trims from the pcurves (BRepAdaptor_Curve2d) densified by
:func:`BSplineCAM.core.faces.densify_edge`, "up" from BRepGProp_Face's oriented normals.
Import only in a Python that has cadquery (the project venv).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from OCP.BRep import BRep_Tool
from OCP.BRepAdaptor import BRepAdaptor_Curve2d
from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert
from OCP.BRepCheck import BRepCheck_Analyzer
from OCP.BRepGProp import BRepGProp_Face
from OCP.BRepTools import BRepTools, BRepTools_WireExplorer
from OCP.Geom import Geom_BezierSurface, Geom_BSplineSurface
from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
from OCP.gp import gp_Pnt, gp_Vec
from OCP.IFSelect import IFSelect_RetDone
from OCP.STEPControl import STEPControl_Reader
from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED, TopAbs_SOLID, TopAbs_WIRE
from OCP.TopExp import TopExp, TopExp_Explorer
from OCP.TopoDS import TopoDS, TopoDS_Shape
from OCP.TopTools import TopTools_IndexedMapOfShape

from ..core import faces as core_faces
from ..core.face_import import checked_face, segment_box
from ..core.faces import DEFAULT_TOLERANCE, Face, FaceError

#: Same thresholds as the FreeCAD side.


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
        from OCP.BRep import BRep_Builder

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


def _bspline(surface):
    return Geom_BSplineSurface.DownCast(surface) if hasattr(
        Geom_BSplineSurface, "DownCast") else surface


#: OCCT's surface class names as FreeCAD's Part module calls them (``Face.source``).
FREECAD_NAMES = {
    "Geom_Plane": "Plane", "Geom_CylindricalSurface": "Cylinder", "Geom_ConicalSurface": "Cone",
    "Geom_SphericalSurface": "Sphere", "Geom_ToroidalSurface": "Toroid",
    "Geom_SurfaceOfRevolution": "SurfaceOfRevolution",
    "Geom_SurfaceOfLinearExtrusion": "SurfaceOfExtrusion", "Geom_OffsetSurface": "OffsetSurface",
    "Geom_BSplineSurface": "BSplineSurface", "Geom_BezierSurface": "BezierSurface",
    "Geom_RectangularTrimmedSurface": "RectangularTrimmedSurface",
}


def _is(surface, cls) -> bool:
    return surface.DynamicType().Name() == cls.get_type_name_s()


def _clamped(s) -> bool:
    return (not s.IsUPeriodic() and not s.IsVPeriodic()
            and s.UMultiplicity(1) == s.UDegree() + 1
            and s.UMultiplicity(s.NbUKnots()) == s.UDegree() + 1
            and s.VMultiplicity(1) == s.VDegree() + 1
            and s.VMultiplicity(s.NbVKnots()) == s.VDegree() + 1)


def _nurbs_arrays(surface, uv_box, name: str):
    if _is(surface, Geom_BezierSurface):
        bez = Geom_BezierSurface.DownCast(surface) if hasattr(
            Geom_BezierSurface, "DownCast") else surface
        p, q = bez.UDegree(), bez.VDegree()
        n, m = bez.NbUPoles(), bez.NbVPoles()
        poles = np.array([[_xyz(bez.Pole(i, j)) for j in range(1, m + 1)]
                          for i in range(1, n + 1)])
        weights = np.array([[bez.Weight(i, j) for j in range(1, m + 1)] for i in range(1, n + 1)])
        return {"poles": poles, "weights": weights,
                "knots_u": np.array([0.0] * (p + 1) + [1.0] * (p + 1)),
                "knots_v": np.array([0.0] * (q + 1) + [1.0] * (q + 1)),
                "degree_u": p, "degree_v": q}
    s = _bspline(surface)
    shift = (0.0, 0.0)
    if not _clamped(s):
        s = _bspline(s.Copy())
        periods = (s.UPeriod() if s.IsUPeriodic() else 0.0,
                   s.VPeriod() if s.IsVPeriodic() else 0.0)
        u0, u1, v0, v1 = segment_box(s.Bounds(), uv_box, periods, name)
        s.Segment(u0, u1, v0, v1)
        shift = core_faces.period_shift(s.Bounds(), (u0, v0), periods)
        if not _clamped(s):
            raise FaceError(f"{name}: OCCT could not clamp the surface's knot vectors")
    n, m = s.NbUPoles(), s.NbVPoles()
    poles = np.array([[_xyz(s.Pole(i, j)) for j in range(1, m + 1)] for i in range(1, n + 1)])
    weights = np.array([[s.Weight(i, j) for j in range(1, m + 1)] for i in range(1, n + 1)])
    knots_u = np.repeat([s.UKnot(i) for i in range(1, s.NbUKnots() + 1)],
                        [s.UMultiplicity(i) for i in range(1, s.NbUKnots() + 1)])
    knots_v = np.repeat([s.VKnot(i) for i in range(1, s.NbVKnots() + 1)],
                        [s.VMultiplicity(i) for i in range(1, s.NbVKnots() + 1)])
    # Segment may land a whole period away from the trim: translate the knots back.
    return {"poles": poles, "weights": weights, "knots_u": knots_u.astype(float) - shift[0],
            "knots_v": knots_v.astype(float) - shift[1], "degree_u": s.UDegree(),
            "degree_v": s.VDegree()}


def _xyz(p) -> tuple[float, float, float]:
    return p.X(), p.Y(), p.Z()


def _loops(face, tolerance: float, name: str):
    surface = BRep_Tool.Surface_s(face)
    outer_wire = BRepTools.OuterWire_s(face)

    def point(uv):
        return np.array([_xyz(surface.Value(float(a), float(b))) for a, b in uv])

    def gap_mm(a, b) -> float:
        """Distance on the surface of two parameter points (mm), as app/faces.py measures."""
        return float(np.linalg.norm(point([a])[0] - point([b])[0]))

    from OCP.TopAbs import TopAbs_VERTEX

    def vertex_tolerance(wire) -> float:
        tol, vertices = 0.0, TopExp_Explorer(wire, TopAbs_VERTEX)
        while vertices.More():
            tol = max(tol, BRep_Tool.Tolerance_s(TopoDS.Vertex_s(vertices.Current())))
            vertices.Next()
        return tol

    size = _diagonal(face)

    outer, holes = None, []
    explorer = TopExp_Explorer(face, TopAbs_WIRE)
    n = 0
    while explorer.More():
        n += 1
        wire = TopoDS.Wire_s(explorer.Current())
        is_outer = wire.IsSame(outer_wire)
        pieces = []
        edges = BRepTools_WireExplorer(wire, face)
        while edges.More():
            edge = edges.Current()
            curve = BRepAdaptor_Curve2d(edge, face)

            def pcurve(ts, curve=curve):
                return np.array([(curve.Value(float(t)).X(), curve.Value(float(t)).Y())
                                 for t in ts])

            t0, t1 = curve.FirstParameter(), curve.LastParameter()
            if BRep_Tool.Degenerated_s(edge):
                pieces.append(pcurve([t0, t1]))
            else:
                pieces.append(core_faces.densify_edge(pcurve, point, t0, t1, tolerance,
                                                      name=name))
            edges.Next()
        # edges meet at a vertex within its tolerance: measured on the surface, in mm
        gap = vertex_tolerance(wire) + 1e-7 * size
        loop = core_faces.join_edges(pieces, name, "outer wire" if is_outer else f"wire {n}",
                                     gap, gap_mm, "on the surface (mm)")
        if is_outer:
            outer = loop
        else:
            holes.append(loop)
        explorer.Next()
    if outer is None:
        raise FaceError(f"{name}: has no outer wire")
    return outer, holes


def _extract(source, index: int, tolerance: float, selected: bool):
    name = f"Face{index}"
    original = BRep_Tool.Surface_s(source)
    kind = original.DynamicType().Name()
    kind = FREECAD_NAMES.get(kind, kind)
    if _is(original, Geom_BSplineSurface) or _is(original, Geom_BezierSurface):
        work = source
    else:
        try:
            converter = BRepBuilderAPI_NurbsConvert(source, True)
            work = shape_faces(converter.Shape())
        except Exception as exc:  # Standard_Failure
            raise FaceError(f"{name} ({kind}): OCCT's NURBS conversion failed ({exc})") from None
        if len(work) != 1 or not _is(BRep_Tool.Surface_s(work[0]), Geom_BSplineSurface):
            raise FaceError(f"{name} ({kind}): OCCT's NURBS conversion gave no B-spline face")
        work = work[0]
    outer, holes = _loops(work, tolerance, name)
    box = np.concatenate([outer, *holes])
    uv_box = (box[:, 0].min(), box[:, 0].max(), box[:, 1].min(), box[:, 1].max())
    data = _nurbs_arrays(BRep_Tool.Surface_s(work), uv_box, name)
    face = checked_face(data, outer, holes, work.Orientation() == TopAbs_REVERSED,
                        lambda face: measure(face, source, work), _diagonal(source),
                        index=index, name=name, kind=kind, selected=selected,
                        tolerance=tolerance)
    return face, work


def _diagonal(shape) -> float:
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.Add_s(shape, box, False)
    x0, y0, z0, x1, y1, z1 = box.Get()
    return max(math.dist((x0, y0, z0), (x1, y1, z1)), 1e-300)


def _occt_v(face: Face, v):
    if not face.flipped_v:
        return v
    k = np.asarray(face.surface.knots_v, dtype=float)
    return k[0] + k[-1] - v


def measure(face: Face, source, work) -> float:
    """Max distance (mm) of the core NURBS from OCCT's B-spline at the same (u, v) and, for a
    converted face, from the original surface (GeomAPI_ProjectPointOnSurf)."""
    uv = core_faces.sample_points(face)
    ours = np.asarray(face.surface.evaluate(uv[:, 0], uv[:, 1]), dtype=float)
    surf = BRep_Tool.Surface_s(work)
    vo = _occt_v(face, uv[:, 1])
    theirs = np.array([_xyz(surf.Value(float(a), float(b))) for a, b in zip(uv[:, 0], vo)])
    deviation = float(np.linalg.norm(ours - theirs, axis=1).max())
    if work is not source:
        original = BRep_Tool.Surface_s(source)
        for p in ours:
            proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, p)), original)
            if proj.NbPoints() == 0:
                raise FaceError(f"{face.name}: a point of its NURBS does not project onto the "
                                "original surface")
            deviation = max(deviation, float(proj.LowerDistance()))
    return deviation


def model_tolerance(face) -> float:
    """The model's own tolerance at a face (mm): the largest of the face's, its edges' and its
    vertices' OCCT tolerances (as :func:`BSplineCAM.app.faces.model_tolerance`)."""
    from OCP.TopAbs import TopAbs_EDGE, TopAbs_VERTEX
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out = float(BRep_Tool.Tolerance_s(face))
    for kind, cast in ((TopAbs_EDGE, TopoDS.Edge_s), (TopAbs_VERTEX, TopoDS.Vertex_s)):
        explorer = TopExp_Explorer(face, kind)
        while explorer.More():
            out = max(out, float(BRep_Tool.Tolerance_s(cast(explorer.Current()))))
            explorer.Next()
    return out


def reaches_from_above(face: Face, work) -> tuple[bool, str]:
    """As :func:`BSplineCAM.app.faces.reaches_from_above`, with BRepGProp_Face's normals."""
    uv = core_faces.sample_points(face, core_faces.REACH_SAMPLES)
    vo = _occt_v(face, uv[:, 1])
    props = BRepGProp_Face(work)
    nz, keep = [], []
    for k, (a, b) in enumerate(zip(uv[:, 0], vo)):
        p, n = gp_Pnt(), gp_Vec()
        props.Normal(float(a), float(b), p, n)
        length = n.Magnitude()
        if length > 1e-12:
            nz.append(n.Z() / length)
            keep.append(k)
    if not keep:
        return core_faces.reach([], [], model_tolerance(work), 0.0)
    points = np.asarray(face.surface.evaluate(uv[keep, 0], uv[keep, 1]), dtype=float)
    spacing = float(np.linalg.norm(np.ptp(points, axis=0))) / core_faces.REACH_SAMPLES
    return core_faces.reach(nz, points[:, 2], model_tolerance(work), spacing)


def faces_from_shape(shape, selection="up", tolerance: float = DEFAULT_TOLERANCE,
                     where: str = "shape") -> list[Face]:
    """Every face of ``shape`` as a core Face, selected as in the FreeCAD module."""
    if not (isinstance(tolerance, (int, float)) and math.isfinite(tolerance) and tolerance > 0):
        raise FaceError(f"{where}: trim tolerance must be a positive length in mm, "
                        f"got {tolerance!r}")
    sources = shape_faces(shape)
    if not sources:
        raise FaceError(f"{where}: has no faces")
    chosen = core_faces.parse_selection(selection, len(sources), where)
    pairs = [_extract(f, i, tolerance, False) for i, f in enumerate(sources, 1)]
    reach = [reaches_from_above(face, work) for face, work in pairs]
    return core_faces.apply_selection([face for face, _ in pairs], reach, chosen, where)


__all__ = ["faces_from_shape", "measure", "reaches_from_above", "read_part", "shape_faces"]
