# SPDX-License-Identifier: LGPL-2.1-or-later
"""Z-level roughing from a cylinder stock, its rings round helices and its bounded width of cut
on the case study and the example part, measured by cutting the moves out of a Z-map."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_roughing import (
    CYLINDER,
    EXAMPLES,
    PLANE_Z,
    SIM_CELL,
    _edge_arc_in_material,
    _job_radial,
    boss_in_cylinder,
    bowl,
    case_study_part,
    check_common,
    cone_pocket,
    farthest_clearing_feed,
    plane_in_cylinder,
    simulate_text,
)

from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.simulation.stock import CylinderStock
from BSplineCAM.core.toolpath.roughing import (
    Stock,
    front_radius,
    generate_roughing,
    ring_step,
    ring_steps,
)


def test_cylinder_stock_to_a_plane_removes_the_cylinder():
    """A flat end mill roughs a cylinder stock (r 20 mm, z 0..12) down to a plane at z 4 with
    0.3 mm axial allowance: the program's G-code, simulated from the cylinder, removes
    pi r^2 (12 - 4.3) mm^3 within a band of half a cell round the rim, leaves the whole disk
    at 4.3 mm and nothing outside it; its rapids cut nothing; the levels stop at the plane
    (a box stock's corners would take the tool down to the stock's bottom)."""
    tool = Tool(8.0, "flat")
    aa = 0.3
    rough = generate_roughing(plane_in_cylinder, CYLINDER, tool, stepdown=3.0, stepover=3.2,
                              radial_allowance=0.3, axial_allowance=aa)
    assert rough.levels == pytest.approx([9.0, 6.0, PLANE_Z + aa])
    job = simulate_text(rough, CYLINDER, tool)
    assert job.cylinder == CYLINDER and job.collisions == ()
    r, h = CYLINDER.radius, CYLINDER.z_max - PLANE_Z - aa
    expected = math.pi * r * r * h
    band = 2 * math.pi * r * (SIM_CELL / 2) * h  # cells whose centre decides the rim
    removed = job.removed_volume()
    print(f"cylinder to plane: removed {removed:.1f} mm^3, pi r^2 h = {expected:.1f} mm^3")
    assert abs(removed - expected) <= band
    assert float(np.abs(job.height[job.in_stock] - (PLANE_Z + aa)).max()) <= 1e-3
    assert np.all(job.height[~job.in_stock] == CYLINDER.z_min)
    # the simulation's stock is the circle: its cells are those within r of the axis
    xs, ys = job.grid.centres()
    circle = np.hypot(xs[None, :] - CYLINDER.x, ys[:, None] - CYLINDER.y) <= r
    assert np.array_equal(job.in_stock, circle)
    assert rough.stats["entries"]["outside"] >= len(rough.levels)


@pytest.mark.parametrize("tool", [Tool(8.0, "flat"), Tool(6.0, "bullnose", 1.0)],
                         ids=["flat", "bullnose"])
def test_cylinder_stock_no_clearing_in_the_air(tool):
    """Every clearing feed (not a link, not an entry) of a cylinder stock's roughing comes
    within the tool radius plus two cells of the cylinder: none clears the corners of the
    cylinder's box, which the roughing of that box does (the check can fail)."""
    rough = generate_roughing(boss_in_cylinder, CYLINDER, tool, stepdown=3.0,
                              stepover=0.4 * tool.diameter, radial_allowance=0.3,
                              axial_allowance=0.3)
    allowed = CYLINDER.radius + tool.radius + 2 * rough.stats["cell_mm"]
    worst, beyond = farthest_clearing_feed(rough, (CYLINDER.x, CYLINDER.y), allowed)
    print(f"{tool.shape.value}: farthest clearing feed {worst:.3f} mm from the axis "
          f"(r + R = {CYLINDER.radius + tool.radius:g} mm)")
    assert beyond == 0 and worst <= allowed
    box = Stock(*CYLINDER.bounds)
    boxed = generate_roughing(boss_in_cylinder, box, tool, stepdown=3.0,
                              stepover=0.4 * tool.diameter, radial_allowance=0.3,
                              axial_allowance=0.3)
    _, beyond_box = farthest_clearing_feed(boxed, (CYLINDER.x, CYLINDER.y), allowed)
    assert beyond_box > 0
    # and the cylinder's roughing cuts less air than the box's, both cut from the cylinder
    air = simulate_text(rough, CYLINDER, tool).tools[1].air_length_mm
    air_box = simulate_text(boxed, CYLINDER, tool).tools[1].air_length_mm
    print(f"{tool.shape.value}: air feed {air:.0f} mm from the cylinder's roughing, "
          f"{air_box:.0f} mm from its box's")
    assert air < air_box


