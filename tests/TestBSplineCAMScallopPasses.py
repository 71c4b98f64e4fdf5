# SPDX-License-Identifier: LGPL-2.1-or-later
"""Constant-scallop finishing on faces (core/toolpath/faces_scallop.py, scallop_field.py).

Closed forms: on a plane the passes are the flat stepover apart; across a convex cylinder's
axis and a sphere's parallels the passes' spacing integrates the closed-form allowance to one
stepover, on a cylinder turned off the grid's axes too (and the simulated scallop is within
h + tol there).  End to end: the plane-with-fillets step of TestBSplineCAMPartialPasses machined
and simulated from its G-code text against the exact faces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_helpers import assert_above_drop, gcode, plane, rectangle
from TestBSplineCAMPartialPasses import arc_face, cylinder_allowance, step_faces

from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.simulation.verify import verify_faces
from BSplineCAM.core.toolpath import generate_faces
from BSplineCAM.core.toolpath.common import flat_stepover
from BSplineCAM.core.toolpath.faces_raster import generate_faces_raster
from BSplineCAM.core.toolpath.faces_scallop import generate_faces_scallop
from BSplineCAM.core.toolpath.faceset import FaceSet
from BSplineCAM.core.toolpath.scallop_field import AXES, contours, propagate

D, H, TOL = 6.0, 0.05, 0.01
R = D / 2


def test_propagate_is_the_distance_within_the_chamfer_bound():
    """Unit costs from one node: the field is the XY distance, never below it, at most
    2.8 % above it; a blocked wall makes paths go round it."""
    xs, ys = np.linspace(0, 30, 121), np.linspace(0, 20, 81)
    cost = np.ones((len(AXES), len(xs), len(ys)))
    free = np.ones((len(xs), len(ys)), bool)
    start = np.full(free.shape, np.inf)
    start[60, 40] = 0.0
    d = propagate(start, cost, xs[1] - xs[0], ys[1] - ys[0], free)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    r = np.hypot(X - 15, Y - 10)
    assert np.all(d >= r - 1e-9)
    assert np.all(d <= 1.028 * r + 1e-9)
    free[40:80, 30:32] = False  # two nodes thick: a knight's move steps over one
    around = propagate(start, cost, xs[1] - xs[0], ys[1] - ys[0], free)
    assert around[60, 20] > 2 * math.hypot(5.0, 2.5) - 0.1  # round the wall's end
    ring = contours(d, xs, ys, 5.0)
    assert len(ring) == 1 and np.allclose(ring[0][0], ring[0][-1])


def test_plane_passes_at_the_flat_stepover():
    top = plane(0.0, 20.0, 0.0, 15.0, 2.0)
    fs = FaceSet([Face(top, rectangle(top), index=1)])
    tp = generate_faces_scallop(fs, D, H, TOL)
    loops = [p for p in tp.passes if np.ptp(p[:, 1]) > 5.0]
    x_left = np.sort([p[:, 0].min() for p in loops])
    np.testing.assert_allclose(np.diff(x_left), flat_stepover(R, H), rtol=0.01)
    assert x_left[0] == pytest.approx(0.05 * flat_stepover(R, H), abs=0.02)
    assert sum(link is None for link in tp.links) <= 2  # the next loop is within reach
    assert tp.extra["gap_area_mm2"] == 0.0
    assert_above_drop(fs, tp)


def spacing_integrals(positions: np.ndarray, rho: float) -> np.ndarray:
    """Per pair of neighbouring passes at centre offsets ``positions`` (mm, sorted, from the
    axis) the integral of dx over the closed-form allowance between them: one stepover."""
    out = []
    for a, b in zip(positions[:-1], positions[1:]):
        x = np.linspace(a, b, 201)
        f = 1.0 / cylinder_allowance(x, rho)
        out.append(float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x))))
    return np.asarray(out)


def test_cylinder_passes_along_its_axis_are_spaced_by_the_closed_form():
    """A convex cylinder of radius 10 from 50 degrees either side of its crest, 40 mm long:
    at mid-length the passes run along the axis, each pair at most one closed-form stepover
    apart (the allowance across the axis, from the curvature and the slope) and at least the
    band's least allowance (the field's cost is the largest within half a stepover: the
    allowance falls towards the steep side), but where the loops from the two sides meet at
    the crest."""
    rho, length = 10.0, 40.0
    a = math.radians(50.0)
    face = arc_face(0.0, 0.0, rho, math.pi / 2 + a, math.pi / 2 - a, length, 1)
    fs = FaceSet([face])
    tp = generate_faces_scallop(fs, D, H, TOL)
    mid = []
    for p in tp.passes:  # where the loops' sides on +x cross mid-length
        y0, y1 = p[:-1, 1] - length / 2, p[1:, 1] - length / 2
        for k in np.flatnonzero((y0 * y1 < 0) & (np.abs(y1 - y0) > 1.0)):
            x = p[k, 0] + (p[k + 1, 0] - p[k, 0]) * y0[k] / (y0[k] - y1[k])
            if x > 0.3:
                mid.append(float(x))
    side = np.sort(mid)
    assert len(side) >= 6
    got = spacing_integrals(side, rho)[1:]  # the first pair holds the crest's gap pass
    assert np.all(got <= 1.03) and np.all(got >= 0.95), got
    least = [cylinder_allowance(np.linspace(a, b, 201), rho).min()
             for a, b in zip(side[1:-1], side[2:])]
    assert np.all(np.diff(side[1:]) >= 0.99 * np.asarray(least))
    assert_above_drop(fs, tp)


def test_sphere_parallels_are_spaced_by_the_closed_form():
    """A spherical zone (radius 12, from 15 to 55 degrees off the pole, a hole round the
    pole): the passes are circles about the axis, each pair of the outer ones one
    closed-form stepover apart (the sphere's normal curvature is the cylinder's in every
    direction, a parallel runs level) to 5 %, the outermost pair on the steep rim, where the
    circles run obliquely to the grid's axes on every side, too."""
    from bsplinecam_helpers import revolved_face

    rho = 12.0
    a0, a1 = math.radians(90 - 15), math.radians(90 - 55)
    half, midang = 0.5 * (a0 - a1), 0.5 * (a0 + a1)
    far = rho / math.cos(half)
    profile = [(rho * math.cos(a0), rho * math.sin(a0)),
               (far * math.cos(midang), far * math.sin(midang)),
               (rho * math.cos(a1), rho * math.sin(a1))]
    fs = FaceSet([revolved_face(profile, [1.0, math.cos(half), 1.0])])
    tp = generate_faces_scallop(fs, D, H, TOL)
    radii = []
    for p in tp.passes:
        r = np.hypot(p[:, 0], p[:, 1])
        around = np.hypot(*np.diff(p[:, :2], axis=0).T).sum()
        if np.allclose(p[0, :2], p[-1, :2]) and around > 5.0 * r.mean():
            radii.append(float(r.mean()))
    radii = np.sort(radii)[::-1]
    outer = radii[:4]  # from the outer border inwards, before the inner loops
    got = spacing_integrals(outer[::-1], rho)
    assert np.all(got <= 1.05) and np.all(got >= 0.95), got
    assert_above_drop(fs, tp)


