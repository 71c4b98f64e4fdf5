# SPDX-License-Identifier: LGPL-2.1-or-later
"""Links between passes (issue 44, item 3): minimum retracts (hops) that clear the model and
the stock by their margin, checked against closed forms and brute force, and contours cut in
the order of short moves, upper levels first."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_helpers import assert_above_drop, plane, rectangle, revolved_face

from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.measures import program_measures, toolpath_lengths
from BSplineCAM.core.toolpath import generate_faces, to_moves
from BSplineCAM.core.toolpath.common import Toolpath, ToolpathStats
from BSplineCAM.core.toolpath.faceset import FaceSet
from BSplineCAM.core.toolpath.order import is_closed, order_contours
from BSplineCAM.core.toolpath.retracts import (
    Hops,
    StockMap,
    faces_hops,
    hop_heights,
    model_bound,
)

R = 3.0
RHO, CX, CY, BASE = 8.0, 30.0, 20.0, 2.0


def dome_on_plate():
    """A hemisphere of radius RHO centred at (CX, CY, BASE) on a check plate at BASE."""
    c = math.sqrt(0.5)
    dome = revolved_face([(RHO, BASE), (RHO, BASE + RHO), (0.0, BASE + RHO)], [1.0, c, 1.0],
                         (CX, CY), 1, "Sphere")
    plate = plane(0.0, 60.0, 0.0, 40.0, BASE)
    return [dome, Face(plate, rectangle(plate), index=2, selected=False)]


def exact_tip(xy: np.ndarray, radius: float = R) -> np.ndarray:
    """The ball's tip height over the dome on its plate, in closed form."""
    d = np.hypot(xy[:, 0] - CX, xy[:, 1] - CY)
    over = np.sqrt(np.maximum((RHO + radius) ** 2 - d * d, 0.0)) - radius
    return BASE + np.where(d < RHO + radius, np.maximum(over, 0.0), 0.0)


@pytest.fixture(scope="module")
def dome():
    return FaceSet(dome_on_plate())


def test_model_bound_is_above_the_exact_height_and_close_to_it(dome):
    rng = np.random.default_rng(7)
    a = rng.uniform([5, 5], [55, 35], (12, 2))
    b = rng.uniform([5, 5], [55, 35], (12, 2))
    reach = 0.5
    bound = model_bound(lambda xy, r: dome.drop_ball(xy, r)[0], a, b, R, reach, 1e-4)
    t = np.linspace(0.0, 1.0, 4001)
    for k in range(len(a)):
        line = a[k] + t[:, None] * (b[k] - a[k])
        top = exact_tip(line).max()
        assert bound[k] >= top - 1e-9
        # no higher than the larger ball's top along the line, plus the reach: on a flat and
        # over the dome's top the reach above the true top, on the dome's flank more
        assert bound[k] <= exact_tip(line, R + reach).max() + reach + 1e-3
    over = model_bound(lambda xy, r: dome.drop_ball(xy, r)[0], np.array([[5.0, CY]]),
                       np.array([[55.0, CY]]), R, reach, 1e-4)
    assert BASE + RHO + reach - 1e-6 <= over[0] <= BASE + RHO + reach + 1e-3


def brute_top_near(m: StockMap, a, b, reach):
    ny, nx = m.height.shape
    xs = m.x0 + (np.arange(nx) + 0.5) * m.cell
    ys = m.y0 + (np.arange(ny) + 0.5) * m.cell
    px, py = np.meshgrid(xs, ys)
    d = b - a
    dd = float(d @ d)
    t = np.zeros_like(px) if dd == 0 else np.clip(((px - a[0]) * d[0] + (py - a[1]) * d[1]) / dd, 0, 1)
    near = np.hypot(px - a[0] - t * d[0], py - a[1] - t * d[1]) <= reach
    return m.height[near].max() if near.any() else -np.inf


def test_stock_top_near_a_segment_is_the_brute_force_maximum():
    rng = np.random.default_rng(3)
    m = StockMap(-3.0, 2.0, 0.7, rng.uniform(0, 10, (40, 50)))
    a = rng.uniform([-10, -5], [40, 35], (30, 2))
    b = a + rng.uniform(-8, 8, (30, 2))
    b[0] = a[0]  # a point
    got = m.top_near(a, b, 2.5)
    want = [brute_top_near(m, p, q, 2.5) for p, q in zip(a, b)]
    assert np.array_equal(got, want)


def two_passes(z=2.0):
    """Two short passes on the plate on either side of the dome: the link crosses it."""
    p1 = np.array([[5.0, 20.0, z], [12.0, 20.0, z]])
    p2 = np.array([[48.0, 20.0, z], [55.0, 20.0, z]])
    return [p1, p2]


def toolpath_of(passes, links=None, clearance=40.0):
    tp = Toolpath("raster", passes, {"tool_diameter": 2 * R, "tolerance": 0.01}, [],
                  ToolpathStats(), links=links or [None] * (len(passes) - 1))
    return tp.finish(0.0, clearance)


