# SPDX-License-Identifier: LGPL-2.1-or-later
"""The faces waterline where the drop height has no face under the ball or jumps past a level
(core/toolpath/faces_waterline.py polish_crossings, waterline.py push_out): crossings next to
"no face" converge onto their level, a jump (the ball leaving the model over an edge) is kept
on its air side, and the contours along a wall that drops to no face follow the wall's exact
offset without the ball ever standing below the drop height.  Measured against closed forms
(a ball beside a plate's edge, a ball beside a tube's rim).  With the height's slopes
(``slopes``) the polish takes Newton steps where the height is smooth and a dyadic bisection
where it jumps: the points land as without, in fewer queries, and the levels a jump crosses
on one grid edge share their queries."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_helpers import cylinder_quarter, plane, rectangle

from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.toolpath import faces_waterline
from BSplineCAM.core.toolpath.faces_waterline import (
    FALSI_STEPS,
    generate_faces_waterline,
    polish_crossings,
)
from BSplineCAM.core.toolpath.faceset import FaceSet

R = 3.0
TOP = 5.0  # mm, the plate's height
EDGE = 20.0  # mm, x of the plate's edge
CELL = 0.75  # mm, the grid edge of the waterline (R / 4)
EPS = 2e-6  # mm, tolerance / 1000 of the CLI's default
WIDTH = 2.5e-4  # mm, tolerance / 8 of the CLI's default
RHO, HEIGHT = 10.0, 10.0  # mm, the tube's radius and height
FLOOR = 25.0  # mm, the floor below the plate's top


def plate() -> FaceSet:
    ns = plane(0.0, EDGE, 0.0, 20.0, TOP)
    return FaceSet([Face(ns, rectangle(ns))])


def beside_edge(d: np.ndarray) -> np.ndarray:
    """Closed form: tip height of the ball whose axis stands d mm beyond the plate's edge
    (resting on the edge, NaN past R: nothing under the ball)."""
    return np.where(d <= R, TOP - R + np.sqrt(np.clip(R * R - d * d, 0.0, None)), np.nan)


def jump_edges(rng, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``n`` grid edges (one CELL long, along x) across the plate's edge whose far end lies
    beyond the ball's reach: the height jumps on each."""
    end_d = R + rng.uniform(1e-4, 0.74, n)
    y = rng.uniform(5.0, 15.0, n)
    return (np.column_stack([EDGE + end_d - CELL, y]), np.column_stack([EDGE + end_d, y]))


def tube() -> FaceSet:
    """A vertical circular tube (radius RHO, from z = 0 to HEIGHT, axis on z), open at both
    ends, nothing around it: an exact rational quadratic circle ("The NURBS Book" sec. 7.5,
    nine poles) extruded along z, u counter-clockwise so that Su x Sv points outwards."""
    c = math.sqrt(0.5)
    ring = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0)]
    w = [1.0, c, 1.0, c, 1.0, c, 1.0, c, 1.0]
    poles = np.array([[[RHO * x, RHO * y, z] for z in (0.0, HEIGHT)] for x, y in ring])
    weights = np.array([[wi, wi] for wi in w])
    knots = [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]
    ns = NurbsSurface(poles, knots, [0, 0, 1, 1], 2, 1, weights=weights)
    return FaceSet([Face(ns, rectangle(ns))])


def beside_tube(xy: np.ndarray) -> np.ndarray:
    """Closed form: tip height of the ball over the tube, resting on its top rim (the highest
    point within R of the axis is the rim's nearest point), NaN where the ball misses the
    tube (more than R from the wall on either side)."""
    d = np.abs(np.hypot(xy[:, 0], xy[:, 1]) - RHO)
    return np.where(d < R, HEIGHT - R + np.sqrt(np.clip(R * R - d * d, 0.0, None)), np.nan)


class Counted:
    """The plate's drop-cutter tip heights, counting the calls (one per polish iteration)."""

    def __init__(self, fs: FaceSet):
        self.fs, self.calls = fs, 0

    def __call__(self, xy):
        self.calls += 1
        return self.fs.drop_ball(xy, R)[0]