def test_cylinder_stock_boss_checks():
    """The roughing of a hemisphere in a cylinder stock, cut move by move out of the
    cylinder: no gouge, at most a stepdown left, engagement within the stepover, rapids
    that cut nothing, ramps no steeper than RAMP_ANGLE_DEG; the job simulation of its text
    reports no rapid collision."""
    tool = Tool(8.0, "flat")
    rough = generate_roughing(boss_in_cylinder, CYLINDER, tool, stepdown=3.0, stepover=3.2,
                              radial_allowance=0.3, axial_allowance=0.3)
    sim, _ = check_common(rough, CYLINDER, tool, boss_in_cylinder, 3.0, 3.2, 0.3, 0.3,
                          head_on=True)
    assert np.all(sim.height[~sim.inside] == CYLINDER.z_min)
    assert simulate_text(rough, CYLINDER, tool).collisions == ()


@pytest.mark.parametrize(("args", "word"), [
    ((0, 0, 0.0, 0, 1), "radius"),
    ((0, 0, -2.0, 0, 1), "radius"),
    ((0, 0, 5.0, 1, 1), "z_max"),
    ((math.nan, 0, 5.0, 0, 1), "cylinder x"),
    ((0, math.inf, 5.0, 0, 1), "cylinder y"),
    ((0, 0, "wide", 0, 1), "radius"),
])
def test_cylinder_stock_validation(args, word):
    with pytest.raises(ParameterError, match=word) as info:
        CylinderStock(*args)
    assert "mm" in str(info.value)


def test_cylinder_stock_must_hold_the_part():
    """A part reaching out of the circle (a square plate whose corners the r 20 circle
    misses) is refused, naming the cylinder."""
    def square(xs, ys):
        X, Y = np.meshgrid(xs, ys)
        inside = (np.abs(X - CYLINDER.x) <= 18) & (np.abs(Y - CYLINDER.y) <= 18)
        return np.where(inside, PLANE_Z, np.nan)

    with pytest.raises(ParameterError, match="cylinder") as info:
        generate_roughing(square, CYLINDER, Tool(8.0, "flat"), 3.0, 3.0)
    assert "mm" in str(info.value)
    with pytest.raises(ParameterError, match="stock"):
        generate_roughing(plane_in_cylinder, (0, 1, 0, 1, 0, 1), Tool(8.0, "flat"), 3.0, 3.0)


@pytest.mark.parametrize("rho,R,s", [(4.0, 5.0, 4.0), (4.0, 5.0, 2.0), (10.0, 5.0, 4.0),
                                     (2.5, 3.0, 1.2), (60.0, 5.0, 4.0), (0.5, 6.0, 5.0)])
def test_ring_step_keeps_the_straight_pass_engagement(rho, R, s):
    """The next round front of a disc cleared by a helix (tool centres within rho) meets the
    material over the same arc of the tool's edge as a straight pass at stepover s, acos(1 -
    s/R); the full stepover there takes a wider arc."""
    ds = ring_step(rho, R, s)
    assert 0.0 < ds <= s
    straight = math.acos(1.0 - s / R)
    assert _edge_arc_in_material(rho + ds, rho + R, R) == pytest.approx(straight, abs=1e-4)
    if ds < s - 1e-9:
        assert _edge_arc_in_material(rho + s, rho + R, R) > straight + 1e-3


