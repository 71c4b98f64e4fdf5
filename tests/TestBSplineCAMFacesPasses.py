# SPDX-License-Identifier: LGPL-2.1-or-later
"""Iso-parametric and waterline finishing of trimmed and several faces
(core/toolpath/faces_iso.py, faces_waterline.py), measured by simulating the G-code text
against the exact faces (FaceSet.height of every face) and against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_helpers import (
    HOLE,
    TOL,
    D,
    H,
    R,
    assert_above_drop,
    bezier_net,
    circle,
    cylinder_quarter,
    dome_faces,
    fillet_ring,
    gcode,
    holed_plane,
    plane,
    plate_with_hole,
    rectangle,
    ridge_contact_slope,
    ridge_z,
)
from conftest import ROOT

from BSplineCAM.core import Surface
from BSplineCAM.core.errors import BSplineCAMError, ParameterError
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.simulate import Grid, Tool, simulate_program
from BSplineCAM.core.toolpath.faces_iso import generate_faces_iso
from BSplineCAM.core.toolpath.faces_waterline import generate_faces_waterline
from BSplineCAM.core.toolpath.faceset import FaceSet

#: Largest gouge allowed anywhere on the model (mm).
GOUGE = 1e-3


def stock_top(tp) -> float:
    """A stock block just under the clearance plane, so that rapids never touch it."""
    return tp.clearance_height - 0.5


def simulated(fs: FaceSet, tp, box, cell: float = 0.1):
    """Z-map of the program text, and the design (NaN off the faces), face index and cell
    centres on it."""
    program = read_gcode(gcode(tp))
    grid = Grid.covering(*box, cell)
    sim = simulate_program(program, Tool(D), grid, top=stock_top(tp))
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    z, fidx, _u, _v, found = fs.height(np.column_stack([X.ravel(), Y.ravel()]), False)
    return sim.height, z.reshape(X.shape), fidx.reshape(X.shape), found.reshape(X.shape), X, Y


def assert_no_gouge(sim, design, found):
    gouge = np.where(found, design - sim, -np.inf)
    assert gouge.max() <= GOUGE, gouge.max()


def contacts_selected(fs: FaceSet, tp) -> float:
    verts = np.concatenate(tp.passes)
    return float(fs.drop_ball(verts[:, :2], R)[4].mean())


# -- iso-parametric -----------------------------------------------------------------------------
@pytest.mark.parametrize("direction", ["u", "v"])
def test_iso_on_dome_with_hole_and_check_face(direction):
    fs = FaceSet(dome_faces())
    tp = generate_faces_iso(fs, D, H, TOL, direction=direction)
    assert tp.passes and tp.parameters["faces"] == ["Face1"]
    assert contacts_selected(fs, tp) > 0.99
    assert_above_drop(fs, tp)
    sim, design, fidx, found, X, Y = simulated(fs, tp, (-1.0, 33.0, -1.0, 25.0))
    assert_no_gouge(sim, design, found)
    # the check plane is never cut below its surface (it may be touched from above)
    on_check = found & (fidx == 1)
    assert np.all(sim[on_check] >= design[on_check] - GOUGE)
    # scallop on the dome away from its borders, the hole and the check face (one radius)
    far = ((X > R) & (X < 24 - R) & (Y > R) & (Y < 24 - R)
           & (np.hypot(X - 12, Y - 12) > 0.12 * 24 + R) & found & (fidx == 0))
    assert far.sum() > 10000
    scallop = (sim - design)[far]
    assert scallop.max() <= H + TOL, scallop.max()
    # no pass over the hole (narrower than the ball: links may bridge it above the rim)
    verts = np.concatenate(tp.passes)
    u, v = fs.drop_ball(verts[:, :2], R)[2:4]
    assert np.hypot(u - 0.5, v - 0.5).min() >= 0.12 * math.cos(math.pi / HOLE) - 1e-9


def test_iso_holed_plane_passes_stop_at_the_hole():
    face = holed_plane(HOLE)
    fs = FaceSet([face])
    tp = generate_faces_iso(fs, D, H, TOL)
    verts = np.concatenate(tp.passes)
    # on a plane the tip lies right above the contact: at z = 1.5, never over the hole
    # (radius 8 mm about (20, 20); the trim polygon's inscribed circle is a little smaller)
    np.testing.assert_allclose(verts[:, 2], 1.5, atol=1e-9)
    r = np.hypot(verts[:, 0] - 20.0, verts[:, 1] - 20.0)
    assert r.min() >= 8.0 * math.cos(math.pi / HOLE) - 1e-9
    # passes reach the rim (the trim crossing is found by bisection)
    assert r.min() <= 8.0 + 1e-6
    # the flat stepover 2 sqrt(2Rh - h^2) (vertical cusps on a plane are the scallop)
    ys = np.unique(np.round(verts[:, 1], 9))
    assert np.diff(ys).max() <= 2 * math.sqrt(2 * R * H - H * H) + 1e-9
    sim, design, _f, found, X, Y = simulated(fs, tp, (-1.0, 41.0, -1.0, 41.0), 0.2)
    assert_no_gouge(sim, design, found)
    far = (found & (X > R) & (X < 40 - R) & (Y > R) & (Y < 40 - R)
           & (np.hypot(X - 20, Y - 20) > 8 + R))
    assert (sim - design)[far].max() <= H + TOL
    # the hole is entered only by stay-down links bridging a chord of it narrower than the
    # ball (it rests on the rim on both sides); away from such chords it is never entered
    links = [lk for lk in tp.links if lk is not None]
    over = [lk for lk in links if np.hypot(lk[:, 0] - 20, lk[:, 1] - 20).min() < 8.0]
    for lk in over:
        assert np.ptp(lk[:, 1]) <= 1e-9  # along its pass
        assert 2 * math.sqrt(64.0 - (lk[0, 1] - 20.0) ** 2) < D
    reach = np.full(X.shape, True)
    for lk in over:
        reach &= np.abs(Y - lk[0, 1]) > R
    hole = (np.hypot(X - 20, Y - 20) < 8 - R) & reach
    assert hole.sum() > 1000
    assert np.all(sim[hole] >= stock_top(tp) - 1e-6)


def test_iso_cylinder_closed_form():
    """Passes along the arc (u) of a quarter cylinder of radius rho: the tip follows
    sqrt((rho + R)^2 - x^2) - R exactly above the face, and every pass lies at constant y."""
    rho, length = 10.0, 20.0
    ns = cylinder_quarter(rho, length)
    fs = FaceSet([Face(ns, rectangle(ns))])
    seen: list = []
    tp = generate_faces_iso(fs, D, H, TOL, direction="u", progress=seen.append)
    assert seen[0] == 0.0 and seen[-1] == 1.0 and seen == sorted(seen)
    pts = np.concatenate(tp.passes)
    for p in tp.passes:
        assert np.ptp(p[:, 1]) <= 1e-9
    exact = np.sqrt((rho + R) ** 2 - pts[:, 0] ** 2) - R
    # one-sided: never below the exact CL curve, at most the chordal tolerance above it
    assert np.all(pts[:, 2] >= exact - 1e-7)
    assert np.all(pts[:, 2] <= exact + TOL)
    # the passes span the face: ball centres from 45 to 135 degrees
    reach = (rho + R) * math.sqrt(0.5)
    assert pts[:, 0].max() >= reach - 1e-6 and pts[:, 0].min() <= -reach + 1e-6
    sim, design, _f, found, X, Y = simulated(fs, tp, (-8.0, 8.0, -1.0, 21.0))
    assert_no_gouge(sim, design, found)
    far = found & (np.abs(Y - length / 2) < length / 2 - R) & (np.abs(X) < rho * math.sqrt(0.5) - R)
    assert (sim - design)[far].max() <= H + TOL


@pytest.mark.parametrize("direction", ["u", "v"])
def test_iso_seam_oblique_to_the_passes_keeps_the_scallop(direction):
    """Two selected faces of one plane, split by a seam running at an angle to the iso-curves
    (y from 16 to 22 mm across the 40 mm plate, as the top and a fillet of examples/part.step
    meet).  Each face spaces its passes on its own, from its trim's parameter box, so at the
    seam the last pass of one face and the first of the other could lie up to two stepovers
    apart.  Every point of each face must lie within half a stepover of one of its passes (or
    between two of them), the seam included: the scallop over the whole plate, seam band
    included, stays within h + tol."""
    ns = plane(0.0, 40.0, 0.0, 40.0, 1.5)
    a, b = 0.4, 0.55  # the seam from (u, v) = (0, a) to (1, b)
    lower = np.array([[0, 0], [1, 0], [1, b], [0, a], [0, 0]], float)
    upper = np.array([[0, a], [1, b], [1, 1], [0, 1], [0, a]], float)
    if direction == "v":  # the same plate with u and v swapped: the seam at x from 16 to 22
        ns = NurbsSurface(ns.poles.transpose(1, 0, 2), ns.knots_v, ns.knots_u, 1, 1)
        lower, upper = lower[::-1, ::-1].copy(), upper[::-1, ::-1].copy()
    fs = FaceSet([Face(ns, lower, index=1), Face(ns, upper, index=2)])
    tp = generate_faces_iso(fs, D, H, TOL, direction=direction)
    verts = np.concatenate(tp.passes)
    np.testing.assert_allclose(verts[:, 2], 1.5, atol=1e-9)
    # the partial passes along the seam, on both faces
    assert all(v["edge_curves"] > 0 for v in tp.extra["faces"].values())
    sim, design, _f, found, X, Y = simulated(fs, tp, (-1.0, 41.0, -1.0, 41.0), 0.05)
    assert_no_gouge(sim, design, found)
    far = found & (X > R) & (X < 40 - R) & (Y > R) & (Y < 40 - R)
    scallop = (sim - design)[far]
    assert scallop.max() <= H + TOL, scallop.max()


@pytest.mark.parametrize("direction", ["u", "v"])
def test_iso_stops_where_the_face_turns_steeper_than_the_raster_reaches(direction):
    """A quarter cylinder from its top (0 degrees) down to its vertical side (90): the passes
    reach no further than STEEPEST_REACHED (75 degrees), as the raster's do; beyond it the
    ball's contact nears its rim and the chord checks would sample the height densely (over
    15 minutes for iso on examples/part.step's fillets).  Along the arc (u) each pass ends
    on the 75 degree line itself."""
    from BSplineCAM.core.toolpath.faces_raster import STEEPEST_REACHED

    rho, length = 10.0, 20.0
    c = math.sqrt(0.5)
    arc = [(0.0, rho), (rho, rho), (rho, 0.0)]
    poles = np.array([[[x, y, z] for y in (0.0, length)] for x, z in arc])
    weights = np.array([[1.0, 1.0], [c, c], [1.0, 1.0]])
    ns = NurbsSurface(poles, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1, weights=weights)
    fs = FaceSet([Face(ns, rectangle(ns))])
    tp = generate_faces_iso(fs, D, H, TOL, direction=direction)
    pts = np.concatenate(tp.passes)
    # the ball centre lies on the offset cylinder (the tip at most the tolerance above it):
    # its x gives the contact's angle from the top
    angle = np.degrees(np.arcsin(np.clip(pts[:, 0] / (rho + R), -1.0, 1.0)))
    assert angle.max() <= STEEPEST_REACHED + 0.01
    assert angle.min() <= 1.0
    if direction == "u":
        for p in tp.passes:
            a = np.degrees(np.arcsin(np.clip(p[:, 0] / (rho + R), -1.0, 1.0)))
            assert a.max() >= STEEPEST_REACHED - 0.01
    else:
        assert angle.max() >= STEEPEST_REACHED - 10.0
    exact = np.sqrt((rho + R) ** 2 - pts[:, 0] ** 2) - R
    assert np.all(pts[:, 2] >= exact - 1e-7)


def test_iso_bad_input():
    fs = FaceSet(dome_faces())
    with pytest.raises(ParameterError, match="direction"):
        generate_faces_iso(fs, D, H, TOL, direction="x")
    with pytest.raises(ParameterError, match="tool_diameter"):
        generate_faces_iso(fs, -1.0, H, TOL)
    faces = [Face(f.surface, f.outer, f.holes, index=f.index, selected=False)
             for f in dome_faces()]
    with pytest.raises(BSplineCAMError, match="selection is empty"):
        generate_faces_iso(FaceSet(faces), D, H, TOL)


def test_iso_refuses_more_curves_than_it_can_cut(monkeypatch):
    """More than MAX_CURVES iso-curves across a face (a tiny scallop on a large face, or a step
    that creeps) is refused by name, with the option to change, before any pass is cut."""
    from BSplineCAM.core.toolpath import isoparametric

    monkeypatch.setattr(isoparametric, "MAX_CURVES", 5)
    with pytest.raises(ParameterError, match="Face1 needs more than 5 iso-curves.*scallop"):
        generate_faces_iso(FaceSet(dome_faces()), D, H, TOL)


# -- waterline ----------------------------------------------------------------------------------
def test_waterline_cylinder_contours_are_straight_at_known_offsets():
    """At tip height z the ball touches a cylinder of radius rho (axis y at z = 0) where
    x = +-sqrt((rho + R)^2 - (z + R)^2): two straight contours the length of the face."""
    rho, length = 10.0, 20.0
    ns = cylinder_quarter(rho, length)
    fs = FaceSet([Face(ns, rectangle(ns))])
    tp = generate_faces_waterline(fs, D, H, TOL)
    levels = tp.extra["levels"]
    assert len(levels) >= 4 and len(tp.passes) == 2 * len(levels)
    for p in tp.passes:
        z = p[0, 2]
        assert np.ptp(p[:, 2]) == 0.0
        x = math.sqrt((rho + R) ** 2 - (z + R) ** 2)
        np.testing.assert_allclose(np.abs(p[:, 0]), x, atol=1e-5)
        # the contact stays on the face: ends within a hair of y = 0 and y = length
        assert p[:, 1].min() <= 0.01 and p[:, 1].max() >= length - 0.01
        assert p[:, 1].min() >= -R * 1e-3 - 1e-9 and p[:, 1].max() <= length + R * 1e-3 + 1e-9
    # levels are scallop-spaced on the steep part: the contacts of neighbouring levels lie
    # at most the convex stepover apart along the arc (closed form, vertical cusp h n_z)
    angles = [math.acos((z + R) / (rho + R)) for z in levels]
    for a, b in zip(angles[:-1], angles[1:]):
        mid = 0.5 * (a + b)
        if mid < math.radians(30.0):
            continue
        h = H * math.cos(mid)
        c = ((rho + R) ** 2 + (rho + h) ** 2 - R * R) / (2 * (rho + R) * (rho + h))
        assert rho * (b - a) <= 2 * rho * math.acos(c) + 1e-9
    sim, design, _f, found, X, Y = simulated(fs, tp, (-8.0, 8.0, -1.0, 21.0))
    assert_no_gouge(sim, design, found)
    # scallop on the steep flanks (contact slope 35 degrees and more, above the lowest level's
    # contact), away from the ends
    low = math.acos((levels[-1] + R) / (rho + R))
    ang = np.arcsin(np.clip(np.abs(X) / rho, 0, 1))
    far = found & (np.abs(Y - length / 2) < length / 2 - R) & (ang >= math.radians(35.0)) & (ang <= low)
    assert far.sum() > 1000
    assert (sim - design)[far].max() <= H + TOL


def test_waterline_cylinder_with_hole_follows_the_material():
    """A hole in the cylinder's steep flank: every contour vertex still lies on the
    closed-form line x = +-sqrt((rho + R)^2 - (z + R)^2) (a ball hanging on the hole's rim
    would stand off it) with its contact on the material, and the contours that cross the hole
    stop at its rim, on both sides of it."""
    rho, length, cu, cv, r = 10.0, 30.0, 0.2, 0.5, 0.1
    ns = cylinder_quarter(rho, length)
    fs = FaceSet([Face(ns, rectangle(ns), holes=(circle(cu, cv, r, HOLE),))])
    tp = generate_faces_waterline(fs, D, H, TOL)
    assert tp.passes
    pts = np.concatenate(tp.passes)
    x = np.sqrt((rho + R) ** 2 - (pts[:, 2] + R) ** 2)
    np.testing.assert_allclose(np.abs(pts[:, 0]), x, atol=1e-5)
    _t, _f, u, v, _s = fs.drop_ball(pts[:, :2], R)
    assert np.all(np.hypot(u - cu, v - cv) >= r * math.cos(math.pi / HOLE) - 1e-9)
    # the contours whose contact line u = const crosses the hole end at its rim, where the
    # circle in (u, v) puts it: y = length (cv +- sqrt(r^2 - (u - cu)^2))
    uc = np.array([fs.drop_ball(p[:1, :2], R)[2][0] for p in tp.passes])
    crossing = [(p, uu) for p, uu in zip(tp.passes, uc) if abs(uu - cu) < 0.9 * r]
    assert len(crossing) >= 4
    for p, uu in crossing:
        half = length * math.sqrt(r * r - (uu - cu) ** 2)
        if p[:, 1].max() < length * cv:
            assert p[:, 1].min() < 1e-3 and abs(p[:, 1].max() - (length * cv - half)) < 0.02
        else:
            assert p[:, 1].max() > length - 1e-3
            assert abs(p[:, 1].min() - (length * cv + half)) < 0.02


def test_waterline_dome_with_hole_and_check_face():
    fs = FaceSet(dome_faces())
    tp = generate_faces_waterline(fs, D, H, TOL)
    assert tp.passes
    for p in tp.passes:
        assert np.ptp(p[:, 2]) == 0.0
    # contacts on the selected dome only, never a ball hanging on the hole's rim
    assert contacts_selected(fs, tp) == 1.0
    assert_above_drop(fs, tp)
    verts = np.concatenate(tp.passes)
    assert np.hypot(verts[:, 0] - 12, verts[:, 1] - 12).min() > 0.12 * 24 - 1e-6
    sim, design, fidx, found, X, Y = simulated(fs, tp, (-4.0, 36.0, -4.0, 28.0))
    assert_no_gouge(sim, design, found)
    # scallop where the dome is steep (35 degrees and more) between the first level and the
    # last one spaced on steep ground (a ball touching at slope a stands R (1 - cos a) lower),
    # away from the borders, the hole and the check face
    levels = tp.extra["levels"]
    dz = np.gradient(np.where(found, design, np.nan), 0.1)
    slope = np.arctan(np.hypot(dz[0], dz[1]))
    tip = design - R * (1.0 - np.cos(slope))
    far = (found & (fidx == 0) & (X > R) & (X < 24 - R) & (Y > R) & (Y < 24 - R)
           & (np.hypot(X - 12, Y - 12) > 0.12 * 24 + R) & (slope >= math.radians(35.0))
           & (tip <= levels[0]) & (tip >= levels[-2]))
    assert far.sum() > 1000
    assert (sim - design)[far].max() <= H + TOL


def test_waterline_bad_input():
    fs = FaceSet(dome_faces())
    with pytest.raises(ParameterError, match="min_slope"):
        generate_faces_waterline(fs, D, H, TOL, min_slope=95.0)
    with pytest.raises(ParameterError, match="scallop"):
        generate_faces_waterline(fs, D, 0.0, TOL)
    with pytest.raises(ParameterError, match="progress"):
        generate_faces_waterline(fs, D, H, TOL, progress=3)
    with pytest.raises(ParameterError, match="faceset"):
        generate_faces_waterline(dome_faces(), D, H, TOL)


def test_waterline_plane_has_no_contour():
    """A plane has no steep part and the ball hanging on the rim of a hole touches only the
    edge: no waterline, and a note says so."""
    fs = FaceSet([holed_plane(HOLE)])
    tp = generate_faces_waterline(fs, D, H, TOL)
    assert tp.passes == []
    assert any("no waterline" in n for n in tp.stats.notes)


# -- steep / shallow ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def ridge_face():
    """The ridge z = 14 - K (x - 20)^2 of the net tests (slope 45 degrees at |x - 20| = 12.5,
    58 at its long borders) as one trimmed face, machined by steep_shallow through the faces
    dispatch (threshold 45 degrees)."""
    from BSplineCAM.core.toolpath import generate_faces

    ns = NurbsSurface.from_surface(Surface(bezier_net(ridge_z, 40.0), knots="clamped"))
    fs = FaceSet([Face(ns, rectangle(ns))])
    tp = generate_faces(fs, "steep_shallow", D, H, TOL, threshold=45.0)
    return fs, tp, ridge_z


def test_faces_steep_shallow_split_matches_the_closed_form(ridge_face):
    """The contact slope on the faces' split grid (edge or surface contact of the certified
    drop-cutter) matches the closed form inside the face; the masks split at 45 degrees."""
    _fs, tp, _z = ridge_face
    split = tp.extra["split"]
    assert split.threshold_deg == 45.0
    X, Y = np.meshgrid(*split.grid.centres())
    inner = (X > 4.0) & (X < 36.0) & (Y > R) & (Y < 40.0 - R)
    ref = ridge_contact_slope(X[inner])
    assert np.abs(split.slope_deg[inner] - ref).max() < 1e-3
    sure = np.abs(ref - 45.0) > 1e-3
    assert np.all(split.shallow[inner][sure] == (ref[sure] < 45.0))
    assert np.all(split.steep[inner][sure] == (ref[sure] >= 45.0))


def test_faces_steep_shallow_passes_and_simulation(ridge_face):
    """Raster pieces stay on the shallow zone and contours (constant Z) on the steep one, each
    grown by the overlap; every cutter location is at or above the certified drop height; the
    simulated program text gouges nothing and leaves at most scallop + tolerance away from the
    face's borders: no seam between the two."""
    fs, tp, ridge_z = ridge_face
    nr, nw = tp.extra["raster_passes"], tp.extra["waterline_passes"]
    assert tp.strategy == "steep_shallow" and nr > 0 and nw > 0
    assert len(tp.passes) == nr + nw == len(tp.links) + 1
    edge = 12.5 + R * math.sin(math.radians(45.0))  # tip |x - 20| where the contact is at 45
    grow = tp.parameters["overlap"] + 2 * tp.extra["split"].grid.cell
    assert max(np.abs(p[:, 0] - 20.0).max() for p in tp.passes[:nr]) <= edge + grow
    assert min(np.abs(p[:, 0] - 20.0).min() for p in tp.passes[nr:]) >= edge - grow
    assert all(np.ptp(p[:, 2]) == 0.0 for p in tp.passes[nr:])
    assert_above_drop(fs, tp)
    sim, design, _f, found, X, Y = simulated(fs, tp, (-4.0, 44.0, -4.0, 44.0))
    np.testing.assert_allclose(design[found], ridge_z(X[found], Y[found]), atol=1e-9)
    assert_no_gouge(sim, design, found)
    inner = found & (np.abs(X - 20.0) < 16.0) & (Y > R) & (Y < 40.0 - R)
    assert inner.sum() > 50000
    assert (sim - design)[inner].max() <= H + TOL, (sim - design)[inner].max()