@pytest.mark.parametrize("flip", [False, True])
@pytest.mark.parametrize("where", ["anywhere", "last 1/32 of the edge"])
def test_crossing_beside_no_face_converges_to_the_level(flip, where):
    """Levels whose crossing lies between a corner with a face and one without: every point
    lands within EPS of its level, at the closed-form place, within the step budget.  (The
    former stand-in value -1e9 for "no face", halved by the Illinois rule, turned the search
    from bisection into a secant pulled onto the no-face end: crossings stalled there.)"""
    rng = np.random.default_rng(11 + flip)
    n = 200
    if where == "anywhere":
        end_d = R + rng.uniform(1e-4, 0.74, n)
        d_cross = np.clip(end_d - CELL * rng.uniform(0.02, 0.98, n), 0.05, R - 1e-3)
    else:
        d_cross = R - rng.uniform(0.005, 0.02, n)
        end_d = np.maximum(d_cross + CELL * rng.uniform(0.0, 1.0 / 32.0, n), R + 1e-6)
    start = np.maximum(end_d - CELL, 0.0)
    y = rng.uniform(5.0, 15.0, n)
    p0, p1 = np.column_stack([EDGE + start, y]), np.column_stack([EDGE + end_d, y])
    if flip:
        p0, p1 = p1, p0
    level = beside_edge(d_cross)
    drop = Counted(plate())
    z0, z1 = beside_edge(p0[:, 0] - EDGE), beside_edge(p1[:, 0] - EDGE)
    assert np.isnan(z1 if not flip else z0).all()  # every edge has its no-face end
    heard = []
    t, jump, _t_up, settled = polish_crossings(drop, p0, p1, z0, z1, level, EPS, WIDTH,
                                               progress=heard.append)
    assert settled.all() and not jump.any()
    # the progress bar hears the share settled before each round and once all are
    assert len(heard) == drop.calls + 1 and heard[-1] == 1.0
    assert np.all(np.diff(heard) >= 0) and heard[0] < 1.0
    xy = p0 + t[:, None] * (p1 - p0)
    d = xy[:, 0] - EDGE
    z = beside_edge(d)
    assert np.all(np.abs(z - level) <= EPS + 1e-9), np.nanmax(np.abs(z - level))
    # |d - d_cross| is at most EPS over the closed form's slope at the nearer of the two
    near = np.minimum(d, d_cross)
    assert np.all(np.abs(d - d_cross) * near / np.sqrt(R * R - near * near) <= 1.01 * EPS)
    assert drop.calls <= FALSI_STEPS


def test_jump_past_the_level_ends_on_the_air_side():
    """A level below the ball's lowest rest on the edge (TOP - R): the height jumps past it
    where the ball leaves the plate (d = R); the point found is on the air side (no face under
    the ball), at most WIDTH mm from the jump, and the bracket's other end rests on the
    plate."""
    rng = np.random.default_rng(5)
    n = 50
    end_d = R + rng.uniform(1e-4, 0.74, n)
    p0 = np.column_stack([EDGE + end_d - CELL, np.full(n, 10.0)])
    p1 = np.column_stack([EDGE + end_d, np.full(n, 10.0)])
    level = np.full(n, TOP - R - 0.5)
    drop = Counted(plate())
    z0, z1 = beside_edge(p0[:, 0] - EDGE), beside_edge(p1[:, 0] - EDGE)
    t, jump, t_up, settled = polish_crossings(drop, p0, p1, z0, z1, level, EPS, WIDTH)
    assert settled.all() and jump.all()
    d = p0[:, 0] + t * (p1[:, 0] - p0[:, 0]) - EDGE
    d_up = p0[:, 0] + t_up * (p1[:, 0] - p0[:, 0]) - EDGE
    assert np.all(d > R) and np.all(d - R <= WIDTH)
    assert np.isnan(beside_edge(d)).all()
    assert np.all(beside_edge(d_up) > level)
    assert drop.calls <= FALSI_STEPS


