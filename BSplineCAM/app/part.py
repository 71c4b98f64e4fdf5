# SPDX-License-Identifier: LGPL-2.1-or-later
"""Exact transfer of a core Surface to FreeCAD's OCCT, its exports, and the paper's route.

The exact route hands OCCT the very poles, knots and multiplicities the matrix evaluator uses,
so both evaluate the same polynomial pieces.  The paper's route (sampled points → curves
through points → surface through curves) is built too, only to measure what it loses.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core import Surface
from ..core.geometry.netio import atomic_write
from ..core.typing import FloatArray
from .compat import ensure_freecad

FreeCAD = ensure_freecad()
import Part  # noqa: E402  (needs FreeCAD on sys.path first)


def to_part_surface(surface: Surface) -> Part.BSplineSurface:
    """A Part.BSplineSurface with the same poles, knots and multiplicities as ``surface``."""
    knots = surface.occt_knots()
    poles = [[FreeCAD.Vector(*map(float, p)) for p in row] for row in surface.control_points]
    part = Part.BSplineSurface()
    part.buildFromPolesMultsKnots(
        poles,
        [int(m) for m in knots["u_mults"]],
        [int(m) for m in knots["w_mults"]],
        [float(k) for k in knots["u_knots"]],
        [float(k) for k in knots["w_knots"]],
        False,
        False,
        surface.degree,
        surface.degree,
    )
    return part


def to_face(surface: Surface) -> Part.Face:
    return Part.Face(to_part_surface(surface))


def to_solid(surface: Surface, base_z: float | None = None, margin: float = 5.0) -> Part.Solid:
    """The surface closed down to the plane z = base_z: the model a CAM job machines.

    ``base_z`` defaults to ``margin`` mm below the surface's lowest point.  The face is swept
    straight down past the base plane and cut there by a box (one OCCT boolean), which gives
    vertical side walls and a flat base sharing their edges with the exact top face.
    """
    face = to_face(surface)
    box = face.BoundBox  # OCCT's box of the poles: encloses the surface, used to cut only
    lowest = surface_extent(surface).z_min
    if base_z is None:
        base_z = lowest - margin
    if base_z >= lowest:
        raise ValueError(f"base plane z = {base_z} mm must lie below the surface's lowest point {lowest:.3f} mm")
    depth = box.ZMax - base_z + 10.0
    prism = face.extrude(FreeCAD.Vector(0, 0, -depth))
    keep = Part.makeBox(box.XLength + 2, box.YLength + 2, depth, FreeCAD.Vector(box.XMin - 1, box.YMin - 1, base_z))
    solids = prism.common(keep).Solids
    if len(solids) != 1 or not solids[0].isValid():
        raise ValueError(f"{surface.name}: the surface does not close to a valid solid (is it a height field over z?)")
    return solids[0]


@dataclass(frozen=True)
class Extent:
    """Axis-aligned extent (mm) of the points of a surface itself (not of its control net)."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    z_min: float
    z_max: float


#: Parameter samples per patch and direction of the extent's first grid.
EXTENT_SAMPLES_PER_PATCH = 16
#: Rounds of local refinement around each extreme sample (the step shrinks 4x per round).
EXTENT_ROUNDS = 10


#: The extents of the last few nets (:func:`surface_extent`): a recompute asks for the same
#: surface's several times (depths, stock, the op's own), each a dense search.
_EXTENTS: dict = {}
EXTENT_MEMO = 8


def surface_extent(surface: Surface) -> Extent:
    """The exact surface's extent by the core's evaluation (deterministic, no OCCT box),
    remembered by the net's knots and points.

    OCCT's ``BoundBox`` of a B-spline face encloses its poles (or, once the face is meshed,
    the mesh plus its deflection), so it stands above a hill's top and changes with the view.
    Here a dense parameter grid (EXTENT_SAMPLES_PER_PATCH per patch) finds each extreme
    sample, then EXTENT_ROUNDS local 9 x 9 grids around it, each a quarter the size of the
    last, refine it (a fine search; the surface is smooth within a patch): the result lies
    inside the true extent by far less than 1 nm for nets of usual size.
    """
    net = surface.control_points
    key = (str(surface.knots.value), net.shape, net.tobytes())
    known = _EXTENTS.get(key)
    if known is not None:
        return known
    extent = _search_extent(surface)
    while len(_EXTENTS) >= EXTENT_MEMO:
        _EXTENTS.pop(next(iter(_EXTENTS)))
    _EXTENTS[key] = extent
    return extent