def test_fronts_round_a_helix_grow_by_the_ring_step():
    """A round pocket with no way in from the air is entered by a helix; its first front is a
    ring at the helix radius plus ring_step (not plus the stepover: there the 10 mm mill at
    4 mm would meet the material over 96 degrees of its edge instead of 78), of the share of
    the stepover the level is cut at."""
    def pocket(xs, ys):
        X, Y = np.meshgrid(xs, ys)
        h = np.where(np.hypot(X, Y) <= 20.0, 0.0, 1.0)
        return np.where((np.abs(X) <= 30) & (np.abs(Y) <= 30), h, np.nan)

    stock = Stock(-30, 30, -30, 30, -5.0, 1.0)
    tool = Tool(10.0, "flat")
    rough = generate_roughing(pocket, stock, tool, stepdown=1.0, stepover=4.0,
                              radial_allowance=0.3, axial_allowance=0.2)
    assert rough.stats["entries"]["helical"] == 1
    first, last = rough.stats["entry_spans"][0]
    helix = np.array([[m.x, m.y] for m in rough.moves[first:last]])
    centre = 0.5 * (helix.min(axis=0) + helix.max(axis=0))
    rh = float(np.hypot(*(helix - centre).T).max())
    level = [m for m in rough.moves[last:] if m.kind == "feed" and abs(m.z - 0.2) < 1e-9]
    radii = np.hypot(np.array([m.x for m in level]) - centre[0],
                     np.array([m.y for m in level]) - centre[1])
    cell = rough.tip_height.grid.cell if hasattr(rough.tip_height.grid, "cell") else 0.5
    # the level may be cut at a share of the stepover (narrowed_levels), its rings too
    share = dict(map(tuple, rough.stats["narrowed_levels"])).get(0.2, 1.0)
    want = rh + ring_step(rh, tool.radius, 4.0 * share)
    assert np.any(np.abs(radii - want) <= cell)
    # no front at the full stepover from the helix (the old ring, 1.45 mm further out)
    assert not np.any(np.abs(radii - (rh + 4.0)) <= 0.25 * cell)


def test_fine_levels_grow_rings_out_of_the_floor_cut_below():
    """At 8 + 4 mm in a conical pocket, a fine level's fronts grow outwards from the pocket's
    floor cut below it, as rings: by ring_step of the radius of a disc of the floor's area,
    not by the full stepover (which cut up to 4.59 mm wide, 59 moves over 1.1 stepover),
    and by less where they bend more than that disc (:func:`front_radius`), in short chords
    of a smooth curve: 3.97 mm and 14 moves over (23 with the disc's step alone, 4.01 mm).
    The rest of the excess is where the rings meet the fronts from the air."""
    stock = Stock(-25, 25, -25, 25, 0.0, 15.0)
    tool = Tool(8.0, "flat")
    rough = generate_roughing(cone_pocket, stock, tool, stepdown=8.0, stepover=3.2,
                              radial_allowance=0.3, axial_allowance=0.2, fine_stepdown=4.0)
    radial, collisions = _job_radial(rough, stock, tool, SIM_CELL)
    assert collisions == 0
    over = radial > 1.1 * 3.2 + SIM_CELL
    assert float(radial.max()) <= 4.1 and over.sum() <= 19, (radial.max(), over.sum())


def test_floor_rings_of_the_case_study_bend_by_their_own_radius():
    """The case study at 8 + 4 mm (10 mm flat, 4 mm stepover): on the fine level the fronts
    grow out of the pocket's floor cut below, which is round only roughly.  Grown by the
    ring step of the disc of the floor's area, and cut in chords up to 5 mm long, 29 moves
    cut wider than 1.1 stepover plus a cell (the job simulation at 0.1 mm), up to 5.46 mm;
    with the step of the radius the front has where it bends more, and the front cut as a
    smooth curve in short chords, 8, up to 4.75 mm."""
    height, stock = case_study_part()
    tool = Tool(10.0, "flat")
    rough = generate_roughing(height, stock, tool, 8.0, 4.0, 0.3, 0.3, fine_stepdown=4.0)
    radial, collisions = _job_radial(rough, stock, tool, 0.1)
    assert collisions == 0
    over = radial > 1.1 * 4.0 + 0.1
    assert float(radial.max()) <= 5.0 and over.sum() <= 15, (radial.max(), over.sum())