def test_jump_down_to_a_floor_far_below_is_bisected():
    """The plate over a floor FLOOR mm below its top (a face on both sides of the jump, the
    air end 22 mm under the level): regula falsi lands next to the air end step after step
    there, so a bracket steeper than JUMP_SLOPE is bisected.  Every edge settles as a jump
    within the step budget, on the air side (the ball on the floor, its closed form) at most
    WIDTH mm from the plate's edge's offset.  (With the secant alone some edges do not
    settle in FALSI_STEPS queries, and their points stay at the grid edge's air end.)"""
    floor = plane(0.0, 40.0, 0.0, 20.0, TOP - FLOOR)
    ns = plane(0.0, EDGE, 0.0, 20.0, TOP)
    fs = FaceSet([Face(ns, rectangle(ns)), Face(floor, rectangle(floor))])
    rng = np.random.default_rng(17)
    n = 60
    p0, p1 = jump_edges(rng, n)
    level = np.full(n, TOP - R - 0.5)
    drop = Counted(fs)
    z0, z1 = drop.fs.drop_ball(p0, R)[0], drop.fs.drop_ball(p1, R)[0]
    assert np.all(z0 > level) and np.all(z1 <= level - 20.0)
    t, jump, t_up, settled = polish_crossings(drop, p0, p1, z0, z1, level, EPS, WIDTH)
    assert settled.all() and jump.all()
    d = p0[:, 0] + t * (p1[:, 0] - p0[:, 0]) - EDGE
    d_up = p0[:, 0] + t_up * (p1[:, 0] - p0[:, 0]) - EDGE
    assert np.all(d > R) and np.all(d - R <= WIDTH), (d - R).max()
    assert np.allclose(drop.fs.drop_ball(p0 + t[:, None] * (p1 - p0), R)[0], TOP - FLOOR,
                       atol=1e-9)
    assert np.all(beside_edge(d_up) > level)
    assert drop.calls <= FALSI_STEPS


@pytest.mark.parametrize("tolerance", [0.01, 0.006])
def test_tube_wall_is_followed_from_the_air_side(tolerance):
    """A tube standing on nothing: below HEIGHT - R the drop height jumps from the rim's
    HEIGHT - R to no face where the ball's side meets the wall, so every waterline is the
    circle of radius RHO + R (the ball touching the wall) and nothing inside (the inner side
    faces away).  Every vertex lies on the air side of the closed-form drop height (never in
    the tube's wall), within the tolerance of the exact offset; along every chord the ball's
    side stays out of the wall (to the UNSEEN_DIP of the chord check, 1e-4 mm); each level is
    one closed contour around the whole tube."""
    fs = tube()
    tp = generate_faces_waterline(fs, 2 * R, 0.2, tolerance)
    levels = [z for z in tp.extra["levels"] if -R < z < HEIGHT - R]
    assert len(levels) >= 3
    assert len(tp.passes) == len(levels)
    for p in tp.passes:
        assert np.ptp(p[:, 2]) == 0.0 and p[0, 2] in levels
        assert np.array_equal(p[0], p[-1])  # closed
        r = np.hypot(p[:, 0], p[:, 1])
        assert not np.any(beside_tube(p[:, :2]) > p[:, 2])  # NaN: no face, the air side
        assert np.all(r > RHO + R), (r - RHO - R).min()
        assert np.all(r - RHO - R <= tolerance), (r - RHO - R).max()
        a = np.sort(np.arctan2(p[:, 1], p[:, 0]))
        assert np.diff(np.r_[a, a[0] + 2 * math.pi]).max() < 0.2  # all round
        # chords: dense samples; the ball's side reaches RHO + R - r into the wall
        s = np.linspace(0.0, 1.0, 257)[:, None, None]
        q = p[:-1, None, :2] + s.transpose(1, 0, 2) * (p[1:, None, :2] - p[:-1, None, :2])
        r = np.hypot(q[..., 0], q[..., 1])
        assert np.all(r >= RHO + R - 1e-4), RHO + R - r.min()
    # the certified drop-cutter agrees: no vertex below it
    allv = np.concatenate(tp.passes)
    drop = fs.drop_ball(allv[:, :2], R)[0]
    assert not np.any(drop > allv[:, 2] + 1e-7)


