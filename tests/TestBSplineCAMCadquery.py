# SPDX-License-Identifier: LGPL-2.1-or-later
"""The exact transfer into cadquery's OCCT (OCP): evaluation, STEP and BREP round trips."""

from __future__ import annotations

import os

import numpy as np
import pytest
from conftest import CASE_STUDY, random_net

from BSplineCAM import Surface

if os.environ.get("BSPLINECAM_REQUIRE_ALL") != "1":
    pytest.importorskip("OCP", reason="cadquery's OCP lives in the project venv")
from OCP.BRep import BRep_Builder, BRep_Tool  # noqa: E402
from OCP.BRepGProp import BRepGProp  # noqa: E402
from OCP.BRepTools import BRepTools  # noqa: E402
from OCP.Geom import Geom_BSplineSurface  # noqa: E402
from OCP.GProp import GProp_GProps  # noqa: E402
from OCP.STEPControl import STEPControl_Reader  # noqa: E402
from OCP.TopAbs import TopAbs_FACE  # noqa: E402
from OCP.TopExp import TopExp_Explorer  # noqa: E402
from OCP.TopoDS import TopoDS, TopoDS_Shape  # noqa: E402

from BSplineCAM.ocp import occ  # noqa: E402


def first_bspline(shape) -> Geom_BSplineSurface:
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    face = TopoDS.Face_s(explorer.Current())
    geom = BRep_Tool.Surface_s(face)
    return Geom_BSplineSurface.DownCast(geom) if hasattr(Geom_BSplineSurface, "DownCast") else geom


@pytest.mark.parametrize("layout", ["uniform", "clamped"])
def test_occt_evaluation_equals_matrix_form(layout, rng):
    surface = Surface(random_net(rng, 9, 6), layout)
    t = np.linspace(0, 1, 41)
    u, w = (a.ravel() for a in np.meshgrid(t, t, indexing="ij"))
    deviation = np.abs(occ.evaluate(surface, u, w) - surface.evaluate(u, w)).max()
    assert deviation <= 1e-9 * surface.size()


def test_case_study_poles_and_knots_transfer_exactly():
    surface = Surface.from_json(CASE_STUDY)
    geom = occ.to_geom(surface)
    assert (geom.NbUPoles(), geom.NbVPoles()) == surface.shape
    assert geom.UDegree() == geom.VDegree() == 3
    k = surface.occt_knots()
    assert [geom.UKnot(i) for i in range(1, geom.NbUKnots() + 1)] == k["u_knots"].tolist()
    assert [geom.UMultiplicity(i) for i in range(1, geom.NbUKnots() + 1)] == k["u_mults"].tolist()
    pole = geom.Pole(3, 7)
    assert (pole.X(), pole.Y(), pole.Z()) == tuple(surface.control_points[2, 6])


@pytest.mark.parametrize("suffix", ["step", "brep"])
def test_export_reimport_evaluates_the_same(tmp_path, suffix):
    surface = Surface.from_json(CASE_STUDY)
    path = tmp_path / f"s.{suffix}"
    occ.export(surface, path)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]
    if suffix == "step":
        reader = STEPControl_Reader()
        reader.ReadFile(str(path))
        reader.TransferRoots()
        shape = reader.OneShape()
    else:
        shape = TopoDS_Shape()
        BRepTools.Read_s(shape, str(path), BRep_Builder())
    geom = first_bspline(shape)
    rng = np.random.default_rng(3)
    u, w = rng.random(200), rng.random(200)
    back = np.array([[geom.Value(a, b).X(), geom.Value(a, b).Y(), geom.Value(a, b).Z()] for a, b in zip(u, w)])
    assert np.abs(back - surface.evaluate(u, w)).max() <= 1e-9 * surface.size()


def test_face_area_matches_gauss_quadrature():
    """OCCT's surface integral of the face equals Gauss–Legendre quadrature per patch of ours."""
    surface = Surface.from_json(CASE_STUDY)
    nodes, weights = np.polynomial.legendre.leggauss(8)
    spans = surface.patches[0]
    t = np.concatenate([(j + (nodes + 1) / 2) / spans for j in range(spans)])
    wt = np.tile(weights / 2 / spans, spans)
    density = np.linalg.norm(np.cross(surface.evaluate_grid(t, t, 1, 0), surface.evaluate_grid(t, t, 0, 1)), axis=-1)
    props = GProp_GProps()
    BRepGProp.SurfaceProperties_s(occ.to_cadquery(surface).wrapped, props, 1e-10)
    assert props.Mass() == pytest.approx(wt @ density @ wt, rel=1e-8)