def test_faces_steep_shallow_bad_threshold():
    from BSplineCAM.core.toolpath import generate_faces

    ns = plane(0.0, 10.0, 0.0, 10.0, 0.0)
    for bad in (0.0, 90.0, float("nan")):
        with pytest.raises(ParameterError, match="threshold_deg"):
            generate_faces(FaceSet([Face(ns, rectangle(ns))]), "steep_shallow", D, H, TOL,
                           threshold=bad)


def test_iso_partial_passes_ignore_rounding_of_the_trim():
    """Faces whose trim box's sides are trim edges (the part's top between its side walls),
    and the same faces with those edges' vertices moved by rounding (1e-15, as a FreeCAD
    document saved and reopened gives) get the same partial passes.  (A probe column on the
    box's side ran along the edge, in or out by rounding: 214 passes on the part, 212 once
    reopened.)"""
    ns = plane(0.0, 40.0, 0.0, 40.0, 1.5)

    def faces(seed):
        rng = np.random.default_rng(seed)

        def side(u, v0, v1):  # a straight side in 20 pieces, its vertices off by rounding
            v = np.linspace(v0, v1, 21)
            jitter = np.zeros(21) if seed is None else rng.uniform(-1e-15, 1e-15, 21)
            return np.column_stack([u + jitter, v])

        lower = np.vstack([side(0.1, 0.4, 0.0), side(0.9, 0.0, 0.55), [[0.1, 0.4]]])
        upper = np.vstack([side(0.1, 1.0, 0.4), side(0.9, 0.55, 1.0), [[0.1, 1.0]]])
        return FaceSet([Face(ns, lower, index=1), Face(ns, upper, index=2)])

    runs = []
    for seed in (None, 1, 2, 3):
        tp = generate_faces_iso(faces(seed), D, H, TOL)
        runs.append(([v["edge_curves"] for v in tp.extra["faces"].values()], len(tp.passes)))
    assert runs[0][0][0] > 0
    assert all(r == runs[0] for r in runs), runs