@pytest.mark.venv_only  # a whole case-study roughing: run once, in the venv
def test_fair_load_moves_still_over_are_peeled():
    """The case study at 8 + 4 mm with a 25 % stepover (10 mm flat, 2.5 mm): fronts still
    meet walls in notches the tool's size and close in on each other there after the levels
    are bent and narrowed.  No move cuts wider than 1.1 stepover plus a cell (the job
    simulation at 0.1 mm) and no rapid touches the stock: such moves are peeled
    (:meth:`_Job.peel`; unpeeled, 11 moves cut up to 3.79 mm) and the replay measures the
    wedge a descent leaves (``uncut_level``; a replay taking a ramp's track as cut at the
    level, 0.29 mm, leaves one at 2.95 mm beside it)."""
    height, stock = case_study_part()
    tool = Tool(10.0, "flat")
    rough = generate_roughing(height, stock, tool, 8.0, 2.5, 0.3, 0.3, fine_stepdown=4.0)
    radial, collisions = _job_radial(rough, stock, tool, 0.1)
    assert collisions == 0
    assert rough.stats["peeled_moves"] > 0
    over = radial > 1.1 * 2.5 + 0.1
    assert not over.any(), (radial.max(), over.sum())


@pytest.mark.venv_only  # a whole case-study roughing: run once, in the venv
@pytest.mark.parametrize("block, corner, s", [("sampled", 2.0, 4.0), ("job", 2.0, 4.0),
                                              ("job", 3.0, 4.0), ("job", 2.0, 2.5)])
def test_bullnose_case_study_within_the_stepover(block, corner, s):
    """The case study at a 2 mm step-down with a 10 mm bull-nose of 2 mm (and 3 mm) corner
    radius at a 4 mm stepover: every move outside the entries within 1.1 stepover plus a cell
    (the job simulation at 0.1 mm).  The cases this holds against: a lead-in skims the toes
    of fillets 0.1 mm deep across 5.33 mm if the roughing takes the corner's height from a
    fillet's crest it passed over but did not cut.  From the block the command line's job
    makes (the face's bounding box in FreeCAD grown by 2 mm, its top 1.5 µm higher) a move at
    the first level stays 4.78 mm wide if the peel, taking the level's material beside it in
    two steps, counts no fillet of the passes beside.  With a 3 mm corner a peel's step
    measures 3.71 mm where the simulation finds 4.75 if the level's replay marks a ramp as cut
    at the level, 0.28 mm under the fillets it leaves beside it.  At a 2.5 mm stepover a move
    into a contour's corner stays 3.04 mm wide if the sliver left of its material, which the
    tool reaches from the corner only and which stands 0.03 mm outside the region the peel's
    steps keep to, is taken by steps too wide to reach the points from which a feed along the
    wall takes it thin."""
    height, stock = case_study_part()
    if block == "job":
        stock = Stock(-2.0, 102.0, -2.0, 102.0, 10.450933463525763, 35.17659478303636)
    tool = Tool(10.0, "bullnose", corner)
    rough = generate_roughing(height, stock, tool, 2.0, s, 0.3, 0.3)
    radial, collisions = _job_radial(rough, stock, tool, 0.1)
    assert collisions == 0
    assert float(radial.max()) >= 0.9 * s  # it does cut at about the stepover
    over = radial > 1.1 * s + 0.1
    assert not over.any(), (radial.max(), over.sum())


def test_bullnose_moves_still_over_on_the_example_part_are_peeled():
    """examples/part.step (its faces by cadquery's OCCT) roughed at 6 + 3 mm with a 10 mm
    bull-nose of 2 mm corner radius at a 4 mm stepover from the block the command line's job
    makes (2 mm round it and on top): its fine level at 28.8 mm, narrowed to 80 %, has a move
    5.45 mm wide where fronts close in beside a wall unless moves of bull-noses are peeled as
    flat end mills' are; peeled, none is over 1.1 stepover plus a cell (the job simulation at
    0.1 mm), and no rapid touches the stock."""
    import os

    if os.environ.get("BSPLINECAM_REQUIRE_ALL") != "1":
        pytest.importorskip("OCP", reason="cadquery's OCP lives in the project venv")
    from BSplineCAM.core.geometry.faces_height import FacesHeight
    from BSplineCAM.ocp import faces as ocp_faces

    faces = ocp_faces.faces_from_shape(ocp_faces.read_part(EXAMPLES / "part.step"), "up")

    def height(xs, ys):
        return FacesHeight(faces, float(xs[1] - xs[0])).grid(np.asarray(xs), np.asarray(ys)).z

    x0, x1, y0, y1 = FacesHeight(faces, 0.25).bounds()
    top = float(np.nanmax(height(np.linspace(x0, x1, 161), np.linspace(y0, y1, 121))))
    stock = Stock(round(x0) - 2.0, round(x1) + 2.0, round(y0) - 2.0, round(y1) + 2.0, 0.0,
                  top + 2.0)
    tool = Tool(10.0, "bullnose", 2.0)
    rough = generate_roughing(height, stock, tool, 6.0, 4.0, 0.3, 0.3, fine_stepdown=3.0)
    assert rough.stats["peeled_moves"] > 0
    radial, collisions = _job_radial(rough, stock, tool, 0.1)
    assert collisions == 0
    assert float(radial.max()) >= 3.6
    over = radial > 1.1 * 4.0 + 0.1
    assert not over.any(), (radial.max(), over.sum())