def test_crossings_on_a_cylinder_with_free_ends(monkeypatch):
    """The whole operation on a quarter cylinder whose ends and feet are free edges (grid
    corners beyond them have no face): every crossing that becomes a contour vertex (a
    selected surface contact, not a jump) lies within tolerance / 1000 of its level."""
    found = []

    def spy(heights, p0, p1, z0, z1, level, eps, width, steps=FALSI_STEPS, progress=None,
            slopes=None):
        out = polish_crossings(heights, p0, p1, z0, z1, level, eps, width, steps, progress,
                               slopes)
        found.append((p0 + out[0][:, None] * (p1 - p0), level, eps, out[1], out[3]))
        return out

    monkeypatch.setattr(faces_waterline, "polish_crossings", spy)
    ns = cylinder_quarter(10.0, 20.0)
    fs = FaceSet([Face(ns, rectangle(ns))])
    tol = 0.01
    tp = generate_faces_waterline(fs, 2 * R, 0.05, tol)
    assert tp.passes and len(found) == 1
    xy, level, eps, jump, settled = found[0]
    assert eps == pytest.approx(tol / 1000) and settled.all()
    assert math.isnan(fs.drop_ball(np.array([[0.0, -R - 0.1]]), R)[0][0])  # no-face corners
    query = faces_waterline._MemoQuery(fs, R)
    tip, good = faces_waterline._contacts(fs, query, faces_waterline._upward_signs(fs), xy)
    good &= ~jump
    assert good.sum() > 100
    assert np.all(np.abs(tip[good] - level[good]) <= eps)


def test_smoothly_pushed_vertices_are_not_taken_for_jumps():
    """A dome with no jump anywhere (no hole, its contours far from its border): push_out
    shifts vertices downhill by their chords' excess, which leaves them a little below their
    level; they are not beside a jump, so no chord is handled as one (no search for the free
    side, no dense sampling).  Every vertex stays at or above the certified drop height and no
    chord dips.  (Taken for jumps, 322 chords would be, at 2.5 times the drop-cutter queries.)"""
    from bsplinecam_helpers import TOL, D, H, assert_above_drop, dome_faces

    sel = dome_faces()[0]
    fs = FaceSet([Face(sel.surface, rectangle(sel.surface), index=1)])
    tp = generate_faces_waterline(fs, D, H, TOL)
    push = tp.extra["chord_push"]
    assert len(tp.passes) > 5 and push["max_push_mm"] > 0.0  # vertices were pushed
    assert push["jump_chords"] == 0 and push["dipping_chords"] == 0
    assert push["worst_dip_mm"] <= 1e-7
    assert_above_drop(fs, tp)