def test_iso_curves_on_the_parts_fillet_ignore_rounding_of_the_trim():
    """examples/part.step's fillet (Face3) machined alone, with every trim vertex of the model
    moved by rounding (2e-16 relative, as a FreeCAD document saved and reopened gives): the
    iso-curves stay within 1e-6 mm (about 2e-8 mm; with a probe at each end of a curve, on
    the trim box's sides, they would move by 4e-6 mm, enough for the part's program reopened
    in FreeCAD 1.1 to have another number of commands)."""
    pytest.importorskip("OCP")
    import dataclasses

    from BSplineCAM.ocp import faces as ocp

    faces = ocp.faces_from_shape(ocp.read_part(ROOT / "examples" / "part.step"), "up",
                                 tolerance=0.002)

    def passes(rng):
        def moved(a):
            return a if rng is None else a * (1.0 + rng.uniform(-2e-16, 2e-16, a.shape))

        fs = FaceSet([dataclasses.replace(f, outer=moved(f.outer),
                                          holes=tuple(moved(h) for h in f.holes),
                                          selected=f.index == 3) for f in faces])
        return generate_faces_iso(fs, D, 0.2, 0.002).passes

    first, other = passes(None), passes(np.random.default_rng(1))
    assert len(first) > 50
    assert [len(p) for p in other] == [len(p) for p in first]
    assert max(float(np.abs(a - b).max()) for a, b in zip(first, other)) < 1e-6


