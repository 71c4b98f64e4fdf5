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
