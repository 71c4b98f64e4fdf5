# SPDX-License-Identifier: LGPL-2.1-or-later
"""Z-level roughing (core.toolpath.roughing) on parts known in closed form: the moves are cut, one at a
time, out of a Z-map of the stock block by the exact swept-tool envelope of core.simulate and
the stock left is compared with the part; entries, levels and fine step-downs."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from bsplinecam_roughing import (
    SIM_CELL,
    Machined,
    _bands,
    _in_entry,
    _job_radial,
    _ramps_retraced,
    bare_job,
    bowl,
    case_study_part,
    check_common,
    hemisphere_on_plate,
    plateau,
    simulate_text,
    slope,
    slot_plate,
)

from BSplineCAM.core.simulation.simulate import Grid, Tool
from BSplineCAM.core.toolpath.roughing import (
    RAMP_ANGLE_DEG,
    Stock,
    generate_roughing,
)


# -- tests ----------------------------------------------------------------------------------
def test_flat_end_mill_hemisphere_boss():
    stock = Stock(-25, 25, -25, 25, 0.0, 17.0)
    tool = Tool(8.0, "flat")
    rough = generate_roughing(hemisphere_on_plate, stock, tool, stepdown=3.0, stepover=3.0,
                              radial_allowance=0.3, axial_allowance=0.2)
    sim, base = check_common(rough, stock, tool, hemisphere_on_plate, 3.0, 3.0, 0.3, 0.2)
    # a level on the plate (5 + 0.2) leaves the plate clean away from the boss
    assert any(abs(z - 5.2) < 1e-6 for z in rough.levels)
    X, Y = np.meshgrid(sim.xs, sim.ys)
    plate = (np.hypot(X, Y) > 10 + 8 + 1) & (np.abs(X) < 24) & (np.abs(Y) < 24)
    left = sim.height[plate] - 5.2
    assert float(np.abs(left).max()) <= 0.05
    # the boss's top (15 + 0.2 allowance) is the highest material after the first level
    assert rough.levels[0] == pytest.approx(14.0)
    st = rough.stats
    assert st["entries"]["helical"] == 0 and st["entries"]["outside"] >= 1
    # passes that no stay-down link reaches but that start beside the floor already cut are
    # entered by a straight descent on that floor and a lead-in cutting within the stepover
    # (check_common: no descent into material steeper than the ramp; the job simulation:
    # no move wider than 1.1 s, also where a lead-in joins a pass further along and runs
    # back to its start), not by a ramp from the top: at most 10 ramps (28 if such passes were
    # ramped into), each 57 mm of feed at 3 mm and 3 degrees
    assert st["entries"]["lead_in"] >= 15 and st["entries"]["ramp"] <= 10, st["entries"]
    radial, collisions = _job_radial(rough, stock, tool, SIM_CELL)
    assert collisions == 0 and float(radial.max()) <= 1.1 * 3.0 + SIM_CELL
    assert st["passes"] > 0 and st["cutting_length_mm"] > 0
    assert not [n for n in st["notes"] if "smaller tool" in n]
    # every move below the stock top stays under the clearance, rapids at clearance or down
    assert all(m.z <= rough.clearance_height for m in rough.moves)
    # rapids between passes travel just above the material instead of at the clearance
    # height; check_common's simulation shows that they remove nothing
    low = [b for a, b in zip(rough.moves, rough.moves[1:]) if b.kind == "rapid"
           and a.z == b.z < stock.z_max and math.hypot(b.x - a.x, b.y - a.y) > 1.0]
    assert st["lifts"] > 0 and len(low) >= st["lifts"] // 2


def test_bull_nose_bowl_needs_helix():
    stock = Stock(-20, 20, -20, 20, 0.0, 10.0)
    tool = Tool(8.0, "bullnose", 1.0)
    rough = generate_roughing(bowl, stock, tool, stepdown=2.0, stepover=3.0,
                              axial_allowance=0.1)
    sim, base = check_common(rough, stock, tool, bowl, 2.0, 3.0, 0.0, 0.1)
    st = rough.stats
    assert st["entries"]["helical"] >= 3
    # (e) no straight plunge into material: descending cuts ramp at most at the ramp angle
    slopes = [s for i, s in sim.descents]
    assert slopes, "the helices cut nothing"
    limit = math.tan(math.radians(RAMP_ANGLE_DEG)) * 1.05
    assert max(slopes) <= limit, f"descending cut with slope {max(slopes):.4f}"
    assert all(_in_entry(rough, i) for i, _ in sim.descents)
    # the helix is a polyline of small chords on a circle around a fixed centre
    a, b = st["entry_spans"][0]
    pts = np.array([m[1:3] for m in rough.moves[a:b] if m.kind == "feed"])[2:]
    # least-squares circle: x^2 + y^2 = 2 a x + 2 b y + c
    M = np.column_stack([2 * pts, np.ones(len(pts))])
    sol = np.linalg.lstsq(M, (pts ** 2).sum(axis=1), rcond=None)[0]
    centre = sol[:2]
    radius = np.hypot(*(pts - centre).T)
    assert float(radius.std()) < 0.05 and 0.5 < float(radius.mean()) <= 3.2 + 1e-6


def test_ball_sloped_plane():
    stock = Stock(-16, 16, -12, 12, 0.0, 9.0)
    tool = Tool(6.0, "ball")
    rough = generate_roughing(slope, stock, tool, stepdown=1.5, stepover=2.4,
                              radial_allowance=0.2, axial_allowance=0.2, flat_levels=False)
    check_common(rough, stock, tool, slope, 1.5, 2.4, 0.2, 0.2, head_on=True)
    assert rough.levels == sorted(rough.levels, reverse=True)
    # a ramp reaches its level where its pass starts: the pass then runs over the ramp's
    # track once, never back over it first
    retraced = _ramps_retraced(rough)
    assert rough.stats["ramps"] > 0 and len(retraced) == rough.stats["ramps"]
    assert max(retraced) <= 1.1, f"a pass runs {max(retraced):.2f} times over its ramp"
    assert rough.levels[0] == pytest.approx(7.5)


@pytest.mark.parametrize("case", ["helix", "ramp"])
def test_ramp_angle_sets_the_entries_slope(case):
    """At ramp_angle 8 degrees the entries that cut (a bull-nose bowl's helices, a ball's
    ramps on a sloped plane) descend at 8 degrees, not the default 3 (the simulated slope of
    the steepest cutting descent lies between 0.9 and 1.05 tan 8), over a shorter length."""
    if case == "helix":
        stock, tool, part, sd, so, ar, aa = (Stock(-20, 20, -20, 20, 0.0, 10.0),
                                             Tool(8.0, "bullnose", 1.0), bowl, 2.0, 3.0, 0.0,
                                             0.1)
        kw = {}
    else:
        stock, tool, part, sd, so, ar, aa = (Stock(-16, 16, -12, 12, 0.0, 9.0),
                                             Tool(6.0, "ball"), slope, 1.5, 2.4, 0.2, 0.2)
        kw = {"flat_levels": False}
    lengths = {}
    for angle in (RAMP_ANGLE_DEG, 8.0):
        rough = generate_roughing(part, stock, tool, stepdown=sd, stepover=so,
                                  radial_allowance=ar, axial_allowance=aa, ramp_angle=angle,
                                  **kw)
        assert rough.parameters["ramp_angle"] == angle
        if case == "ramp":
            sim, _ = check_common(rough, stock, tool, part, sd, so, ar, aa, head_on=True,
                                  ramp_angle=angle)
        else:
            # (the bowl's top level, a small ring entered by a ramp round it, cuts wider
            # than 1.1 s once the steeper ramp covers only part of the ring; at 3 degrees
            # the ramp covers it all; see the module's known limits)
            sim = Machined(rough, stock, tool)
            assert sim.rapid_cut <= 0.01
        slopes = [s for _, s in sim.descents]
        assert max(slopes) <= 1.05 * math.tan(math.radians(angle))
        assert max(slopes) >= 0.9 * math.tan(math.radians(angle)), (angle, max(slopes))
        lengths[angle] = sum(
            math.dist(a[1:], b[1:]) for a, b in zip(rough.moves, rough.moves[1:])
            if b.kind == "feed" and b.z < a.z - 1e-9)
    assert lengths[8.0] < 0.6 * lengths[RAMP_ANGLE_DEG], lengths


def test_region_too_small_is_reported_not_cut():
    stock = Stock(-20, 20, -15, 15, 0.0, 10.0)
    tool = Tool(8.0, "flat")
    progress = []
    rough = generate_roughing(slot_plate, stock, tool, stepdown=3.0, stepover=3.0,
                              progress=progress.append)
    notes = rough.stats["notes"]
    # the 6 mm slot: the 8 mm tool cannot enter it at all
    slot = [n for n in notes if "cannot reach" in n and "x=0.0" in n and "y=0.0" in n]
    assert len(slot) == 1, notes
    # the 9.6 mm pocket: the tool fits, but no helix does (a straight plunge would be needed)
    helix = [n for n in notes if "too narrow for a helical entry" in n]
    assert len(helix) == 1 and helix[0].startswith("1 closed pocket"), notes
    x, y = (float(v) for v in re.search(r"\(([-\d.]+), ([-\d.]+)\)", helix[0]).groups())
    assert math.hypot(x - 14.0, y - 9.0) < 0.5
    # the note names a smaller tool that enters the 9.6 mm pocket by a helix, and what is uncut
    fits = float(re.search(r"a tool of at most ([\d.]+) mm enters it", helix[0]).group(1))
    assert 0.0 < fits < 8.0
    assert "uncut from Z" in helix[0] and "full width" in helix[0]
    assert rough.stats["entries"]["helical"] == 0
    # neither keeps less material: the tool never reaches below the plate inside them
    sim = Machined(rough, stock, tool)
    X, Y = np.meshgrid(sim.xs, sim.ys)
    inside = ((np.abs(Y) < 2.5) & (np.abs(X) < 9.5)) | (np.hypot(X - 14, Y - 9) < 4.5)
    assert float(sim.height[inside].min()) >= 10.0 - 1e-3
    assert sim.rapid_cut <= 0.01
    assert progress and progress[-1] == pytest.approx(1.0)
    assert all(b >= a for a, b in zip(progress, progress[1:]))


@pytest.mark.parametrize("flat_levels", [True, False])
def test_flat_levels_clean_terraces(flat_levels):
    stock = Stock(-22, 22, -22, 22, 0.0, 12.0)
    tool = Tool(8.0, "flat")
    rough = generate_roughing(plateau, stock, tool, stepdown=3.0, stepover=4.0,
                              axial_allowance=0.2, flat_levels=flat_levels)
    sim, base = check_common(rough, stock, tool, plateau, 3.0, 4.0, 0.0, 0.2)
    X, Y = np.meshgrid(sim.xs, sim.ys)
    top = (np.abs(X) < 11) & (np.abs(Y) < 11)
    left = float((sim.height[top] - 9.5).max())
    if flat_levels:
        assert any(abs(z - 9.5) < 1e-9 for z in rough.levels)
        assert left <= 0.05
    else:
        assert rough.levels == pytest.approx([9.0, 6.0, 5.2])
        assert left == pytest.approx(12.0 - 9.5, abs=1e-3)  # never reached: above level 9


@pytest.mark.venv_only  # a whole case-study roughing: run once, in the venv
@pytest.mark.parametrize("shape", ["flat", "bullnose"])
def test_fine_stepdown_terraces_and_order(shape):
    """Step-down 9 mm with a fine step-down of 3 mm: the levels every 9 mm are cut top-down and
    after each the levels every 3 mm in the band above it, bottom-up; the simulated stock left
    never lies more than the fine step above the part plus the allowances (check_common's
    bound with stepdown = 3), as with plain 3 mm levels, for a shorter cutting length, and no
    rapid cuts (check_common (d))."""
    stock = Stock(-25, 25, -25, 25, 0.0, 17.0)
    tool = Tool(8.0, "flat") if shape == "flat" else Tool(8.0, "bullnose", 1.0)
    kw = dict(stepover=3.0, radial_allowance=0.3, axial_allowance=0.2)
    fine = generate_roughing(hemisphere_on_plate, stock, tool, stepdown=9.0, fine_stepdown=3.0,
                             **kw)
    plain = generate_roughing(hemisphere_on_plate, stock, tool, stepdown=3.0, **kw)
    bands = _bands(fine.levels, stock.z_max, 9.0)
    mains = [z for z, _ in bands]
    assert mains[:2] == pytest.approx([8.0, 5.2])  # 17 - 9, then the plate (5 + 0.2)
    above = stock.z_max
    for z, band in bands:
        assert band == sorted(band)  # bottom-up
        assert all(z < b < above for b in band)
        assert np.all(np.diff([z, *band, above]) <= 3.0 + 1e-9)
        above = z
    assert sorted(fine.levels) == sorted(set(fine.levels))
    sim, base = check_common(fine, stock, tool, hemisphere_on_plate, 3.0, 3.0, 0.3, 0.2,
                             head_on=True)
    ref, _ = check_common(plain, stock, tool, hemisphere_on_plate, 3.0, 3.0, 0.3, 0.2,
                          head_on=True)
    reach = np.isfinite(hemisphere_on_plate(sim.xs, sim.ys))
    assert float((sim.height - base)[reach].max()) <= float((ref.height - base)[reach].max()) + 0.1
    assert fine.stats["cutting_length_mm"] < 0.9 * plain.stats["cutting_length_mm"]


@pytest.mark.venv_only  # a whole case-study roughing: run once, in the venv
def test_fine_stepdown_no_rapid_into_a_terrace_case_study():
    """The case study roughed at an 8 mm step-down with a 2 mm fine step: the job simulation of
    the program's text finds no rapid touching the stock.  (A rapid descent into a band
    touched a terrace 1 mm deep while the surface estimate took a cell as cut when only its
    centre lay within the tool.)"""
    height, stock = case_study_part()
    tool = Tool(10.0, "flat")
    rough = generate_roughing(height, stock, tool, 8.0, 4.0, 0.3, 0.3, fine_stepdown=2.0)
    job = simulate_text(rough, stock, tool, cell=0.1)
    assert rough.stats["ramps"] + rough.stats["entries"]["helical"] > 0  # entries inside
    assert not job.tools[1].collisions, job.tools[1].collisions[:3]
    assert float(job.volume.sum()) > 1e5  # it does rough: over 100 cm3 removed


@pytest.mark.parametrize("tool", [Tool(6.0, "flat"), Tool(6.0, "bullnose", 1.5),
                                  Tool(6.0, "ball")])
def test_surface_estimate_bounds_the_cut_over_whole_cells(tool):
    """After a pass, the roughing's estimate of the material's top (which decides where rapids
    may descend) lies at or above the true top over every point of every cell, sampled 7 x 7
    per cell: a cell whose centre the tool covered but not its corners keeps its old height
    there.  And it is no mere upper bound: the cells the tool covers whole drop to the
    level plus the profile."""
    cell = 0.25
    job, xs, ys = bare_job(cell, 8.0, tool, stepover=2.0)
    zeros = np.zeros(job.T.shape)
    job.surface = np.full(zeros.shape, 10.0)
    job.surface_lo = job.surface.copy()
    job.uncut = np.ones(zeros.shape, bool)
    job.z = 5.0
    path = np.array([[-6.0, -2.3], [1.1, 0.4], [5.0, 4.7]])
    job.mark(path)
    offsets = (np.arange(7) / 6.0 - 0.5) * cell
    truth = np.full(zeros.shape, -np.inf)
    lowest = np.full(zeros.shape, np.inf)
    dist_c = None
    for oy in offsets:
        for ox in offsets:
            X, Y = np.meshgrid(xs + ox, ys + oy)
            pts = np.column_stack([X.ravel(), Y.ravel()])
            a, b = path[:-1], path[1:]
            d = np.full(len(pts), np.inf)
            for p0, p1 in zip(a, b):
                t = np.clip(((pts - p0) @ (p1 - p0)) / float((p1 - p0) @ (p1 - p0)), 0, 1)
                d = np.minimum(d, np.hypot(*(pts - (p0 + t[:, None] * (p1 - p0))).T))
            d = d.reshape(zeros.shape)
            top = np.where(d <= tool.radius, 5.0 + tool.profile(np.minimum(d, tool.radius)),
                           10.0)
            truth = np.maximum(truth, top)
            lowest = np.minimum(lowest, top)
            if ox == 0 and oy == 0:
                dist_c = d
    assert float((truth - job.surface).max()) <= 1e-9
    # its lower bound (from which the depth of a cut is taken) lies at or below the true top
    # at every point of every cell, and drops wherever the tool reaches a cell
    assert float((job.surface_lo - lowest).max()) <= 1e-9
    assert np.all(job.surface_lo[lowest < 10.0] < 10.0)
    inner = dist_c <= tool.radius - 1.5 * cell
    assert inner.sum() > 500
    assert np.all(job.surface[inner] < 10.0)
    if tool.shape.value == "flat":
        assert np.all(job.surface[inner] == 5.0)


def test_a_feed_wider_than_the_stepover_is_peeled_within_it():
    """A pass along the edge of a cleared half-plane (y < 0) with its centre on the edge
    cuts R = 4 mm wide at a 2 mm stepover; :meth:`_Job.peel` cuts the same material in feeds
    each within the stepover.  Checked by the job simulation of the G-code text: the whole
    feed measures 4 mm, each of the peel's within 1.1 stepovers plus a cell, and after them
    the material within the feed's reach is gone as after the feed itself."""
    from BSplineCAM.core.program.gcode import read_gcode
    from BSplineCAM.core.simulation.job_simulation import simulate_job

    cell, s, z = 0.25, 2.0, 5.0
    tool = Tool(8.0, "flat")
    job, xs, ys = bare_job(cell, 20.0, tool, stepover=s)
    X, Y = np.meshgrid(xs, ys)
    # the previous pass came along y = 0 from x = -30 to -10 (head-on into the band)
    behind = np.hypot(np.maximum(X + 10.0, 0.0), Y) <= tool.radius
    job.uncut = (Y >= 0.0) & ~behind & (X <= 18.0)
    job.uncut_level = job.uncut.copy()
    job.floor = np.full(X.shape, 10.0)
    job.surface = np.where(job.uncut, 10.0, z)
    job.surface_lo = job.surface.copy()
    job.z = z
    a, b = np.array([-10.0, 0.0]), np.array([10.0, 0.0])
    assert job.engaged_width(a, b) == pytest.approx(4.0 + cell, abs=cell)
    way = job.peel(a, b, z)
    assert way is not None and len(way) > 2
    assert np.allclose(way[0], a) and np.allclose(way[-1], b)

    head = ["G21 G90 G17", "T1 M6", "G0 X-30 Y-4 Z20", "G1 Z5 F500", "G1 X30 Y-4",
            "G0 Z20", "G0 X-30 Y0", "G1 Z5", "G1 X-10 Y0"]
    box = (-20.0, 20.0, -20.0, 20.0, 0.0, 10.0)

    def run(points):
        text = "\n".join(head + [f"G1 X{x:.4f} Y{y:.4f}" for x, y in points] + ["M2"])
        return simulate_job(read_gcode(text + "\n", "peel"), {1: tool},
                            Grid.covering(*box[:4], 0.1), box)

    plain, peeled = run([b]), run(way[1:])
    assert float(plain.radial[-1]) == pytest.approx(4.0, abs=0.2)
    widths = peeled.radial[-(len(way) - 1):]
    assert float(widths.max()) <= 1.1 * s + 0.1, widths
    gx, gy = plain.grid.centres()
    GX, GY = np.meshgrid(gx, gy)
    reach = (np.abs(GX) <= 10.0) & (np.abs(GY) <= tool.radius - 0.1)
    assert float(np.abs(peeled.height - plain.height)[reach].max()) < 1e-9