def oblique_cylinder(rho: float, half_angle: float, length: float, turn: float) -> Face:
    """:func:`arc_face`'s convex cylinder (radius rho, ``half_angle`` rad either side of its
    crest, ``length`` mm) turned by ``turn`` rad about Z: its axis oblique to the grid."""
    face = arc_face(0.0, 0.0, rho, math.pi / 2 + half_angle, math.pi / 2 - half_angle,
                    length, 1)
    s = face.surface
    c, sn = math.cos(turn), math.sin(turn)
    poles = np.asarray(s.poles, dtype=float).copy()
    x, y = poles[..., 0].copy(), poles[..., 1].copy()
    poles[..., 0], poles[..., 1] = x * c - y * sn, x * sn + y * c
    turned = NurbsSurface(poles, s.knots_u, s.knots_v, s.degree_u, s.degree_v,
                          weights=s.weights)
    return Face(turned, rectangle(turned), index=1)


def test_oblique_cylinder_passes_within_the_closed_form_and_the_scallop():
    """The cylinder's axis turned 30 degrees off the grid's, its sides 50 degrees steep: at
    mid-length every pair of neighbouring passes is at most one closed-form stepover apart
    (measured across the axis) and the simulated scallop is within h + tol.  A cost taken
    along each axis as 1 / (the stepover across it) is lower than the true one obliquely to
    a slope (the path runs where the stepover is wide), so the steep pair stood 11 % wider;
    the field's dual costs (scallop_metric) keep it."""
    rho, length, turn, tol = 10.0, 30.0, math.radians(30.0), 0.002
    face = oblique_cylinder(rho, math.radians(50.0), length, turn)
    fs = FaceSet([face])
    tp = generate_faces_scallop(fs, D, H, tol)
    axis = np.array([-math.sin(turn), math.cos(turn)])
    across = np.array([math.cos(turn), math.sin(turn)])
    offsets = []
    for p in tp.passes:  # where the passes on the + side cross mid-length
        t = (p[:, :2] - axis * length / 2) @ axis
        for k in np.flatnonzero(t[:-1] * t[1:] < 0):
            q = p[k, :2] + (p[k + 1, :2] - p[k, :2]) * t[k] / (t[k] - t[k + 1])
            if float(q @ across) > 0.3:
                offsets.append(float(q @ across))
    side = np.sort(offsets)
    assert len(side) >= 8
    got = spacing_integrals(side, rho)
    assert np.all(got <= 1.03), got
    program = read_gcode(gcode(tp))
    m = verify_faces([face], program, Tool(D), cell=0.05).metrics
    assert m["scallop_max_mm"] <= H + tol, m["scallop_max_mm"]
    assert m["gouge_max_mm"] <= 1e-3
    assert_above_drop(fs, tp)


