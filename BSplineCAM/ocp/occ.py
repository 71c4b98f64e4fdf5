# SPDX-License-Identifier: LGPL-2.1-or-later
"""The exact surface in cadquery's OCCT (OCP): Geom_BSplineSurface, face, STEP and BREP.

This OCCT build is independent of FreeCAD's, so agreement of both with the matrix evaluator
is two separate confirmations.  Import only in a Python that has cadquery (the project venv).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
from OCP.BRepTools import BRepTools
from OCP.Geom import Geom_BSplineSurface
from OCP.gp import gp_Pnt
from OCP.IFSelect import IFSelect_RetDone
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer
from OCP.TColgp import TColgp_Array2OfPnt
from OCP.TColStd import TColStd_Array1OfInteger, TColStd_Array1OfReal

from ..core import Surface
from ..core.geometry.basis import unique_knots
from ..core.typing import FloatArray


def _reals(values) -> TColStd_Array1OfReal:
    arr = TColStd_Array1OfReal(1, len(values))
    for i, v in enumerate(values, start=1):
        arr.SetValue(i, float(v))
    return arr


def _ints(values) -> TColStd_Array1OfInteger:
    arr = TColStd_Array1OfInteger(1, len(values))
    for i, v in enumerate(values, start=1):
        arr.SetValue(i, int(v))
    return arr


def to_geom(surface: Surface) -> Geom_BSplineSurface:
    """Geom_BSplineSurface with the same poles, knots and multiplicities as ``surface``."""
    rows, cols = surface.shape
    poles = TColgp_Array2OfPnt(1, rows, 1, cols)
    for i in range(rows):
        for j in range(cols):
            poles.SetValue(i + 1, j + 1, gp_Pnt(*map(float, surface.control_points[i, j])))
    k = surface.occt_knots()
    return Geom_BSplineSurface(
        poles, _reals(k["u_knots"]), _reals(k["w_knots"]), _ints(k["u_mults"]), _ints(k["w_mults"]),
        surface.degree, surface.degree, False, False,
    )


def evaluate(surface: Surface, u: FloatArray, w: FloatArray) -> FloatArray:
    """OCCT's per-point evaluation (Geom_BSplineSurface::Value) at scattered (u, w)."""
    geom = to_geom(surface)
    out = []
    for a, b in zip(np.ravel(u), np.ravel(w)):
        p = geom.Value(float(a), float(b))
        out.append((p.X(), p.Y(), p.Z()))
    return np.array(out)


def to_face(surface: Surface):
    return BRepBuilderAPI_MakeFace(to_geom(surface), 1e-7).Face()


def to_cadquery(surface: Surface):
    """A cadquery Face wrapping the exact surface."""
    import cadquery as cq

    return cq.Face(to_face(surface))


def export(surface: Surface, path: str | os.PathLike) -> None:
    """Write the exact face as STEP or BREP (by extension), renamed into place on success."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.part{path.suffix}")
    face = to_face(surface)
    try:
        if path.suffix.lower() in (".step", ".stp"):
            writer = STEPControl_Writer()
            writer.Transfer(face, STEPControl_AsIs)
            if writer.Write(str(tmp)) != IFSelect_RetDone:
                raise OSError(f"{path}: STEP writer failed")
        elif path.suffix.lower() in (".brep", ".brp"):
            if not BRepTools.Write_s(face, str(tmp)):
                raise OSError(f"{path}: BREP writer failed")
        else:
            raise ValueError(f"{path}: unknown export format {path.suffix!r}")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


# -- general NURBS surfaces (core.nurbs.NurbsSurface's constructor arguments) -----------------
def nurbs_geom(poles, knots_u, knots_v, degree_u: int, degree_v: int, weights=None,
               periodic_u: bool = False, periodic_v: bool = False) -> Geom_BSplineSurface:
    """Geom_BSplineSurface from the arguments of :class:`~BSplineCAM.core.geometry.nurbs.NurbsSurface`
    (full flat knot vectors, periodic directions in OCCT's own form)."""
    poles = np.asarray(poles, dtype=float)
    rows, cols = poles.shape[:2]
    net = TColgp_Array2OfPnt(1, rows, 1, cols)
    for i in range(rows):
        for j in range(cols):
            net.SetValue(i + 1, j + 1, gp_Pnt(*map(float, poles[i, j])))
    uk, um = unique_knots(knots_u, tol=0.0)
    vk, vm = unique_knots(knots_v, tol=0.0)
    args = (_reals(uk), _reals(vk), _ints(um), _ints(vm), int(degree_u), int(degree_v),
            bool(periodic_u), bool(periodic_v))
    if weights is None:
        return Geom_BSplineSurface(net, *args)
    from OCP.TColStd import TColStd_Array2OfReal

    wts = TColStd_Array2OfReal(1, rows, 1, cols)
    weights = np.asarray(weights, dtype=float)
    for i in range(rows):
        for j in range(cols):
            wts.SetValue(i + 1, j + 1, float(weights[i, j]))
    return Geom_BSplineSurface(net, wts, *args)


def nurbs_d2(geom, u, v) -> tuple[FloatArray, ...]:
    """OCCT's Geom_Surface::D2 at scattered (u, v): point, Su, Sv, Suu, Suv, Svv, each (m, 3)."""
    from OCP.gp import gp_Vec

    out = []
    for a, b in zip(np.ravel(u), np.ravel(v)):
        p = gp_Pnt()
        vecs = [gp_Vec() for _ in range(5)]
        geom.D2(float(a), float(b), p, *vecs)  # P, D1U, D1V, D2U, D2V, D2UV
        d1u, d1v, d2u, d2v, d2uv = vecs
        out.append([(q.X(), q.Y(), q.Z()) for q in (p, d1u, d1v, d2u, d2uv, d2v)])
    arr = np.array(out).reshape(-1, 6, 3)
    return tuple(arr[:, k] for k in range(6))
