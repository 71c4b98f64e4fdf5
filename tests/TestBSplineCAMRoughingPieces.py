# SPDX-License-Identifier: LGPL-2.1-or-later
"""Z-level roughing's pieces (core.toolpath.roughing): engaged widths, peeling, safe heights, tip
heights, capped distances and contours against brute-force references; bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_roughing import (
    SIM_CELL,
    _blobs,
    _job_radial,
    _rough_boss_near_corner,
    bare_job,
    hemisphere_on_plate,
)

from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.toolpath.common import ToolpathCancelled
from BSplineCAM.core.toolpath.roughing import (
    Stock,
    capped_distance,
    generate_roughing,
    marching_squares,
    tip_height,
)


def test_feeds_checked_at_once_match_a_cell_by_cell_reference():
    """engaged_widths and in_region_many (the lead-in search checks its tries in one go)
    against loops over cells and samples: the extent across each feed of the uncut cells
    within R of it and ahead of its start (plus a cell), and whether samples a tenth of a
    cell apart along it stay in {T <= z} (allowing the half-cell sampling's miss: a region
    edge is met within a cell of the reference's verdict).  Feeds of no length, empty
    batches and feeds over no uncut cell included."""
    cell = 0.25
    job, xs, ys = bare_job(cell, 12.0)
    rng = np.random.default_rng(7)
    X, Y = np.meshgrid(xs, ys)
    job.uncut = (np.hypot(X - 2.0, Y + 1.0) < 6.0) | (rng.random(X.shape) < 0.05)
    job.uncut &= (X > -4.0) | (Y > -4.0)  # a cleared corner
    job.T = np.where(np.hypot(X + 3.0, Y - 2.0) < 3.0, 5.0, 0.0)
    A = rng.uniform(-11, 11, (60, 2))
    B = A + rng.uniform(-6, 6, (60, 2))
    B[:3] = A[:3]  # no length
    A[3], B[3] = (-11.0, -11.0), (-10.0, -11.0)  # nothing uncut within R
    A[4], B[4] = (-8.0, 2.0), (2.0, 2.0)  # across the region's hole
    A[5], B[5] = (-10.0, 2.5), (-3.0, 2.5)  # into it
    R = job.R
    cx, cy = X[job.uncut], Y[job.uncut]
    widths = job.engaged_widths(A, B)
    inside = job.in_region_many(A, B, 1.0)
    for i, (a, b) in enumerate(zip(A, B)):
        L = math.dist(a, b)
        if L < 1e-9:
            assert widths[i] == 0.0
        else:
            d = (b - a) / L
            along = (cx - a[0]) * d[0] + (cy - a[1]) * d[1]
            across = (cy - a[1]) * d[0] - (cx - a[0]) * d[1]
            swept = [(0 < al <= L and abs(ac) <= R) or (al > L and (al - L) ** 2 + ac ** 2 <= R * R)
                     for al, ac in zip(along, across)]
            ref = float(across[swept].max() - across[swept].min()) + cell if any(swept) else 0.0
            assert widths[i] == pytest.approx(ref, abs=1e-9), i
        t = np.linspace(0.0, 1.0, max(2, int(math.dist(a, b) / (0.1 * cell)) + 2))
        pts = a + t[:, None] * (b - a)
        blocked = np.hypot(pts[:, 0] + 3.0, pts[:, 1] - 2.0) < 3.0 - cell
        near = np.hypot(pts[:, 0] + 3.0, pts[:, 1] - 2.0) < 3.0 + 2 * cell
        if blocked.any():
            assert not inside[i], i
        elif not near.any():
            assert inside[i], i
        assert inside[i] == job.in_region(a, b, 1.0)
        assert widths[i] == job.engaged_width(a, b)
    assert widths[3] == 0.0
    assert not inside[4] and not inside[5]
    assert len(job.engaged_widths(A[:0], B[:0])) == len(job.in_region_many(A[:0], B[:0], 1.0)) == 0


def test_stairs_along_a_shallow_wall_are_straightened_inwards():
    """A wall whose allowed side x <= w(y) steps by a cell every 5 mm (the tip height of a
    3 degree slope rises in one-cell plateaus): its contour runs in stairs, each jog a short
    move sideways into the material.  The pass keeps its first and last moves, drops the
    jogs in between, and never runs outside the contour (checked against the contour's own
    polyline, y-monotone), nor more than a cell inside it."""
    from BSplineCAM.core.toolpath.roughing import marching_squares

    cell = 0.2
    job, xs, ys = bare_job(cell, 20.0)
    wall = cell * np.floor((-3.0 - 0.04 * ys) / cell)
    field = xs[None, :] - wall[:, None]
    job.uncut = field > 0.0  # material beyond the contour, as before a front's pass
    lines = [job.xy(q) for q in marching_squares(field)]
    line = max(lines, key=len)
    line = line[(line[:, 1] > -15) & (line[:, 1] < 15)]
    line = line[np.argsort(line[:, 1])]
    short = np.hypot(*np.diff(line, axis=0).T) < 1.5 * cell
    assert short.sum() >= 5  # the stairs' jogs
    path = job.inner_chords(line, field)
    assert len(path) < len(line) / 3
    assert np.allclose(path[[0, 1, -2, -1]], line[[0, 1, -2, -1]])
    assert all(any(np.allclose(v, w) for w in line) for v in path)  # vertices of the contour
    # along the new path, never right of the contour (the material's side), at most a cell
    # left of it
    t = np.linspace(0.0, 1.0, 41)[:, None]
    dense = np.concatenate([a + t * (b - a) for a, b in zip(path[:-1], path[1:])])
    contour_x = np.interp(dense[:, 1], line[:, 1], line[:, 0])
    assert np.all(dense[:, 0] <= contour_x + 1e-6)
    assert np.all(dense[:, 0] >= contour_x - cell - 1e-6)
    # no jog left but at the ends
    jogs = np.hypot(*np.diff(path[1:-1], axis=0).T) < 1.5 * cell
    assert not jogs.any()


@pytest.mark.parametrize("tool", [Tool(8.0, "flat"), Tool(8.0, "bullnose", 1.5), Tool(6.0)])
def test_safe_heights_and_clear_points_against_brute_force(tool):
    """safe_heights (the lowest tip height at a point that meets none of the surface
    estimate, its cells taken 3/4 cell nearer) against a loop over every cell, and clear_at
    (which skips measuring points whose nearest cell above the level lies beyond the tool or
    under its flat bottom) against safe_heights itself, on a random estimate of bumps."""
    cell = 0.25
    job, xs, ys = bare_job(cell, 10.0, tool)
    rng = np.random.default_rng(7)
    X, Y = np.meshgrid(xs, ys)
    surface = np.full(X.shape, 2.0)
    for cx, cy, h in rng.uniform([-9, -9, 0.5], [9, 9, 4.0], (6, 3)):
        surface = np.where(np.hypot(X - cx, Y - cy) < 1.2, 2.0 + h, surface)
    surface[rng.random(X.shape) < 0.002] = -np.inf  # air
    job.surface = surface
    z = 2.0
    pts = rng.uniform(-11.0, 11.0, (300, 2))
    fast = job.safe_heights(pts, z)
    for (px, py), got in zip(pts, fast):
        r = np.hypot(X - px, Y - py) - 0.75 * cell
        inside = r <= tool.radius
        top = surface[inside] - tool.profile(np.maximum(r[inside], 0.0))
        assert got == pytest.approx(max(float(top.max(initial=-np.inf)), z), abs=1e-9)
    clear = job.clear_at(pts, z)
    assert np.array_equal(clear, fast <= z + 0.01)
    assert 20 < clear.sum() < 280  # both kinds of point


def test_run_back_to_a_pass_start_is_checked_move_by_move():
    """A lead-in that joins a pass further along runs back to its start: along the band the
    run cuts 3 mm; with a block of uncut material beyond the start (the corner a front leaves
    at a wall) the last move meets it head-on and the run is refused."""
    cell = 0.1
    job, xs, ys = bare_job(cell, 20.0)
    job.z = 0.0
    job.surface = np.full((len(ys), len(xs)), 10.0)
    job.surface_lo = job.surface.copy()
    band = np.broadcast_to((ys > 0.0)[:, None], job.surface.shape)
    run = np.array([[12.0, -6.0], [5.0, -1.0], [0.0, -1.0], [-5.0, -1.0]])
    job.uncut = band.copy()
    assert job.runs_within(run)
    assert np.array_equal(job.uncut, band)  # the trial is undone
    job.uncut = band | ((xs[None, :] < -6.0) & (ys[:, None] > -6.0))
    assert not job.runs_within(run)


def test_ramp_along_a_pass_of_no_length_ends():
    """A pass whose points coincide has nothing to ramp along: no ramp, at once (the walk back
    and forth along it never reached its length and grew without end, on the case study at
    an 8 mm step-down with 2 mm fine levels)."""
    from BSplineCAM.core.toolpath.roughing import _ramp

    for closed in (False, True):
        ramp, route = _ramp(np.array([[65.5, 18.5], [65.5, 18.5]]), closed, 2.0, 0.05)
        assert ramp.shape == (0, 3) and len(route) == 2


@pytest.mark.parametrize("fine, word", [(0.0, "fine_stepdown"), (-1.0, "fine_stepdown"),
                                        (4.0, "fine_stepdown"), (math.nan, "fine_stepdown")])
def test_fine_stepdown_bad_input(fine, word):
    with pytest.raises(ParameterError, match=word) as info:
        generate_roughing(hemisphere_on_plate, Stock(-25, 25, -25, 25, 0.0, 17.0),
                          Tool(8.0, "flat"), stepdown=3.0, stepover=3.0, fine_stepdown=fine)
    assert "mm" in str(info.value)


def test_fine_stepdown_equal_to_stepdown_is_plain():
    stock = Stock(-25, 25, -25, 25, 0.0, 17.0)
    a = generate_roughing(hemisphere_on_plate, stock, Tool(8.0, "flat"), 3.0, 3.0,
                          fine_stepdown=3.0)
    b = generate_roughing(hemisphere_on_plate, stock, Tool(8.0, "flat"), 3.0, 3.0)
    assert a.levels == b.levels and a.moves == b.moves


def test_tip_height_matches_brute_force():
    rng = np.random.default_rng(3)
    part = rng.uniform(0.0, 3.0, (23, 27))
    part[5:9, 4:7] = np.nan
    cell = 0.5
    for tool in (Tool(4.0, "flat"), Tool(4.0, "ball"), Tool(4.0, "bullnose", 0.8)):
        got = tip_height(part, cell, tool, 0.3, 0.1, -1.0, 0.0)
        grow = 0.3 + 1.5 * cell
        k = int((tool.radius + grow) / cell)
        ref = np.full(part.shape, -np.inf)
        H = np.where(np.isfinite(part), part + 0.1, -np.inf)
        for dy in range(-k, k + 1):
            for dx in range(-k, k + 1):
                r = cell * math.hypot(dx, dy)
                if r > tool.radius + grow + 1e-9:
                    continue
                f = float(tool.profile(min(max(r - grow, 0.0), tool.radius)))
                sh = np.full(part.shape, -np.inf)
                ys = slice(max(dy, 0), part.shape[0] + min(dy, 0))
                yd = slice(max(-dy, 0), part.shape[0] + min(-dy, 0))
                xs = slice(max(dx, 0), part.shape[1] + min(dx, 0))
                xd = slice(max(-dx, 0), part.shape[1] + min(-dx, 0))
                sh[yd, xd] = H[ys, xs]
                ref = np.maximum(ref, sh - f)
        ref = np.maximum(ref, -1.0)
        np.testing.assert_allclose(got, ref, atol=1e-12)


def test_replay_splits_descents_into_pieces_of_the_band():
    """The level's replay marks a descent in pieces each descending at most the band, so that
    the surface estimate drops to each piece's own height (a 2 mm ramp over 38 mm marked at
    the level in one feed would set the estimate 0.28 mm under the fillets it left).  The
    feeds at the level and a plunge (no move across) stay whole; the points are on the
    feeds, the heights linear along them."""
    from BSplineCAM.core.toolpath.roughing import _split_descents

    path = np.array([[0.0, 0.0], [0.0, 0.0], [38.0, 0.0], [40.0, 0.0], [40.0, 0.0]])
    zs = np.array([12.0, 11.0, 10.0, 10.0, 9.0])  # plunge, ramp, level, plunge
    at = [False, False, False, True, False]
    P, Z, A = _split_descents(path, zs, at, 0.05)
    assert np.allclose(P[[0, 1]], path[[0, 1]]) and np.allclose(Z[[0, 1]], [12.0, 11.0])
    ramp = slice(1, 22)  # 20 pieces of 0.05 mm from 11 down to 10
    assert np.allclose(np.diff(Z[ramp]), -0.05)
    assert np.allclose(P[ramp, 0], np.linspace(0.0, 38.0, 21)) and not any(A[2:22])
    assert np.allclose(P[-2:], path[-2:]) and np.allclose(Z[-2:], [10.0, 9.0])
    assert A[-2] and not A[-1] and len(P) == 24
    # no band: nothing added
    P, Z, A = _split_descents(path, zs, at, math.inf)
    assert np.allclose(P, path) and np.allclose(Z, zs) and list(A) == at


def test_capped_distance_and_contours():
    from scipy import ndimage

    rng = np.random.default_rng(5)
    mask = rng.random((40, 50)) < 0.02
    ref = ndimage.distance_transform_edt(~mask)
    got = capped_distance(mask, 6.0)
    near = ref <= 6.0
    np.testing.assert_allclose(got[near], ref[near], atol=1e-9)
    assert np.all(got[~near] > 6.0)
    # a circle of radius 10 cells: one closed loop, inside on its right (clockwise)
    yy, xx = np.mgrid[0:41, 0:41]
    F = np.hypot(xx - 20.0, yy - 20.0) - 10.0
    lines = marching_squares(F)
    assert len(lines) == 1
    loop = lines[0]
    assert np.allclose(loop[0], loop[-1])
    np.testing.assert_allclose(np.hypot(loop[:, 0] - 20, loop[:, 1] - 20), 10.0, atol=0.02)
    area = 0.5 * np.sum(loop[:-1, 0] * loop[1:, 1] - loop[1:, 0] * loop[:-1, 1])
    assert area < 0  # clockwise


@pytest.mark.parametrize("cap", [1.0, 2.5, 6.0, 30.0, 200.0])
def test_capped_distance_against_scipy_on_cropped_masks(cap):
    """Exact (scipy's Euclidean distance transform) up to the cap and above it beyond, where
    only part of the grid lies near both set and unset cells, with caps whose squares need
    16-, 32-bit integers."""
    from scipy import ndimage

    rng = np.random.default_rng(11)
    for shape in [(1, 1), (1, 40), (40, 1), (37, 90), (120, 60)]:
        for mask in _blobs(shape, rng):
            got = capped_distance(mask, cap)
            assert got.shape == mask.shape and got.dtype == float
            if not mask.any():
                assert np.all(got > cap)
                continue
            ref = ndimage.distance_transform_edt(~mask)
            near = ref <= cap
            np.testing.assert_allclose(got[near], ref[near], atol=1e-12)
            assert np.all(got[~near] > cap)


def test_densify_and_polyline_distance():
    """Points along a polyline at most ``step`` apart, every vertex kept, on its segments;
    the distance to a polyline against one from dense samples of it."""
    from BSplineCAM.core.toolpath.roughing import _densify, _polyline_distance

    path = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 0.0], [3.0, 2.5], [-1.0, 4.0]])
    for step in (0.3, 1.0, 10.0):
        dense = _densify(path, step)
        gaps = np.hypot(*np.diff(dense, axis=0).T)
        assert gaps.max() <= step + 1e-12
        for v in path:
            assert np.min(np.hypot(*(dense - v).T)) == 0.0
        assert np.allclose(_polyline_distance(dense, path), 0.0, atol=1e-12)
        np.testing.assert_array_equal(_densify(path[:2], step), dense[:len(_densify(path[:2], step))])
    rng = np.random.default_rng(2)
    pts = rng.uniform(-3, 6, (300, 2))
    fine = _densify(path, 1e-4)
    ref = np.array([np.hypot(*(fine - p).T).min() for p in pts])
    np.testing.assert_allclose(_polyline_distance(pts, path), ref, atol=1e-4)
    np.testing.assert_allclose(_polyline_distance(pts, path[:1]), np.hypot(*(pts - path[0]).T))


def test_stock_around():
    s = Stock.around((0, 10, -5, 5, 1, 4), 2.0)
    assert (s.x_min, s.x_max, s.y_min, s.y_max, s.z_min, s.z_max) == (-2, 12, -7, 7, 1, 6)
    s = Stock.around((0, 10, -5, 5, 1, 4), 2.0, top_margin=0.5)
    assert s.z_max == 4.5
    with pytest.raises(ParameterError, match="x_max"):
        Stock(1, 0, 0, 1, 0, 1)


def test_cancel():
    stock = Stock(-25, 25, -25, 25, 0.0, 17.0)
    with pytest.raises(ToolpathCancelled):
        generate_roughing(hemisphere_on_plate, stock, Tool(8.0, "flat"), 3.0, 3.0,
                          cancel=lambda: True)


@pytest.mark.parametrize(("kwargs", "word"), [
    ({"stepdown": 0.0}, "stepdown"),
    ({"stepdown": -1.0}, "stepdown"),
    ({"stepover": 0.0}, "stepover"),
    ({"stepover": 9.0}, "stepover"),
    ({"radial_allowance": -0.1}, "radial_allowance"),
    ({"radial_allowance": 100.0}, "radial_allowance"),
    ({"axial_allowance": -0.1}, "axial_allowance"),
    ({"axial_allowance": 50.0}, "axial_allowance"),
    ({"cell": 0.0}, "cell"),
    ({"cell": -0.2}, "cell"),
    ({"clearance_height": 10.0}, "clearance_height"),
    ({"stock": Stock(-20, 20, -25, 25, 0, 17)}, "stock"),
    ({"stock": Stock(-25, 25, -25, 25, 0, 14)}, "stock"),
    ({"height": 3.0}, "height"),
    ({"ramp_angle": 0.0}, "ramp_angle"),
    ({"ramp_angle": -2.0}, "ramp_angle"),
    ({"ramp_angle": 31.0}, "ramp_angle"),
    ({"ramp_angle": float("nan")}, "ramp_angle"),
])
def test_bad_input(kwargs, word):
    args = {"stock": Stock(-25, 25, -25, 25, 0.0, 17.0), "tool": Tool(8.0, "flat"),
            "stepdown": 3.0, "stepover": 3.0}
    args.update(kwargs)
    height = args.pop("height", hemisphere_on_plate)
    with pytest.raises(ParameterError, match=word) as info:
        generate_roughing(height, **args)
    assert ("degrees" if word == "ramp_angle" else "mm") in str(info.value)


@pytest.mark.parametrize("fraction", [0.3, 0.5])
def test_radial_engagement_bound_head_on_boss(fraction):
    """The fronts of the flat levels run head-on into the hemisphere's wall; the program's
    radial engagement outside entries, measured by the job simulation, stays within
    1.1 stepover plus one simulation cell.  (At 30 %: about 2.2 mm against 2.84 mm; 5.0 mm
    if the fronts on the plate's level at T = z are cut into slivers.)"""
    stock = Stock(-25, 25, -25, 25, 0.0, 17.0)
    tool = Tool(8.0, "flat")
    s = fraction * tool.diameter
    rough = generate_roughing(hemisphere_on_plate, stock, tool, stepdown=3.0, stepover=s,
                              radial_allowance=0.3, axial_allowance=0.2)
    radial, collisions = _job_radial(rough, stock, tool, SIM_CELL)
    assert collisions == 0
    # not vacuous: the passes do cut at about the stepover
    assert float(radial.max()) >= 0.9 * s
    over = radial > 1.1 * s + SIM_CELL
    assert not over.any(), f"{int(over.sum())} moves wider than 1.1 s, up to {radial.max():.2f}"


def test_fronts_bent_towards_the_walls_cut_narrower_than_head_on(monkeypatch):
    """Fronts from the far sides of the block run head-on into the boss near its corner:
    with the plain fronts only (ENGAGEMENT_LIMIT infinite, never retried, and no move
    peeled) the job simulation measures cuts up to R + s/2 wide there; with the levels cut
    again with bent fronts where that happens, the widest cut outside entries is at least
    1.5 mm narrower and fewer moves cut wider than 1.1 s, with no rapid touching the
    stock."""
    from BSplineCAM.core.toolpath import roughing

    s = 4.0
    monkeypatch.setattr(roughing, "PEEL_OVER", math.inf)
    bent, radial, over = _rough_boss_near_corner(s)
    monkeypatch.setattr(roughing, "ENGAGEMENT_LIMIT", math.inf)
    plain, radial_plain, over_plain = _rough_boss_near_corner(s)
    assert plain.stats["bent_levels"] == [] and plain.stats["peeled_moves"] == 0
    assert len(bent.stats["bent_levels"]) >= 3
    assert float(radial_plain.max()) >= 5.0 + s / 2 - 0.5  # the head-on ends (R + s/2)
    assert float(radial.max()) <= float(radial_plain.max()) - 1.5
    assert over < over_plain


@pytest.mark.venv_only  # a whole case-study roughing: run once, in the venv
def test_levels_still_over_when_bent_are_cut_at_a_smaller_stepover(monkeypatch):
    """Bent fronts alone (no move peeled) leave cuts wider than 1.1 s beside the boss near
    the block's corner (where they bend and close in on each other); with the levels still
    over cut again at a share of the stepover (STEPOVER_SCALES), the job simulation finds
    no move outside the entries wider than 1.1 s plus a cell, and the narrowed levels are
    reported.  So it does with the bent fronts at the full stepover and the moves still
    over peeled (:meth:`_Job.peel`)."""
    from BSplineCAM.core.toolpath import roughing

    monkeypatch.setattr(roughing, "PEEL_OVER", math.inf)
    narrowed, _, over = _rough_boss_near_corner(4.0)
    monkeypatch.setattr(roughing, "STEPOVER_SCALES", ())
    bent, _, over_bent = _rough_boss_near_corner(4.0)
    monkeypatch.setattr(roughing, "PEEL_OVER", 1.0)
    peeled, _, over_peeled = _rough_boss_near_corner(4.0)
    assert bent.stats["narrowed_levels"] == [] and bent.stats["peeled_moves"] == 0
    assert over_bent > 0
    assert over == 0
    assert over_peeled == 0 and peeled.stats["peeled_moves"] > 0
    levels = narrowed.stats["narrowed_levels"]
    assert levels and all(0 < share < 1 for _, share in levels)
    assert {z for z, _ in levels} <= set(narrowed.stats["bent_levels"])
    # closer fronts: more cutting, not a different part
    assert narrowed.stats["cutting_length_mm"] > bent.stats["cutting_length_mm"]