def test_no_contour_rubs_a_check_wall_under_a_fillet():
    """A selected top and fillet whose end turns vertical at x = rho, along a line rising from
    z = H0 to H1, over an unselected vertical wall up to that line (a part's side under its
    rounded edge): at a level between, the ball's side meets only the wall where the end is
    higher than the ball's centre, so no contour runs beside the wall there (each such contour
    rubbed the check face: on examples/part.step five levels along its side, 15 % of the
    waterline's cutting length); the fillet's own contours stay."""
    H0, H1, rho, length = 8.0, 12.0, 5.0, 8.0
    c = math.sqrt(0.5)  # a quarter cylinder from (0, y, H + rho) to (rho, y, H), H along y
    arc = [(0.0, rho), (rho, rho), (rho, 0.0)]
    fillet = NurbsSurface(np.array([[[x, 0.0, z + H0], [x, length, z + H1]] for x, z in arc]),
                          [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1,
                          weights=np.array([[1.0, 1.0], [c, c], [1.0, 1.0]]))
    top = NurbsSurface(np.array([[[-10.0, 0.0, H0 + rho], [-10.0, length, H1 + rho]],
                                 [[0.0, 0.0, H0 + rho], [0.0, length, H1 + rho]]]),
                       [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    wall = NurbsSurface(np.array([[[rho, 0.0, 0.0], [rho, length, 0.0]],
                                  [[rho, 0.0, H0], [rho, length, H1]]]), [0, 0, 1, 1],
                        [0, 0, 1, 1], 1, 1)
    fs = FaceSet([Face(top, rectangle(top), index=1), Face(fillet, rectangle(fillet), index=2),
                  Face(wall, rectangle(wall), index=3, selected=False)])
    tp = faces_waterline.generate_faces_waterline(fs, 2 * R, 0.3, 0.01)
    pts = np.concatenate(tp.passes)
    end = H0 + (H1 - H0) * pts[:, 1] / length  # the fillet's end over the wall
    beside = pts[:, 0] > rho + R - 0.05
    assert np.any(pts[:, 2] + R > end + 1.0)  # the fillet's own contours
    assert np.any(beside)  # where the end is at the ball's centre, the contour meets it
    low = beside & (pts[:, 2] + R < end - 0.05)
    assert not low.any(), pts[low][:5]



def test_contour_at_a_fillets_vertical_end_is_checked_in_bounded_time(monkeypatch):
    """A 30 x 20 x 10 mm box whose top edge along x is rounded by a 4 mm fillet (cadquery's
    OCCT, as the FreeCAD op test's part): one level's contour runs R beyond the side, where
    the ball touches the fillet's vertical end with its rim (height slope about 100).  Every
    interval of its chords is too steep for the chord model; they are sampled as a jump's, in
    bounded time (cut into 16 pieces a round down to 1e-5 mm they cost 140 000 queries in one
    round, over 15 minutes).  The contours stay on the free side: no point along them has a
    drop height above its level."""
    cq = pytest.importorskip("cadquery")
    from BSplineCAM.ocp import faces as ocp

    box = cq.Workplane().box(30, 20, 10, centered=False)
    box = box.edges(cq.selectors.BoxSelector((-1, -1, 9.9), (31, 0.1, 10.1))).fillet(4.0)
    fs = FaceSet(ocp.faces_from_shape(box.val().wrapped, "up", tolerance=0.01))
    asked = [0]
    drop = FaceSet.centre_heights

    def counted(self, q, *args, **kwargs):
        asked[0] += len(q)
        if asked[0] > 100_000:
            raise AssertionError(f"{asked[0]} drop-cutter queries and counting")
        return drop(self, q, *args, **kwargs)

    monkeypatch.setattr(FaceSet, "centre_heights", counted)
    tp = generate_faces_waterline(fs, 2 * R, 0.1, 0.01)
    monkeypatch.setattr(FaceSet, "centre_heights", drop)
    pts = np.concatenate(tp.passes)
    assert np.sum(np.abs(pts[:, 1] + R) < 0.01) >= 2  # the contour at the vertical end
    for p in tp.passes:  # the chords, every 0.01 mm, never below the drop height
        seg = np.diff(p[:, :2], axis=0)
        n = np.maximum(np.ceil(np.hypot(*seg.T) / 0.01).astype(int), 1)
        t = np.concatenate([np.arange(k) / k for k in n])
        i = np.repeat(np.arange(len(seg)), n)
        z = fs.drop_ball(p[i, :2] + t[:, None] * seg[i], R)[0]
        above = np.nan_to_num(z, nan=-np.inf) - p[i, 2]
        assert above.max() <= 1e-6, above.max()


# -- the polish with the height's slopes (polish_crossings ``slopes``): Newton steps from the
# latest point where the height is smooth, the dyadic bisection where it jumps ------------------
class Asked:
    """Heights and slopes of the plate (the op's remembering query), counting the rounds and
    the distinct points asked about."""

    def __init__(self):
        self.query = faces_waterline._MemoQuery(plate(), R)
        self.calls = 0
        self.points: set = set()

    def heights(self, xy):
        self.calls += 1
        self.points.update(map(tuple, np.asarray(xy).tolist()))
        return self.query.heights(xy)[0]

    def slopes(self, xy):
        return self.query.heights_and_slopes(xy)[1]


def edges(rng, n: int, near_rim: bool):
    """Grid edges across the plate's edge, one end resting on the plate, the other beyond
    the ball's reach (no face), and levels crossed between."""
    if near_rim:
        d_cross = R - rng.uniform(0.005, 0.02, n)
        end_d = np.maximum(d_cross + CELL * rng.uniform(0.0, 1.0 / 32.0, n), R + 1e-6)
    else:
        end_d = R + rng.uniform(1e-4, 0.74, n)
        d_cross = np.clip(end_d - CELL * rng.uniform(0.02, 0.98, n), 0.05, R - 1e-3)
    start = end_d - CELL
    y = rng.uniform(5.0, 15.0, n)
    p0, p1 = np.column_stack([EDGE + start, y]), np.column_stack([EDGE + end_d, y])
    return p0, p1, beside_edge(d_cross)


@pytest.mark.parametrize("near_rim", [False, True])
@pytest.mark.parametrize("flip", [False, True])
def test_newton_lands_on_the_level_in_fewer_queries(near_rim, flip):
    """Crossings between a corner resting on the plate and one with no face: with slopes as
    without, every point lies within EPS of its level (closed form) and every edge settles;
    the slopes take fewer queries."""
    rng = np.random.default_rng(3 + 2 * near_rim + flip)
    p0, p1, level = edges(rng, 120, near_rim)
    if flip:
        p0, p1 = p1, p0
    z0, z1 = beside_edge(p0[:, 0] - EDGE), beside_edge(p1[:, 0] - EDGE)
    asked_about = {}
    for use in (False, True):
        asked = Asked()
        t, jump, _t_up, settled = polish_crossings(
            asked.heights, p0, p1, z0, z1, level, EPS, WIDTH,
            slopes=asked.slopes if use else None)
        assert settled.all() and not jump.any()
        d = p0[:, 0] + t * (p1[:, 0] - p0[:, 0]) - EDGE
        assert np.all(np.abs(beside_edge(d) - level) <= EPS + 1e-9)
        assert asked.calls <= FALSI_STEPS
        asked_about[use] = len(asked.points)
    assert asked_about[True] < asked_about[False], asked_about


def test_jump_levels_on_one_edge_share_their_queries():
    """Levels below the ball's lowest rest on the edge (TOP - R) on the same grid edges: each
    point is on the air side within WIDTH of the jump (d = R), and the levels together ask
    about no more points than one level alone (the same dyadic points of the edge)."""
    rng = np.random.default_rng(9)
    n = 40
    p0, p1 = jump_edges(rng, n)
    z0, z1 = beside_edge(p0[:, 0] - EDGE), beside_edge(p1[:, 0] - EDGE)
    counts = []
    for levels in ([TOP - R - 0.5], [TOP - R - 0.5, TOP - R - 1.3, TOP - R - 2.9]):
        k = len(levels)
        asked = Asked()
        level = np.repeat(levels, n)
        t, jump, t_up, settled = polish_crossings(
            asked.heights, np.tile(p0, (k, 1)), np.tile(p1, (k, 1)), np.tile(z0, k),
            np.tile(z1, k), level, EPS, WIDTH, slopes=asked.slopes)
        assert settled.all() and jump.all()
        x0, x1 = np.tile(p0[:, 0], k), np.tile(p1[:, 0], k)
        d = x0 + t * (x1 - x0) - EDGE
        d_up = x0 + t_up * (x1 - x0) - EDGE
        assert np.all(d > R) and np.all(d - R <= WIDTH)
        assert np.all(beside_edge(d_up) > level)
        counts.append(len(asked.points))
    assert counts[1] == counts[0], counts


@pytest.mark.parametrize("seed", range(5))
def test_dyadic_point_has_the_fewest_binary_digits(seed):
    """_dyadic against a search over j / 2^k: strictly inside, and no coarser one is."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.0, 1.0, 300)
    b = np.minimum(a + rng.uniform(0.0, 1.0, 300) ** 4, 1.0)
    a[:20], b[:20] = 0.0, 1.0  # the whole edge: its midpoint
    t = faces_waterline._dyadic(a, b)
    assert np.all((t > a) & (t < b))
    assert np.all(t[:20] == 0.5)
    for lo, hi, x in zip(a, b, t):
        k = 0
        while (x * 2.0 ** k) % 1.0:
            k += 1
        for coarser in range(k):  # the first j / 2^c above lo is not below hi
            s = 2.0 ** coarser
            assert (np.floor(lo * s) + 1.0) / s >= hi