def test_a_hop_clears_the_dome_by_its_margin_and_not_the_clearance(dome):
    tp = toolpath_of(two_passes())
    hops = faces_hops(tp, dome, tp.clearance_height, margin=1.0)
    top = BASE + RHO
    assert top + 1.0 <= hops.travel[0] <= top + 1.0 + 0.8
    assert hops.approach[0] == pytest.approx(BASE + 1.0)
    moves = to_moves(tp, hops=hops)
    rapids = [m for m in moves if m.kind == "rapid"]
    # out to clearance, down to the first approach; then the hop: up, across, down; then out
    assert [round(m.z, 6) for m in rapids[2:5]] == [round(hops.travel[0], 6)] * 2 + [BASE + 1.0]
    assert max(m.z for m in rapids[2:5]) < tp.clearance_height
    # every rapid and feed of the program stays above the ball's exact height along it
    pts = np.array([[m.x, m.y, m.z] for m in moves])
    for p, q in zip(pts[:-1], pts[1:]):
        line = p + np.linspace(0, 1, 801)[:, None] * (q - p)
        assert np.all(line[:, 2] >= exact_tip(line[:, :2]) - 1e-9)
    full = to_moves(tp)
    def length(ms):
        xyz = np.array([[m.x, m.y, m.z] for m in ms])
        return np.linalg.norm(np.diff(xyz, axis=0), axis=1).sum()
    assert length(moves) < length(full) - 2 * (tp.clearance_height - hops.travel[0]) + 1e-6


def test_a_hop_clears_the_stock_left_and_lands_above_it(dome):
    tp = toolpath_of(two_passes())
    height = np.full((40, 60), BASE + 0.5)
    height[15:25, 20:40] = 16.0  # a column of stock left over the dome
    height[18:22, 46:50] = 9.0   # and stock beside the second pass's start
    stock = StockMap(0.0, 0.0, 1.0, height)
    hops = faces_hops(tp, dome, tp.clearance_height, margin=1.0, stock=stock)
    assert hops.travel[0] >= 16.0 + 1.0
    assert hops.approach[0] == pytest.approx(9.0 + 1.0)
    # stock above the clearance less the margin: the tool climbs to the clearance
    height[15:25, 20:40] = 39.5
    hops = faces_hops(tp, dome, tp.clearance_height, 1.0, StockMap(0.0, 0.0, 1.0, height))
    assert np.isnan(hops.travel[0])
    assert [m.z for m in to_moves(tp, hops=hops) if m.kind == "rapid"].count(40.0) >= 3


def test_linked_gaps_do_not_hop_and_a_wrong_length_is_refused(dome):
    p = two_passes()
    link = np.array([p[0][-1], p[1][0]])
    tp = toolpath_of(p, [link])
    hops = hop_heights(tp.passes, tp.links, lambda xy, r: dome.drop_ball(xy, r)[0], R, 40.0)
    assert np.isnan(hops.travel).all()
    with pytest.raises(ParameterError, match="hops"):
        to_moves(toolpath_of(two_passes()), hops=Hops(np.zeros(3), np.zeros(3)))


def square(c, half, z, n=8):
    t = np.linspace(0, 1, n, endpoint=False)
    side = [np.column_stack([c[0] - half + 2 * half * t, np.full(n, c[1] - half)]),
            np.column_stack([np.full(n, c[0] + half), c[1] - half + 2 * half * t]),
            np.column_stack([c[0] + half - 2 * half * t, np.full(n, c[1] + half)]),
            np.column_stack([np.full(n, c[0] - half), c[1] + half - 2 * half * t])]
    ring = np.concatenate(side)
    ring = np.vstack([ring, ring[:1]])
    return np.column_stack([ring, np.full(len(ring), z)])


def signed_area(p):
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]))


def test_contours_go_feature_by_feature_top_down_entered_nearest():
    # two bosses 60 mm apart, five levels each, given level by level (as waterline makes them)
    levels = [10.0, 8.0, 6.0, 4.0, 2.0]
    given = []
    for z in levels:
        given.append(square((0, 0), 10 + (10 - z), z))
        given.append(square((60, 0), 10 + (10 - z), z))
    out = order_contours(given, 6.0)
    centres = [round(float(p[:-1, 0].mean())) for p in out]
    assert centres == [0] * 5 + [60] * 5
    for group in (out[:5], out[5:]):
        assert [p[0, 2] for p in group] == levels
    for p in out:
        assert is_closed(p)
        assert signed_area(p) > 0  # the loops keep their direction
    # each loop entered at its vertex nearest where the last one ended
    for prev, p in zip(out[:-1], out[1:]):
        same = [q for q in given if q[0, 2] == p[0, 2] and abs(q[:-1, 0].mean() - p[:-1, 0].mean()) < 1]
        ring = same[0][:-1]
        assert np.linalg.norm(p[0] - prev[-1]) == pytest.approx(
            np.linalg.norm(ring - prev[-1], axis=1).min())
    # the same points, each loop once
    assert sorted(round(float(abs(signed_area(p))), 6) for p in out) == \
        sorted(round(float(abs(signed_area(p))), 6) for p in given)


