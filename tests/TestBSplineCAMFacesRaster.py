# SPDX-License-Identifier: LGPL-2.1-or-later
"""Raster finishing of trimmed and several faces (core/toolpath/faces_raster.py), measured by
simulating the G-code text against the exact faces."""

from __future__ import annotations

import time

import numpy as np
from bsplinecam_helpers import fillet_ring, gcode, plate_with_hole, two_faces

from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.simulate import Grid, Tool, simulate_program
from BSplineCAM.core.toolpath.faces_raster import generate_faces_raster
from BSplineCAM.core.toolpath.faceset import FaceSet


def test_raster_of_trimmed_face_simulated():
    faces = two_faces()
    fs = FaceSet(faces)
    D, h, tol = 6.0, 0.05, 0.01
    t0 = time.perf_counter()
    tp = generate_faces_raster(fs, D, h, tol)
    print("raster", time.perf_counter() - t0, tp.extra["chord_lift"], tp.extra["dropcutter"])
    assert tp.passes
    # passes only where the contact lies on the selected face
    verts = np.concatenate(tp.passes)
    _t, _f, _u, _v, on_sel = fs.drop_ball(verts[:, :2], D / 2)
    assert on_sel.mean() > 0.99
    program = read_gcode(gcode(tp))
    grid = Grid.covering(0.0, 32.0, 0.0, 24.0, 0.2)
    sim = simulate_program(program, Tool(D), grid, top=5.0)
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    z, fidx, _u, _v, found = fs.height(np.column_stack([X.ravel(), Y.ravel()]), False)
    design = z.reshape(X.shape)
    found = found.reshape(X.shape)
    assert found.mean() > 0.9
    gouge = np.where(found, design - sim.height, -np.inf)
    assert gouge.max() <= 1e-3, gouge.max()
    # scallop on the selected face away from its borders (one tool radius)
    R = D / 2
    far = ((X > R) & (X < 24 - R) & (Y > R) & (Y < 24 - R)
           & (np.hypot(X - 12, Y - 12) > 0.12 * 24 + R))
    far &= found & (fidx.reshape(X.shape) == 0)
    assert far.sum() > 500
    scallop = (sim.height - design)[far]
    assert scallop.max() <= h + tol + 1e-3, scallop.max()


def _max_departure(f, df, x0, x1, n=2001):
    """Largest |f - chord| on [x0, x1] by dense sampling, and the Hermite bound there."""
    from BSplineCAM.core.toolpath.faces_raster import _hermite_departure

    x = np.linspace(x0, x1, n)
    chord = f(x0) + (x - x0) / (x1 - x0) * (f(x1) - f(x0))
    true = float(np.abs(f(x) - chord).max())
    a = np.array([x0, x1])
    gentle, dep = _hermite_departure(a, f(a), df(a), np.ones(2, bool), np.array([0]))
    return true, float(dep[0]), bool(gentle[0])


def test_hermite_departure_bounds_smooth_heights_and_kinks():
    """The model's departure from the chord bounds the true one for smooth heights (circles
    of the ball's radius, a cubic, a sine over a sample step), is within 1.7x of a concave
    corner's kink, and flags a wall between two gentle samples."""
    R = 3.0
    circle = (lambda x: np.sqrt(R * R - x * x), lambda x: -x / np.sqrt(R * R - x * x))
    valley = (lambda x: -np.sqrt(R * R - x * x), lambda x: x / np.sqrt(R * R - x * x))
    cubic = (lambda x: 0.01 * x ** 3 - 0.2 * x, lambda x: 0.03 * x ** 2 - 0.2)
    sine = (lambda x: 0.5 * np.sin(2 * x), lambda x: np.cos(2 * x))
    step = 0.22  # sqrt(8 R tol) at R = 3, tol = 0.002
    for f, df in (circle, valley, cubic, sine):
        for x0 in np.linspace(-2.5, 2.2, 15):
            true, dep, gentle = _max_departure(f, df, x0, x0 + step)
            assert dep >= true * (1 - 1e-9), (x0, true, dep)
            assert dep <= 1.6 * true + 1e-12, (x0, true, dep)  # not loose either
    # a V (concave corner) anywhere in the interval
    for kink in np.linspace(0.01, 0.21, 9):
        v = (lambda x, k=kink: np.where(x < k, -0.7 * (x - k), 1.3 * (x - k)),
             lambda x, k=kink: np.where(x < k, -0.7, 1.3))
        true, dep, _ = _max_departure(*v, 0.0, step)
        assert 1.7 * dep >= true, (kink, true, dep)
    # a 2 mm wall between two flat samples: both slopes 0, the chord's slope 9
    wall = (lambda x: np.where(x < 0.1, 0.0, 2.0), lambda x: np.zeros_like(x))
    _true, dep, _ = _max_departure(*wall, 0.0, step)
    assert dep > 0.5