def test_a_feed_ending_just_outside_the_region_is_peeled():
    """A contour's corner may stand some hundredths of a mm outside the region {T <= z} the
    tool's centre may take at a level (here 0.03 mm: the pass ends at the bottom of a notch in the
    region, whose tip reaches a sliver of the band beyond the wall, y < 0).  The feed into it
    from the upper right cuts the sliver 2.6 mm wide at a 2 mm stepover; a peel must end
    where the feed ends, so its own steps may stand out of the region as far as the feed
    does (a peel kept inside the region would never reach the feed's end, and the feed would
    stay).
    Checked by the job simulation of the G-code text, from a block that holds the band."""
    from BSplineCAM.core.program.gcode import read_gcode
    from BSplineCAM.core.simulation.job_simulation import simulate_job

    cell, s, z = 0.25, 2.0, 5.0
    tool = Tool(8.0, "flat")
    job, xs, ys = bare_job(cell, 20.0, tool, stepover=s)
    X, Y = np.meshgrid(xs, ys)
    # centres may stand above a notch y = 3.5 + |x| / 4, shifted 0.03 mm up
    job.T = z + (3.53 + 0.25 * np.abs(X) - Y)
    job.uncut = Y < 0.0
    job.uncut_level = job.uncut.copy()
    job.floor = np.full(X.shape, 10.0)
    job.surface = np.where(job.uncut, 10.0, z)
    job.surface_lo = job.surface.copy()
    job.z = z
    a, b = np.array([3.0, 6.5]), np.array([0.0, 3.5])
    assert job.level_width(a, b) > 1.1 * s + cell
    assert not job.in_region(a, b, z)
    way = job.peel(a, b, z)
    assert way is not None and len(way) > 2
    slack = job.region_slack(a, b, z)
    assert 0.01 < slack < 0.1  # 0.03 and the notch's kink between cells
    assert np.allclose(way[0], a) and np.allclose(way[-1], b)
    assert max(job.region_slack(p, q, z) for p, q in zip(way, way[1:])) <= slack + 1e-9

    box = (-20.0, 20.0, -20.0, 0.0, 0.0, 10.0)

    def run(points):
        text = "\n".join(["G21 G90 G17", "T1 M6", "G0 X3 Y6.5 Z20", "G1 Z5 F500"]
                         + [f"G1 X{x:.4f} Y{y:.4f}" for x, y in points] + ["M2"])
        return simulate_job(read_gcode(text + "\n", "notch"), {1: tool},
                            Grid.covering(-20.0, 20.0, -20.0, 20.0, 0.1), box)

    plain, peeled = run([b]), run(way[1:])
    assert float(plain.radial[-1]) > 1.1 * s + 0.1
    widths = peeled.radial[-(len(way) - 1):]
    assert float(widths.max()) <= 1.1 * s + 0.1, widths
    # the peel took all the feed took (and more of the sliver: the notch's flank lets the
    # tool down to it beside the end too)
    assert float((peeled.height - plain.height).max()) < 1e-9