def test_open_contours_run_back_and_forth_when_reversible():
    given = [np.array([[0.0, y, 10 - y], [50.0, y, 10 - y]]) for y in range(5)]
    kept = order_contours(given, 6.0)
    assert all(p[0, 0] == 0.0 for p in kept)
    both = order_contours(given, 6.0, reversible=True)
    assert [p[0, 0] for p in both] == [0.0, 50.0, 0.0, 50.0, 0.0]
    assert [p[0, 2] for p in both] == [10.0, 9.0, 8.0, 7.0, 6.0]


def ring_wall_faces():
    """A round boss's vertical-ish wall (a cone, 70 degrees) on a check plate: waterline
    contours all around it."""
    profile = [(14.0, 2.0), (14.0 - 8.0 / math.tan(math.radians(70)), 10.0)]
    cone = revolved_face(profile, None, (30.0, 20.0), 1, "Cone")
    top = revolved_face([(14.0 - 8.0 / math.tan(math.radians(70)), 10.0), (0.0, 10.0)], None,
                        (30.0, 20.0), 3, "Disc")
    top = Face(top.surface, top.outer, index=3, selected=False)
    plate = plane(0.0, 60.0, 0.0, 40.0, 2.0)
    return [cone, Face(plate, rectangle(plate), index=2, selected=False), top]


def test_waterline_contours_are_linked_down_the_wall_and_the_program_is_shorter():
    faces = ring_wall_faces()
    fs = FaceSet(faces)
    tp = generate_faces(fs, "waterline", 6.0, 0.05, 0.01)
    assert len(tp.passes) >= 5
    linked = sum(lk is not None for lk in tp.links)
    assert linked == len(tp.passes) - 1  # one wall: every contour follows the one above
    levels = [p[0, 2] for p in tp.passes]
    assert levels == sorted(levels, reverse=True)
    text = "\n".join(["G21 G90"] + [
        f"{'G0' if m.kind == 'rapid' else 'G1'} X{m.x:.4f} Y{m.y:.4f} Z{m.z:.4f}"
        + ("" if m.kind == "rapid" else " F1000") for m in to_moves(tp)] + ["M2"]) + "\n"
    program = read_gcode(text, "waterline")
    figures = program_measures(program, toolpath_lengths(tp)["along_passes_mm"])
    # the air is one approach and one retract, not one per contour
    assert figures["rapid_length_mm"] < 4 * (tp.clearance_height - 2.0) + 60.0
    # the links' straight moves stay above the certified drop-cutter height along them
    assert_above_drop(fs, tp)
    for lk in tp.links:
        for p, q in zip(lk[:-1], lk[1:]):
            line = p + np.linspace(0, 1, 41)[:, None] * (q - p)
            drop = fs.drop_ball(line[:, :2], R)[0]
            ok = np.isfinite(drop)
            assert np.all(line[ok, 2] >= drop[ok] - 1e-7)


def circle_loop(r, z, ccw=True, n=64):
    t = np.linspace(0.0, 2 * np.pi, n + 1)
    t[-1] = 0.0
    if not ccw:
        t = -t
    return np.column_stack([r * np.cos(t), r * np.sin(t), np.full(n + 1, z)])


def test_climb_puts_the_material_on_the_right():
    """A boss (height falling outwards): its loops run clockwise; a pocket (height rising
    outwards): counter-clockwise; an open contour along a wall: the wall on its right."""
    from BSplineCAM.core.toolpath.order import orient_climb

    boss = lambda xy: 10.0 - np.hypot(xy[:, 0], xy[:, 1])  # noqa: E731
    pocket = lambda xy: np.hypot(xy[:, 0], xy[:, 1])  # noqa: E731
    loops = [circle_loop(5.0, 5.0, True), circle_loop(4.0, 6.0, False)]
    assert all(signed_area(p) < 0 for p in orient_climb(loops, boss, 0.1))
    # the pocket's waterlines at its own levels (h = r)
    loops = [circle_loop(5.0, 5.0, True), circle_loop(4.0, 4.0, False)]
    assert all(signed_area(p) > 0 for p in orient_climb(loops, pocket, 0.1))
    wall = lambda xy: np.where(xy[:, 1] > 0.0, 5.0 + xy[:, 1], np.nan)  # noqa: E731
    line = np.array([[0.0, 0.0, 5.0], [10.0, 0.0, 5.0]])
    (out,) = orient_climb([line], wall, 0.1)
    assert out[0, 0] == 10.0  # running -x, the wall (+y) on its right
    (kept,) = orient_climb([line[::-1]], wall, 0.1)
    assert kept[0, 0] == 10.0


def test_waterline_contours_around_a_boss_run_climb():
    fs = FaceSet(ring_wall_faces())
    for direction in ("oneway", "zigzag"):
        tp = generate_faces(fs, "waterline", 6.0, 0.2, 0.01, direction=direction)
        loops = [p for p in tp.passes if is_closed(p)]
        assert loops, direction
        assert all(signed_area(p) < 0 for p in loops), direction