def _search_extent(surface: Surface) -> Extent:
    """:func:`surface_extent`'s search."""
    pu, pw = surface.patches
    nu = EXTENT_SAMPLES_PER_PATCH * pu + 1
    nw = EXTENT_SAMPLES_PER_PATCH * pw + 1
    u, w = np.linspace(0.0, 1.0, nu), np.linspace(0.0, 1.0, nw)
    points = surface.evaluate_grid(u, w)
    bounds = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            values = sign * points[..., axis]
            i, j = np.unravel_index(int(np.argmax(values)), values.shape)
            best, u0, w0 = float(values[i, j]), float(u[i]), float(w[j])
            hu, hw = 1.0 / (nu - 1), 1.0 / (nw - 1)
            for _ in range(EXTENT_ROUNDS):
                us = np.clip(np.linspace(u0 - hu, u0 + hu, 9), 0.0, 1.0)
                ws = np.clip(np.linspace(w0 - hw, w0 + hw, 9), 0.0, 1.0)
                local = sign * surface.evaluate_grid(us, ws)[..., axis]
                a, b = np.unravel_index(int(np.argmax(local)), local.shape)
                if float(local[a, b]) >= best:
                    best, u0, w0 = float(local[a, b]), float(us[a]), float(ws[b])
                hu, hw = hu / 4.0, hw / 4.0
            bounds.append(sign * best)
    return Extent(*bounds)


def evaluate(surface: Surface, u: FloatArray, w: FloatArray) -> FloatArray:
    """OCCT's own evaluation (Geom_BSplineSurface::D0 through Part) at scattered (u, w)."""
    part = to_part_surface(surface)
    return np.array([tuple(part.value(float(a), float(b))) for a, b in zip(np.ravel(u), np.ravel(w))])


def export_shape(shape: Part.Shape, path: str | os.PathLike) -> None:
    """STEP or BREP by extension, written beside and renamed into place when complete."""
    path = Path(path)
    suffix = path.suffix.lower()
    tmp = path.with_name(f".{path.stem}.part{path.suffix}")
    try:
        if suffix in (".step", ".stp"):
            shape.exportStep(str(tmp))
        elif suffix in (".brep", ".brp"):
            shape.exportBrep(str(tmp))
        else:
            raise ValueError(f"{path}: unknown export format {suffix!r}: expected .step or .brep")
        if not tmp.exists() or tmp.stat().st_size == 0:
            raise OSError(f"{path}: OCCT wrote nothing")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def paper_route(points: FloatArray) -> Part.Face:
    """The paper's import route: a spline through each row of points, then a surface through
    those curves (UGS "through curves"; here FreeCAD's interpolation and loft)."""
    curves = []
    for row in np.asarray(points, dtype=float):
        curve = Part.BSplineCurve()
        curve.interpolate([FreeCAD.Vector(*map(float, p)) for p in row])
        curves.append(Part.Wire([curve.toShape()]))
    loft = Part.makeLoft(curves, False, False, False)
    return loft.Faces[0]


def deviation_between(face: Part.Face, surface: Surface, samples: int = 41, reverse_samples: int = 11) -> dict:
    """Largest distance (mm) between a face and the exact surface, measured both ways.

    Face → design: ``samples``² points of the face projected onto the exact Part surface.
    Design → face: ``reverse_samples``² points of the exact surface projected onto the face
    (projection onto a loft is ~40x slower, hence the coarser grid).  Both by OCCT.  Samples
    sit at cell midpoints, so they never coincide with the points a fitted face interpolates.
    """
    exact = to_part_surface(surface)
    mid = (np.arange(reverse_samples) + 0.5) / reverse_samples
    design = surface.evaluate_grid(mid, mid).reshape(-1, 3)
    other = face.Surface
    worst_to_face = 0.0
    for p in design:
        v = FreeCAD.Vector(*map(float, p))
        a, b = other.parameter(v)
        worst_to_face = max(worst_to_face, (other.value(a, b) - v).Length)
    u0, u1, w0, w1 = face.ParameterRange
    worst_to_design = 0.0
    mid = (np.arange(samples) + 0.5) / samples
    for a in u0 + (u1 - u0) * mid:
        for b in w0 + (w1 - w0) * mid:
            v = other.value(float(a), float(b))
            s, t = exact.parameter(v)
            worst_to_design = max(worst_to_design, (exact.value(s, t) - v).Length)
    return {
        "design_to_result_mm": worst_to_face,
        "result_to_design_mm": worst_to_design,
        "max_deviation_mm": max(worst_to_face, worst_to_design),
        "samples": [samples, samples],
        "reverse_samples": [reverse_samples, reverse_samples],
    }


__all__ = [
    "atomic_write", "deviation_between", "evaluate", "export_shape", "paper_route",
    "Extent", "surface_extent", "to_face", "to_part_surface", "to_solid",
]