def test_engaged_width_of_a_feed_against_a_band():
    """The width of cut the lead-ins are checked by, against a band of uncut material 3 mm wide
    beside a cleared floor (edge at y = 0), in closed form, the whole swath of a move as the
    job simulation measures it: a feed along the band 3 mm in cuts 3 mm; one leading into it
    at 10 degrees spans from the capsule's left edge (R across) to the point of its end cap
    where the band begins (y = 0: R sin(phi + a) = 1, across R sin(phi)), more than 3 mm, so
    a lead-in must be shallower; one head-on the tool's chord there, near the diameter."""
    cell = 0.1
    job, xs, ys = bare_job(cell, 20.0)
    job.uncut = np.broadcast_to((ys > 0.0)[:, None], (len(ys), len(xs))).copy()
    # tool centres at y = -4 + 3: 3 mm into the band along x
    along = job.engaged_width((-10.0, -1.0), (10.0, -1.0))
    assert along == pytest.approx(3.0, abs=2 * cell)
    # from clear (y = -4) into the band at 10 degrees, ending 3 mm in
    a = math.radians(10.0)
    dx = 3.0 / math.tan(a)
    oblique = job.engaged_width((-dx / 2, -4.0), (dx / 2, -1.0))
    assert oblique == pytest.approx(4.0 - 4.0 * math.sin(math.asin(0.25) - a) + cell, abs=cell)
    assert oblique > 3.0 + 2 * cell
    head_on = job.engaged_width((0.0, -4.0), (0.0, -1.0))
    assert head_on >= 2 * math.sqrt(16.0 - 1.0) - 2 * cell  # chord 3 mm deep in a 4 mm radius
    assert job.engaged_width((0.0, -9.0), (5.0, -9.0)) == 0.0


