# SPDX-License-Identifier: LGPL-2.1-or-later
"""Rest finishing from the roughed stock (issue 12, item 2), core only.

The part is a B-spline patch that is exactly a closed-form quadratic height field; the
roughed stock is the closed-form stair a Z-level roughing leaves (part + allowance rounded up
to the next level) on the Z-map.  The rest program and the normal finishing raster are then
simulated move by move with core.simulate, and the cuts are compared with the closed form.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_helpers import K_RIDGE, NET_SIZE, bezier_net, ridge_contact_slope, ridge_z

from BSplineCAM.core import ParameterError, Surface
from BSplineCAM.core.program.gcode import Segments
from BSplineCAM.core.simulation.simulate import Grid, Tool, simulate
from BSplineCAM.core.toolpath import generate, to_moves
from BSplineCAM.core.toolpath.rest import OffsetHeights, generate_rest, net_cl_height

SIZE = NET_SIZE
D = 6.0
R = D / 2
ALLOWANCE = 0.3
STEP_DOWN = 2.0
LIMIT = 0.5
STEPOVER = 1.5
SCALLOP = 0.01
TOL = 0.005
CELL = 0.1
#: Terraces only where x >= X_TERRACE; the rest of the part was left at the allowance.
X_TERRACE = 14.0
#: Z-map error allowed on a cut depth: a cell across the steepest slope (about 0.23).
CELL_ERROR = CELL * 0.25


def part_z(x, y):
    return 4.0 + 0.12 * x + 0.05 * y - 0.003 * (x - 15.0) ** 2


def roughed_stock(grid: Grid, top: float) -> np.ndarray:
    """min(block top, part + allowance rounded up to the next Z level) where x >= X_TERRACE,
    part + allowance elsewhere."""
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    finish = part_z(X, Y) + ALLOWANCE
    stair = STEP_DOWN * np.ceil(finish / STEP_DOWN)
    return np.minimum(top, np.where(X >= X_TERRACE, stair, finish))


def segments(moves) -> Segments:
    """Straight segments of a move list, the first starting at its own end (no motion)."""
    ends = np.array([[m.x, m.y, m.z] for m in moves])
    starts = np.vstack([ends[:1], ends[:-1]])
    n = len(moves)
    return Segments(starts, ends, np.array([m.kind == "rapid" for m in moves]),
                    np.arange(1, n + 1), np.arange(n))


def cut_move_by_move(moves, height: np.ndarray, grid: Grid, top: float):
    """Simulate each move on its own (core.simulate) and take the minimum into ``height``;
    returns the deepest cut (mm) of every move and the final Z-map."""
    seg = segments(moves)
    tool = Tool(D)
    current = height.astype(np.float32).astype(float)
    depth = np.zeros(len(moves))
    for k in range(len(moves)):
        one = Segments(seg.start[k:k + 1], seg.end[k:k + 1], seg.rapid[k:k + 1] & False,
                       seg.line[k:k + 1], seg.move[k:k + 1])
        env = simulate(one, tool, grid, top).height
        depth[k] = float(np.max(current - env))
        np.minimum(current, env, out=current)
    return depth, current


@pytest.fixture(scope="module")
def case():
    surface = Surface(bezier_net(part_z), "clamped", "rest")
    grid = Grid.covering(0.0, SIZE, 0.0, SIZE, CELL)
    top = 12.0
    stock = roughed_stock(grid, top)
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    rest = generate_rest(net_cl_height(surface), (grid, stock), D, LIMIT, STEPOVER,
                         (0.0, SIZE, 0.0, SIZE), angle=0.0, tolerance=TOL)
    rest_moves = to_moves(rest, clearance_height=top + 5.0)
    rest_depth, after_rest = cut_move_by_move(rest_moves, stock, grid, top + 5.0)
    finish = generate(surface, "raster", tool_diameter=D, scallop=SCALLOP, tolerance=TOL)
    fin_moves = to_moves(finish, clearance_height=top + 5.0)
    fin_depth, after = cut_move_by_move(fin_moves, after_rest, grid, top + 5.0)
    return {"surface": surface, "grid": grid, "top": top, "stock": stock, "X": X, "Y": Y,
            "rest": rest, "rest_moves": rest_moves, "rest_depth": rest_depth,
            "after_rest": after_rest, "finish": finish, "fin_moves": fin_moves,
            "fin_depth": fin_depth, "after": after}


def test_finishing_cut_bounded_after_rest(case):
    """Every finishing move cuts at most allowance + scallop + limit (+ the Z-map's error),
    which the finishing raster on the roughed stock alone exceeds by the terraces."""
    bound = ALLOWANCE + SCALLOP + LIMIT + CELL_ERROR
    assert case["fin_depth"].max() <= bound, case["fin_depth"].max()
    # without the rest passes the same finish cuts the terraces (up to a step-down)
    direct, _ = cut_move_by_move(case["fin_moves"][:400], case["stock"], case["grid"],
                                 case["top"] + 5.0)
    assert direct.max() > bound + 0.5


def test_rest_never_below_offset(case):
    """The rest program leaves at least ``limit`` on the part (closed form), so no gouge."""
    X, Y = case["X"], case["Y"]
    left = case["after_rest"] - part_z(X, Y)
    cut = case["after_rest"] < case["stock"] - 1e-6
    assert cut.any()
    assert left[cut].min() >= LIMIT - 1e-3, left[cut].min()
    # the finish itself: no gouge beyond 1 um
    assert (part_z(X, Y) - case["after"]).max() <= 1e-3


def test_rest_depth_per_move_bounded(case):
    """A rest move cuts about one ``limit``: at most limit / cos(slope) plus the cusp of
    its stepover and the clipping margin."""
    slope = math.atan(math.hypot(0.12 + 0.006 * 15.0, 0.05))
    cusp = R - math.sqrt(R * R - STEPOVER ** 2 / 4)
    bound = LIMIT / math.cos(slope) + cusp + 0.05 * LIMIT + CELL_ERROR
    assert 0.5 * LIMIT < case["rest_depth"].max() <= bound, case["rest_depth"].max()
    # no rapid of either program touches the stock
    for moves, depth in ((case["rest_moves"], case["rest_depth"]),
                         (case["fin_moves"], case["fin_depth"])):
        rapid = np.array([m.kind == "rapid" for m in moves])
        assert depth[rapid].max() <= 1e-5, depth[rapid].max()


def test_rest_only_on_terraces(case):
    """No rest pass over the part left at the allowance; every pass removes material."""
    rest = case["rest"]
    assert rest.strategy == "rest" and len(rest.passes) > 0
    xmin = min(float(p[:, 0].min()) for p in rest.passes)
    assert xmin >= X_TERRACE - R - 1.0, xmin
    X = case["X"]
    untouched = X < X_TERRACE - 2 * R
    assert np.array_equal(case["after_rest"][untouched],
                          case["stock"].astype(np.float32).astype(float)[untouched])
    # where the terraces stood more than a limit above the finish stock, the rest cut them
    excess = case["stock"] - part_z(X, case["Y"]) - ALLOWANCE
    assert np.all(case["after_rest"][excess > LIMIT + 0.2] < case["stock"][excess > LIMIT + 0.2])
    # each pass (its feed moves) removes something
    moves = case["rest_moves"]
    depth = case["rest_depth"]
    feeds = np.array([m.kind == "feed" for m in moves])
    starts = [k for k in range(len(moves)) if feeds[k] and not feeds[k - 1]]
    ends = [k for k in range(len(moves)) if feeds[k] and (k + 1 == len(moves) or not feeds[k + 1])]
    for a, b in zip(starts, ends):
        assert depth[a:b + 1].max() > 1e-3


def test_rest_links_and_order(case):
    """Links: one per gap between passes, stay-down ones join pass ends; zig-zag order."""
    rest = case["rest"]
    assert len(rest.links) == len(rest.passes) - 1
    stay = [k for k, lk in enumerate(rest.links) if lk is not None]
    assert stay
    for k in stay:
        lk = rest.links[k]
        assert np.allclose(lk[0, :2], rest.passes[k][-1, :2])
        assert np.allclose(lk[-1, :2], rest.passes[k + 1][0, :2])
    # offsets: top level first, the last at the limit
    offsets = rest.extra["offsets_mm"]
    assert offsets == sorted(offsets, reverse=True) and offsets[-1] == pytest.approx(LIMIT)
    assert len(offsets) == math.ceil(rest.extra["max_excess_mm"] / LIMIT) - 1


def plane_cl(a: float, b: float, c: float):
    """Closed-form ball tip height over the plane z = a + b x + c y (no slopes given)."""
    sec = math.sqrt(1.0 + b * b + c * c)
    return lambda radius: (lambda xy: a + b * xy[:, 0] + c * xy[:, 1] + radius * (sec - 1.0))


def test_plane_passes_on_closed_form_offsets():
    """On an inclined plane (closed-form cl_height without slopes) the pass vertices lie on
    the exact offset CL (within the one-sided lift of tolerance/2) and never below it."""
    a, b, c = 2.0, 0.1, -0.05
    cl = plane_cl(a, b, c)
    grid = Grid.covering(0.0, 20.0, 0.0, 20.0, 0.1)
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    stock = a + b * X + c * Y + np.where(X > 10.0, 1.7, 0.2)
    tp = generate_rest(cl, (grid, stock), D, LIMIT, 2.0, (0.0, 20.0, 0.0, 20.0), angle=30.0,
                       tolerance=0.01)
    sec = math.sqrt(1.0 + b * b + c * c)
    assert len(tp.passes) > 0
    seen = set()
    for p in tp.passes:
        base = a + b * p[:, 0] + c * p[:, 1] + R * (sec - 1.0)
        o = (p[:, 2] - base) / sec  # CL_o = CL_0 + o sec on a plane
        level = round(float(o.min()) / LIMIT) * LIMIT
        seen.add(level)
        assert o.min() >= level - 1e-9 and o.max() <= level + 0.005 / sec + 1e-9
        assert p[:, 0].min() >= 10.0 - R - 1.0
    # excess about 1.68 over CL_0 on the right: offsets 1.5, 1.0, 0.5 (M = 4)
    assert seen == {1.5, 1.0, 0.5}
    oh = OffsetHeights(cl, R, 0.5)
    z, grad = oh.heights_and_slopes(np.array([[3.0, 4.0]]))
    assert grad[0] == pytest.approx([b, c], abs=1e-6)
    assert z[0] == pytest.approx(a + 0.3 - 0.2 + R * (sec - 1) + 0.5 * sec, abs=1e-9)


@pytest.mark.parametrize("kwargs, name", [
    ({"limit": 0.0}, "limit"), ({"limit": -1.0}, "limit"), ({"stepover": 0.0}, "stepover"),
    ({"stepover": float("nan")}, "stepover"), ({"extent": (0.0, 25.0, 0.0, 10.0)}, "extent"),
    ({"tool_diameter": 0.0}, "tool_diameter"), ({"tolerance": 5.0}, "tolerance"),
    ({"angle": 400.0}, "angle"),
])
def test_bad_arguments(kwargs, name):
    grid = Grid.covering(0.0, 20.0, 0.0, 20.0, 0.5)
    args = {"cl_height": plane_cl(0.0, 0.0, 0.0), "stock": (grid, np.ones((grid.ny, grid.nx))),
            "tool_diameter": D, "limit": LIMIT, "stepover": 1.0,
            "extent": (0.0, 20.0, 0.0, 20.0)}
    args.update(kwargs)
    with pytest.raises(ParameterError, match=name):
        generate_rest(**args)


def test_faceset_plane_matches_closed_form():
    """The same passes from a trimmed face (FaceSet drop-cutter): vertices on the closed-form
    offset CL of the inclined plane."""
    from BSplineCAM.core.geometry.faces import Face
    from BSplineCAM.core.geometry.nurbs import NurbsSurface
    from BSplineCAM.core.toolpath.faceset import FaceSet
    from BSplineCAM.core.toolpath.rest import faceset_cl_height

    a, b, c = 1.0, 0.08, 0.0
    poles = np.array([[[0.0, 0.0, a], [0.0, 16.0, a]],
                      [[16.0, 0.0, a + 16 * b], [16.0, 16.0, a + 16 * b]]])
    face = Face(NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1),
                np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], float))
    grid = Grid.covering(0.0, 16.0, 0.0, 16.0, 0.1)
    X, Y = np.meshgrid(*grid.centres())
    stock = a + b * X + c * Y + np.where(X > 9.0, 1.2, 0.2)
    tp = generate_rest(faceset_cl_height(FaceSet([face])), (grid, stock), D, LIMIT, 2.0,
                       (3.0, 13.0, 3.0, 13.0), tolerance=0.01)
    sec = math.sqrt(1.0 + b * b + c * c)
    assert len(tp.passes) > 0
    levels = set()
    for p in tp.passes:
        o = (p[:, 2] - (a + b * p[:, 0] + c * p[:, 1] + R * (sec - 1.0))) / sec
        level = round(float(o.min()) / LIMIT) * LIMIT
        levels.add(level)
        assert o.min() >= level - 1e-6 and o.max() <= level + 0.005 / sec + 1e-6
        assert p[:, 0].min() >= 9.0 - R - 1.0
    assert levels == {1.0, 0.5}


def test_simulation_input_progress_and_cancel():
    """A core Simulation is accepted as the stock; progress rises to 1; cancel stops."""
    from BSplineCAM.core.simulation.simulate import Simulation
    from BSplineCAM.core.toolpath import ToolpathCancelled

    grid = Grid.covering(0.0, 20.0, 0.0, 20.0, 0.1)
    xs, _ys = grid.centres()
    height = np.broadcast_to(np.where(xs > 12.0, 1.4, 0.2), (grid.ny, grid.nx))
    sim = Simulation(grid, np.array(height), 5.0, ())
    seen = []
    tp = generate_rest(plane_cl(0.0, 0.0, 0.0), sim, D, LIMIT, 2.0, (0.0, 20.0, 0.0, 20.0),
                       progress=seen.append)
    assert seen[-1] == 1.0 and seen == sorted(seen)
    # flat part: the tips lie exactly on z = 1.0 and 0.5, only over x > 12 - R
    assert {round(float(z), 9) for p in tp.passes for z in p[:, 2]} == {1.0, 0.5}
    assert min(float(p[:, 0].min()) for p in tp.passes) >= 12.0 - R - 1.0
    with pytest.raises(ToolpathCancelled):
        generate_rest(plane_cl(0.0, 0.0, 0.0), sim, D, LIMIT, 2.0, (0.0, 20.0, 0.0, 20.0),
                      cancel=lambda: True)


# -- steep / shallow split ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def ridge():
    from BSplineCAM.core.toolpath.steep_shallow import generate_steep_shallow

    surface = Surface(bezier_net(ridge_z, 40.0), "clamped", "ridge")
    tp = generate_steep_shallow(surface, D, 0.02, 0.01, threshold_deg=45.0)
    return surface, tp


def test_split_by_slope_closed_form(ridge):
    """The contact slope on the split grid matches the closed form; the masks split at 45."""
    _surface, tp = ridge
    split = tp.extra["split"]
    xs, ys = split.grid.centres()
    X, Y = np.meshgrid(xs, ys)
    inner = (X > 4.0) & (X < 36.0) & (Y > R) & (Y < 40.0 - R)
    ref = ridge_contact_slope(X[inner])
    assert np.abs(split.slope_deg[inner] - ref).max() < 1e-3
    assert np.all(split.shallow[inner] == (ref < 45.0))
    assert np.all(split.steep[inner] == (ref >= 45.0))


def test_steep_shallow_passes_and_simulation(ridge):
    """Raster pieces stay in the shallow zone, contours in the steep one (each grown by the
    overlap); the simulated program leaves no seam: within scallop + tolerance everywhere
    on the part away from its lower edges, and no gouge."""
    surface, tp = ridge
    nr, nw = tp.extra["raster_passes"], tp.extra["waterline_passes"]
    assert nr > 0 and nw > 0 and len(tp.passes) == nr + nw == len(tp.links) + 1
    edge = 1.0 / (2 * K_RIDGE) + R * math.sin(math.radians(45.0))  # tip |x - 20| at 45 deg
    grow = tp.parameters["overlap"] + 2 * tp.extra["split"].grid.cell
    assert max(np.abs(p[:, 0] - 20.0).max() for p in tp.passes[:nr]) <= edge + grow
    assert min(np.abs(p[:, 0] - 20.0).min() for p in tp.passes[nr:]) >= edge - grow
    assert all(np.ptp(p[:, 2]) < 1e-9 for p in tp.passes[nr:])  # contours: constant Z
    grid = Grid.covering(0.0, 40.0, 0.0, 40.0, CELL)
    height = simulate(segments(to_moves(tp, 30.0)), Tool(D), grid, 20.0).height
    X, Y = np.meshgrid(*grid.centres())
    left = height - ridge_z(X, Y)
    assert left.min() >= -1e-3
    inner = (np.abs(X - 20.0) < 16.0) & (Y > 1.0) & (Y < 39.0)
    assert left[inner].max() <= 0.02 + 0.01 + CELL_ERROR, left[inner].max()


@pytest.mark.parametrize("kwargs, name", [
    ({"threshold_deg": 0.0}, "threshold_deg"), ({"threshold_deg": 90.0}, "threshold_deg"),
    ({"overlap": 0.0}, "overlap"), ({"tool_diameter": -1.0}, "tool_diameter"),
])
def test_steep_shallow_bad_arguments(kwargs, name):
    from BSplineCAM.core.toolpath.steep_shallow import generate_steep_shallow

    args = {"surface": Surface(bezier_net(ridge_z, 40.0), "clamped", "ridge"),
            "tool_diameter": D, "scallop": 0.02, "tolerance": 0.01}
    args.update(kwargs)
    with pytest.raises(ParameterError, match=name):
        generate_steep_shallow(**args)


def test_coarse_stock_refined_to_quarter_limit():
    """A Z-map coarser than limit / 4 is analysed on cells of at most limit / 4, each
    holding at least the stock of the coarse cell around it (never less material)."""
    from BSplineCAM.core.toolpath.rest import _refine_stock

    grid = Grid.covering(0.0, 20.0, 0.0, 20.0, 0.5)
    rng = np.random.default_rng(7)
    height = rng.uniform(0.0, 2.0, (grid.ny, grid.nx))
    fine, up = _refine_stock(grid, height, 0.125)
    assert fine.cell <= 0.125 and fine.nx * fine.cell == pytest.approx(grid.nx * grid.cell)
    xs, ys = fine.centres()
    X, Y = np.meshgrid(xs, ys)
    ix = np.floor((X - grid.x0) / grid.cell).astype(int)
    iy = np.floor((Y - grid.y0) / grid.cell).astype(int)
    assert np.all(up >= height[iy, ix])
    assert up.max() == height.max() and up.min() >= height.min()
    tp = generate_rest(plane_cl(0.0, 0.0, 0.0), (grid, np.where(height > 1.0, 1.4, 0.2)), D,
                       LIMIT, 2.0, (0.0, 20.0, 0.0, 20.0))
    assert tp.extra["zmap_cell_mm"] <= LIMIT / 4
    # stock only at the allowance (below one limit): nothing to do
    empty = generate_rest(plane_cl(0.0, 0.0, 0.0), (grid, np.full(height.shape, 0.3)), D,
                          LIMIT, 2.0, (0.0, 20.0, 0.0, 20.0))
    assert empty.passes == [] and empty.links == [] and empty.extra["offsets_mm"] == []