def test_iso_on_a_part_whose_walls_come_before_its_selected_faces():
    """A 30 x 20 x 10 mm box with a 4 mm fillet along one top edge (cadquery's OCCT): its
    vertical sides, unselected, precede the top and the fillet in the face list and enter the
    drop-cutter by their borders only.  Each selected face gets its own passes, inside its
    trim and never below the drop height: its trim test is the face's own, not the one at its
    position among the faces that are not walls (an IndexError on such a part)."""
    cq = pytest.importorskip("cadquery")
    from BSplineCAM.ocp import faces as ocp

    box = cq.Workplane().box(30, 20, 10, centered=False)
    box = box.edges(cq.selectors.BoxSelector((-1, -1, 9.9), (31, 0.1, 10.1))).fillet(4.0)
    faces = ocp.faces_from_shape(box.val().wrapped, "up", tolerance=0.01)
    fs = FaceSet(faces)
    chosen = [k for k, f in enumerate(faces) if f.selected]
    walls = set(fs.walls.owner.tolist())
    assert len(chosen) == 2 and any(w < min(chosen) for w in walls)
    for direction in ("u", "v"):
        tp = generate_faces_iso(fs, D, 0.2, 0.01, direction=direction)
        per_face = tp.extra["faces"]
        assert sorted(per_face) == sorted(faces[k].name for k in chosen)
        assert all(v["passes"] > 0 for v in per_face.values()), per_face
        assert_above_drop(fs, tp)
        verts = np.concatenate(tp.passes)
        assert verts[:, 1].min() >= -R - 1e-6 and verts[:, 2].max() <= 10.0 + 0.01  # tolerance
        # along the passes the ball rests on the selected faces (at the box's ends x = 0
        # and 30 it ties with the walls' top edges)
        pts = np.concatenate([p[:-1] + t * np.diff(p, axis=0) for p in tp.passes
                              for t in np.linspace(0.05, 0.95, 10)])
        inner = (pts[:, 0] > 0.5) & (pts[:, 0] < 29.5)
        assert inner.sum() > 100
        assert fs.drop_ball(pts[inner, :2], R)[4].mean() > 0.99
    with pytest.raises(IndexError, match="wall"):
        fs.trim_test(min(walls))