def test_engaged_width_counts_a_bullnose_fillet_as_the_simulation_does():
    """A 10 mm bull-nose of 2 mm corner radius slots along x through a 2 mm layer; the pass
    4 mm beside it also shaves the fillet the slot's corner left (the surface estimate holds
    it): its width of cut counts the fillet above half the cut's depth, as the job
    simulation does (corner_height), s + R - (R - rc) - sqrt(rc^2 - (rc - 1)^2) = 4.27 mm,
    where the uncut cells alone give the stepover; the slot cut again counts nothing (the
    same fillets), a pass 1 mm off its axis counts the fillet it shaves (a flat end mill
    leaves none: 1 mm of fresh material)."""
    cell = 0.1
    s, R, rc = 4.0, 5.0, 2.0
    for tool in (Tool(10.0, "bullnose", rc), Tool(10.0, "flat")):
        job, xs, ys = bare_job(cell, 20.0, tool, s)
        job.z = 0.0
        job.surface = np.full((len(ys), len(xs)), 2.0)
        job.surface_lo = job.surface.copy()
        job.uncut = np.ones((len(ys), len(xs)), bool)
        job.floor = np.full((len(ys), len(xs)), 2.0)
        job.mark(np.array([[-25.0, 0.0], [25.0, 0.0]]))
        beside = job.engaged_width((-10.0, s), (10.0, s))
        # the slot again: the same tool on the same line leaves the same fillets
        again = job.engaged_width((-10.0, 0.0), (10.0, 0.0))
        assert again == 0.0
        # 1 mm off the slot's axis: its flat reaches the fillet on that side, no fresh
        # material (beyond |y| = 5, within R of y = 1 only at y = 6: reached, 1 mm)
        off = job.engaged_width((-10.0, 1.0), (10.0, 1.0))
        if tool.shape.value == "flat":
            assert beside == pytest.approx(s + cell, abs=2 * cell)
            assert off == pytest.approx(1.0 + cell, abs=2 * cell)
        else:
            want = s + R - (R - rc) - math.sqrt(rc * rc - (rc - 1.0) ** 2)
            assert beside == pytest.approx(want + cell, abs=2 * cell)
            assert off > 1.0 + 3 * cell  # the fillet beyond y = 3 counts