def test_front_radius_of_discs_and_a_square():
    """:func:`front_radius` against the exact curvature: round a disc of radius rho the
    estimate at 3.5 mm out is rho within 15 % (its 5-95 % range within -40 % and +50 %: the
    grid's directions); beside a square's straight side it is infinite (a straight front),
    and 3.5 mm out from its corner under 2.5 mm (the corner's is 0; the smoothing spreads it)."""
    cell = 0.25
    n = 400
    y, x = np.mgrid[0:n, 0:n] * cell - n * cell / 2
    for rho in (5.0, 10.0, 20.0):
        est = front_radius(x * x + y * y <= rho * rho, cell, 5.0)
        ring = np.abs(np.hypot(x, y) - rho - 3.5) < 0.2
        p5, p50, p95 = np.percentile(est[ring], [5, 50, 95])
        assert abs(p50 - rho) <= 0.15 * rho, (rho, p50)
        assert p5 >= 0.6 * rho and p95 <= 1.5 * rho, (rho, p5, p95)
    square = (np.abs(x) <= 15) & (np.abs(y) <= 15)
    est = front_radius(square, cell, 5.0)
    side = (np.abs(x - 18.5) < 0.2) & (np.abs(y) < 5)
    assert np.isinf(est[side]).all()
    corner = (np.hypot(x - 15, y - 15) > 3.3) & (np.hypot(x - 15, y - 15) < 3.7) & (x > 15) & (
        y > 15)
    assert float(est[corner].max()) <= 2.5


def test_ring_steps_match_ring_step():
    """:func:`ring_steps` is :func:`ring_step` of each radius, the stepover on a straight
    front, and never below MIN_FRONT_STEP of it."""
    from BSplineCAM.core.toolpath.roughing import MIN_FRONT_STEP

    rho = np.array([3.0, 10.0, 40.0, 200.0])
    got = ring_steps(rho, 5.0, 4.0)
    want = [max(ring_step(r, 5.0, 4.0), MIN_FRONT_STEP * 4.0) for r in rho]
    assert np.allclose(got, want)
    assert ring_steps(np.array([np.inf]), 5.0, 4.0)[0] == pytest.approx(4.0, rel=1e-5)
    assert ring_steps(np.array([0.01]), 5.0, 4.0)[0] == pytest.approx(MIN_FRONT_STEP * 4.0)


def test_stay_down_lead_ins_are_measured_by_their_whole_swath():
    """A stay-down lead-in into a pass is taken only where its whole swath is within the
    stepover, as the job simulation measures a move: on the bull-nose bowl with 0.3 / 0.2 mm
    allowances one measured position by position cuts 3.61 mm at a 3 mm stepover (2.83 mm,
    by the job simulation, when measured by its swath)."""
    stock = Stock(-20, 20, -20, 20, 0.0, 10.0)
    tool = Tool(8.0, "bullnose", 1.0)
    rough = generate_roughing(bowl, stock, tool, stepdown=2.0, stepover=3.0,
                              radial_allowance=0.3, axial_allowance=0.2)
    radial, collisions = _job_radial(rough, stock, tool, SIM_CELL)
    assert collisions == 0
    assert float(radial.max()) <= 1.1 * 3.0 + SIM_CELL, float(radial.max())