def test_iso_on_a_spherical_dimple_whose_iso_curve_shrinks_to_its_pole(monkeypatch):
    """A 60 x 40 x 20 mm block with a spherical dimple of radius 15 mm (cadquery's OCCT, as
    a STEP file has it): OCCT's NURBS of the sphere has one side of its domain at the pole,
    where the iso-curve is a point.  Its normal curvature there is 0/0, which would allow a
    step of 1e-16 between iso-curves (the spacing creeping by 1e-9 of the domain forever).  A
    curve shrunk to a point sets no step; the dimple gets a bounded number of passes, all on
    its faces and never below the drop height."""
    cq = pytest.importorskip("cadquery")
    from BSplineCAM.core.toolpath import faces_iso
    from BSplineCAM.ocp import faces as ocp

    block = cq.Workplane().box(60, 40, 20, centered=False)
    sphere = cq.Solid.makeSphere(15, cq.Vector(30, 20, 30), angleDegrees1=-90, angleDegrees2=90)
    part = block.cut(cq.Workplane().add(sphere))
    faces = ocp.faces_from_shape(part.val().wrapped, "up", tolerance=0.01)
    fs = FaceSet(faces)
    assert any(f.selected and "Sphere" in f.source for f in faces)
    asked = [0]
    step = faces_iso._allowed_step

    def counted(*args):
        asked[0] += 1
        if asked[0] > 5000:
            raise AssertionError("iso-curves without end")
        return step(*args)

    monkeypatch.setattr(faces_iso, "_allowed_step", counted)
    tp = generate_faces_iso(fs, D, 0.2, 0.01)
    sphere_face = next(f.name for f in faces if "Sphere" in f.source)
    assert tp.extra["faces"][sphere_face]["passes"] > 0
    assert_above_drop(fs, tp)
    verts = np.concatenate(tp.passes)
    dimple = np.hypot(verts[:, 0] - 30, verts[:, 1] - 20) < 10.0
    # in the dimple the ball rests on the sphere: tip at 30 - sqrt((15 - R)^2 - r^2) - R
    r = np.hypot(verts[dimple, 0] - 30, verts[dimple, 1] - 20)
    np.testing.assert_allclose(verts[dimple, 2], 30 - np.sqrt((15 - R) ** 2 - r * r) - R,
                               atol=0.011)


def test_iso_leaves_a_fillet_the_ball_fits_and_says_so():
    """The 3 mm fillet round a boss's foot on a plate: a 6 mm ball fits it across, so every
    iso-curve's cutter locations (p + R n) fall on the fillet's axis circle.  On a real boss
    that circle lies on the wall's edge at the ball's rim, where the drop height jumps by the
    wall's height: cutting it once per curve takes over 15 minutes on a STEP boss.  The
    fillet is left with a note naming it; a 5 mm ball, which does not fit, machines it."""
    fs = FaceSet([plate_with_hole(), fillet_ring()])
    six = generate_faces_iso(fs, 6.0, 0.1, TOL)
    ring = six.extra["faces"]["Face2"]
    assert ring["passes"] == 0 and ring["chord_lift"]["collapsed"]
    assert six.extra["faces"]["Face1"]["passes"] > 0
    assert any("fits Face2 across" in n and "raster or waterline" in n for n in six.stats.notes)
    five = generate_faces_iso(fs, 5.0, 0.1, TOL)
    assert five.extra["faces"]["Face2"]["passes"] > 0
    assert not any("fits" in n for n in five.stats.notes)