def test_engaged_width_takes_the_corner_height_from_the_depth_of_cut():
    """A 10 mm bull-nose of 2 mm corner radius runs along x over a cleared floor crossed by a
    ridge 0.06 mm high along y (the toes of two fillets), with a band 0.3 mm high at
    y = 4.7..5 beside it, under the tool's corner where that stands 0.95 mm or more (not cut).
    The simulation takes the corner's height from the deepest drop, the ridge's 0.06 mm
    (corner_height 0.03), so the ridge counts wherever the tool passes 0.01 mm under it: the
    profile's 0.05 mm, |y| < 3 + sqrt(rc^2 - (rc - 0.05)^2), measured from each cell's far
    corner.  From the highest material it passed over (the band's 0.3 mm, corner 0.15) the
    width would be 0, and a lead-in on the case study would skim such toes 5.33 mm wide."""
    cell = 0.1
    rc = 2.0
    tool = Tool(10.0, "bullnose", rc)
    job, xs, ys = bare_job(cell, 20.0, tool, 4.0)
    X, Y = np.meshgrid(xs, ys)
    job.z = 0.0
    job.uncut = np.zeros(X.shape, bool)
    job.floor = np.zeros(X.shape)
    job.surface = np.where(np.abs(X) <= 0.3, 0.06, 0.0)
    job.surface[(Y >= 4.7) & (Y <= 5.0)] = 0.3
    job.surface_lo = job.surface.copy()
    half = 3.0 + math.sqrt(rc * rc - (rc - 0.05) ** 2) - 0.5 * math.sqrt(2.0) * cell
    assert job.engaged_width((-10.0, 0.0), (10.0, 0.0)) == pytest.approx(2 * half + cell,
                                                                          abs=2 * cell)
    # the band alone, not cut: nothing
    job.surface = np.where((Y >= 4.7) & (Y <= 5.0), 0.3, 0.0)
    job.surface_lo = job.surface.copy()
    assert job.engaged_width((-10.0, 0.0), (10.0, 0.0)) == 0.0