def test_radial_engagement_round_a_helix_in_a_bowl():
    """Each level of a bowl is a round pocket entered by a helix; the rings round it, the
    last one on the bowl's wall, keep the radial engagement outside entries, measured by the
    job simulation, within 1.1 stepover plus one cell (at the full stepover from the helix it
    reached 3.65 mm against 2.84 mm)."""
    stock = Stock(-20, 20, -20, 20, 0.0, 10.0)
    tool = Tool(6.0, "flat")
    s = 2.4
    rough = generate_roughing(bowl, stock, tool, stepdown=2.0, stepover=s, axial_allowance=0.1)
    assert rough.stats["entries"]["helical"] >= 3
    radial, collisions = _job_radial(rough, stock, tool, SIM_CELL)
    assert collisions == 0
    # not vacuous: the rings cut most of the stepover (their short chords on the exact
    # circle meet the tapering end of the crescent in few cells: 1.8-1.9 mm by this measure)
    assert float(radial.max()) >= 0.7 * s
    over = radial > 1.1 * s + SIM_CELL
    assert not over.any(), f"{int(over.sum())} moves wider than 1.1 s, up to {radial.max():.2f}"


def test_rings_round_a_helix_are_cut_on_their_circle(monkeypatch):
    """A bowl twice the size roughed with a 10 mm flat at 4 mm: on each level entered by a
    helix, the rings round it clear of the wall are cut on exact circles round the helix's
    centre (the grid's contour of a ring wanders by about a cell, and a chord pointing
    outwards measured up to 6.2 mm wide on the case study's pocket; polygon chords of 1.8 mm
    4.7 mm), in chords within RING_CHORD_MM.  (Here the rings are entered by ramps round them, so the job
    simulation counts them as entries: the case study's figures are in the README.)  The
    rings as cut, before moves still over are peeled (a peel's steps leave the circle)."""
    from BSplineCAM.core.toolpath import roughing
    from BSplineCAM.core.toolpath.roughing import RING_CHORD_MM

    monkeypatch.setattr(roughing, "PEEL_OVER", math.inf)

    def big_bowl(xs, ys):
        return 2.0 * bowl(np.asarray(xs) / 2.0, np.asarray(ys) / 2.0)

    stock = Stock(-40, 40, -40, 40, 0.0, 20.0)
    tool = Tool(10.0, "flat")
    s = 4.0
    rough = generate_roughing(big_bowl, stock, tool, stepdown=4.0, stepover=s,
                              axial_allowance=0.1)
    spans = rough.stats["entry_spans"]
    checked = 0
    for a, b in spans:
        helix = np.array([m[1:] for m in rough.moves[a:b] if m.kind == "feed"])
        if len(helix) < 20:
            continue
        z = float(helix[-1, 2])
        pts = helix[2:, :2]
        M = np.column_stack([2 * pts, np.ones(len(pts))])
        centre = np.linalg.lstsq(M, (pts ** 2).sum(axis=1), rcond=None)[0][:2]
        radii = np.hypot(*(pts - centre).T)
        rh = float(radii.mean())
        if float(radii.std()) > 0.05 or rh > 0.4 * tool.diameter + 1e-6:
            continue  # a ramp along a pass or round a ring, not a helix
        level = np.array([m[1:3] for m in rough.moves[b:] if m.kind == "feed"
                          and abs(m.z - z) < 1e-9])
        # rings clear of the pocket's wall (the allowed centres' boundary, less a mm)
        tip = rough.tip_height
        xs, ys = tip.grid.centres()
        X, Y = np.meshgrid(xs, ys)
        wall = float(np.hypot(X - centre[0], Y - centre[1])[tip.z > z + 1e-6].min()) - 1.0
        d = np.sort(np.hypot(*(level - centre).T))
        d = d[(d > rh + 1.0) & (d < wall)]
        # groups of radii within 0.01 mm: rings of at least 8 vertices
        groups = np.split(d, np.flatnonzero(np.diff(d) > 0.01) + 1)
        on = sum(len(g) for g in groups if len(g) >= 8 and g[-1] - g[0] <= 0.01)
        assert len(d) >= 16 and on >= 0.9 * len(d), (z, len(d), on, groups)
        rings = [g for g in groups if len(g) >= 8]
        # consecutive vertices of a ring: chords within RING_CHORD_MM of the circle
        for g in rings:
            r = float(g.mean())
            ring = level[np.abs(np.hypot(*(level - centre).T) - r) <= 0.01]
            gaps = np.hypot(*np.diff(ring, axis=0).T)
            chord = 2.0 * math.sqrt(2.0 * r * RING_CHORD_MM) * 1.01
            assert np.median(gaps) <= chord, (z, r, np.median(gaps), chord)
        checked += 1
    assert checked >= 2
    radial, collisions = _job_radial(rough, stock, tool, SIM_CELL)
    assert collisions == 0