@pytest.fixture(scope="module")
def step_runs():
    faces = step_faces()
    runs = {}
    for name in ("scallop", "raster"):
        fs = FaceSet(faces)
        if name == "scallop":
            tp = generate_faces(fs, "scallop", D, H, TOL)
        else:
            tp = generate_faces_raster(fs, D, H, TOL, angle=0.0)
        program = read_gcode(gcode(tp))
        runs[name] = (fs, tp, verify_faces(faces, program, Tool(D), cell=0.1).metrics)
    return runs


@pytest.mark.venv_only
def test_step_scallop_passes_certified_covering_and_shorter(step_runs):
    """The flat-ramp-flat step with its fillets: no gouge, every scallop within h + tol,
    the faces covered, and less cutting than the raster at the same scallop."""
    fs, tp, m = step_runs["scallop"]
    _, _, mr = step_runs["raster"]
    assert tp.strategy == "scallop"
    assert m["gouge_max_mm"] <= 1e-3
    assert m["scallop_max_mm"] <= H + TOL, m["scallop_max_mm"]
    assert m["coverage"] == 1.0
    assert m["cutting_length_mm"] < mr["cutting_length_mm"], (m, mr)
    assert_above_drop(fs, tp)
    assert tp.stats.passes > 0 and tp.extra["levels"] > 5


def test_scallop_refused_on_a_net():
    from BSplineCAM.core import Surface
    from BSplineCAM.core.errors import ParameterError
    from BSplineCAM.core.toolpath import generate

    x = np.linspace(0.0, 20.0, 4)
    pts = np.zeros((4, 4, 3))
    pts[..., 0], pts[..., 1] = np.meshgrid(x, x, indexing="ij")
    with pytest.raises(ParameterError, match="faces only"):
        generate(Surface(pts, knots="clamped"), "scallop", 6.0, 0.05, 0.01)