def test_modelled_midpoints_leave_the_passes_unchanged(monkeypatch):
    """With the Hermite model standing in for exact midpoints the passes are the same as with
    every midpoint asked of the drop-cutter (MODEL_SHARE = 0), for fewer queries."""
    from BSplineCAM.core.toolpath import faces_raster

    counts = {}

    def run(label):
        fs = FaceSet(two_faces())
        n = [0]
        drop = fs.drop_ball

        def counted(xy, *a, **k):
            n[0] += len(np.asarray(xy).reshape(-1, 2))
            return drop(xy, *a, **k)

        fs.drop_ball = counted
        tp = generate_faces_raster(fs, 6.0, 0.05, 0.01)
        counts[label] = n[0]
        return tp.passes

    modelled = run("model")
    monkeypatch.setattr(faces_raster, "MODEL_SHARE", 0.0)
    exact = run("exact")
    assert len(modelled) == len(exact)
    for p, q in zip(modelled, exact):
        assert p.shape == q.shape
        assert np.abs(p - q).max() <= 1e-9
    assert counts["model"] < 0.8 * counts["exact"], counts


def test_a_ball_in_a_fillet_of_its_radius_is_dropped_in_bounded_work(monkeypatch):
    """A 6 mm ball centred over the axis circle of the 3 mm fillet round a boss's foot touches
    the whole quarter circle of its cross-section: the maximum is tied along it, no bound
    separates the sub-patches there, and a branch and bound keeping MAX_OPEN of them open at
    every level down to MAX_DEPTH costs about 9 700 pairs a query (over 15 minutes for a
    boss's iso passes, which lie on that circle).  A query crowded for MAX_CROWDED levels is
    given up with its gap reported; the height is the closed form's (the fillet's axis circle,
    13 mm) and queries off the circle stay certified."""
    from BSplineCAM.core.toolpath import faceset as fsm

    def drop(r):
        fs = FaceSet([plate_with_hole(), fillet_ring()])
        a = np.linspace(0.1, 1.4, 16)
        q = np.column_stack([20 + r * np.cos(a), 20 + r * np.sin(a)])
        res = fs.centre_heights(q, 3.0)
        return res, fs.stats["pairs"] / len(q)

    on, pairs = drop(15.0)
    np.testing.assert_allclose(on.centre, 13.0, atol=fsm.CERTIFY)
    assert pairs < 4000, pairs
    assert np.all(on.gap > fsm.CERTIFY)  # said, not hidden
    off, _ = drop(15.1)
    np.testing.assert_allclose(off.centre, 13.0, atol=fsm.CERTIFY)
    assert np.all(off.gap == 0.0)
    monkeypatch.setattr(fsm, "MAX_CROWDED", fsm.MAX_DEPTH + 1)
    assert drop(15.0)[1] > 8000


def test_a_fillet_the_ball_fits_bounds_no_stepover():
    """A plate and the 3 mm fillet round a boss's foot, machined with a 6 mm ball: the fillet's
    cross-sections along the passes are hollows the ball fits, whose contacts' centres all
    crowd at one point; they bound no stepover, so the lines lie about the flat stepover
    apart (bounded by the fillet, 0.05 mm apart across the whole plate: 50 times the path), and the
    lines that cross the fillet fill it.  A 5 mm ball (a 2.5 mm radius in a 3 mm hollow) keeps
    its bound there."""
    from BSplineCAM.core.toolpath.common import ToolParameters
    from BSplineCAM.core.toolpath.faces_raster import _stepover_field
    from BSplineCAM.core.toolpath.raster import cross_section_stepover, scallop_line_offsets

    fs = FaceSet([plate_with_hole(), fillet_ring()])
    along, across = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    tool = ToolParameters.validate(6.0, 0.1, 0.002)
    b, allowed, _ = _stepover_field(fs, tool, along, across)
    lines = scallop_line_offsets(b, allowed, -3.0, 43.0, tool, 0.5 * tool.flat_stepover)
    flat_lines = 46.0 / tool.flat_stepover
    assert len(lines) < 1.3 * flat_lines, (len(lines), flat_lines)
    # the bound itself: a hollow of the ball's radius, or a little wider, bounds nothing; one
    # a fifth wider than the ball does
    up = np.array([[0.0, 0.0, 1.0]] * 3)
    kappa = np.array([1 / 3.0, 1 / 3.1, 1 / 3.6])
    s = cross_section_stepover(3.0, 0.1, kappa, up, across, along)
    assert np.isinf(s[:2]).all() and 0 < s[2] < 2.0
