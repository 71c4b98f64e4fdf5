# SPDX-License-Identifier: LGPL-2.1-or-later
"""Roughing's entries into closed pockets (core.toolpath.roughing): a helix where one fits, a
zig-zag ramp along a slot's length, a straight plunge with a centre-cutting end mill, and a
note naming what stays uncut otherwise; and the depth of cut outside the entries.  The moves
are cut one at a time out of a Z-map of the stock block (core.simulation.simulate's swept
envelope) and the stock left is compared with the parts, known in closed form."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from bsplinecam_helpers import cut_moves

from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.simulation.simulate import Grid, Tool
from BSplineCAM.core.toolpath.roughing import RAMP_ANGLE_DEG, Stock, generate_roughing

SIM_CELL = 0.2
TOOL = Tool(10.0, "flat")
STEPDOWN, STEPOVER, ALLOWANCE = 2.0, 4.0, 0.3
HOLE = (2.0, -16.0, 6.0)  # the plate's through hole: centre x, y and radius (mm)
PLATE_TOP = 16.0


def plate(xs, ys):
    """An 80 x 60 mm plate 16 mm thick with a boss of radius 9 mm up to z 22 at (-22, 0), a
    closed 24 x 16 mm pocket down to z 8 round (20, 8) and a 12 mm through hole at (2, -16)
    (no part there: NaN, as outside the plate)."""
    X, Y = np.meshgrid(xs, ys)
    h = np.full(X.shape, PLATE_TOP)
    h = np.where(np.hypot(X + 22.0, Y) <= 9.0, 22.0, h)
    h = np.where((np.abs(X - 20.0) <= 12.0) & (np.abs(Y - 8.0) <= 8.0), 8.0, h)
    h = np.where(np.hypot(X - HOLE[0], Y - HOLE[1]) <= HOLE[2], np.nan, h)
    return np.where((np.abs(X) <= 40.0) & (np.abs(Y) <= 30.0), h, np.nan)


PLATE_STOCK = Stock(-42.0, 42.0, -32.0, 32.0, 0.0, 24.0)
SLOT = (40.0, 12.2)  # the slot's length and width (mm)


def slot_plate(xs, ys):
    """A 60 x 40 mm plate 10 mm thick with a closed slot 40 x 12.2 mm (round ends) along x down
    to z 4 at the middle: a 10 mm mill's centre reaches 0.8 mm to each side of its axis at a
    0.3 mm allowance (0.4 mm beside the tip map's growth), too little for a helix, and 28 mm
    along it, a long chord for a zig-zag ramp."""
    X, Y = np.meshgrid(xs, ys)
    half = 0.5 * SLOT[1]
    axis = np.clip(X, -0.5 * SLOT[0] + half, 0.5 * SLOT[0] - half)
    slot = np.hypot(X - axis, Y) <= half
    h = np.where(slot, 4.0, 10.0)
    return np.where((np.abs(X) <= 30.0) & (np.abs(Y) <= 20.0), h, np.nan)


SLOT_STOCK = Stock(-32.0, 32.0, -22.0, 22.0, 0.0, 12.0)


class Cut:
    """The moves cut one at a time out of the block; per feed move outside the entries the
    deepest drop of a cell more than ``rim`` mm inside the tool's disk (the move's distance to
    the cell's centre below R - rim), and of any cell."""

    def __init__(self, rough, stock: Stock, tool: Tool, rim: float = SIM_CELL):
        grid = Grid.covering(stock.x_min, stock.x_max, stock.y_min, stock.y_max, SIM_CELL)
        h = np.full((grid.ny, grid.nx), stock.z_max, dtype=np.float32)
        xs, ys = grid.centres()
        entry = np.zeros(len(rough.moves), bool)
        for a, b in rough.stats["entry_spans"]:
            entry[a:b] = True
        self.inner: list = []  # (move index, deepest drop inside the disk by more than rim)
        self.any: list = []    # (move index, deepest drop)
        for i, m, pos, end, (ix0, iy0), _, drop in cut_moves(
                rough.moves, rough.clearance_height, h, tool, grid, stock.z_min, stock.z_max):
            if m.kind == "feed" and not entry[i] and float(drop.max()) > 0.0:
                # the distance of each cell's centre from the move's XY track
                rows, cols = drop.shape
                px = xs[ix0:ix0 + cols][None, :] - pos[0]
                py = ys[iy0:iy0 + rows][:, None] - pos[1]
                ab = end[:2] - pos[:2]
                t = np.clip((px * ab[0] + py * ab[1]) / max(float(ab @ ab), 1e-300), 0.0, 1.0)
                dist = np.hypot(px - t * ab[0], py - t * ab[1])
                self.any.append((i, float(drop.max())))
                inner = drop[dist <= tool.radius - rim]
                self.inner.append((i, float(inner.max(initial=0.0))))
        self.height = h.astype(float)
        self.xs, self.ys = xs, ys


def _rough(centre_cutting: bool, part=plate, stock=PLATE_STOCK, tool=TOOL):
    return generate_roughing(part, stock, tool, stepdown=STEPDOWN, stepover=STEPOVER,
                             radial_allowance=ALLOWANCE, axial_allowance=ALLOWANCE,
                             centre_cutting=centre_cutting)


def _job(rough, stock: Stock, tool: Tool = TOOL):
    """The roughing written as G-code and cut out of the block by core.job_simulation (its
    entries, radial and axial engagement per move)."""
    from BSplineCAM.core.program.gcode import read_gcode
    from BSplineCAM.core.simulation.job_simulation import simulate_job

    lines = ["G21 G90 G17", "T1 M6"]
    for m in rough.moves:
        feed = "" if m.kind == "rapid" else " F1000"
        lines.append(f"{'G0' if m.kind == 'rapid' else 'G1'} X{m.x:.4f} Y{m.y:.4f} "
                     f"Z{m.z:.4f}{feed}")
    lines.append("M2")
    program = read_gcode("\n".join(lines) + "\n", "roughing")
    return simulate_job(program, {1: tool}, Grid.covering(*stock.bounds[:4], 0.1), stock.bounds)


def _pocket_notes(rough) -> list:
    return [n for n in rough.stats["notes"] if "closed pocket" in n]


@pytest.mark.parametrize("centre_cutting", [False, True])
def test_plate_hole_plunged_or_named_and_no_deep_cut(centre_cutting):
    """The plate (boss, closed pocket, 12 mm through hole) roughed by a 10 mm flat at 2 mm
    down: the hole, where the mill's centre reaches 0.7 mm from the axis (a helix needs more,
    a zig-zag ramp a 10 mm chord), is plunged at every level below the plate's top with a
    centre-cutting mill and cleared down to the block's bottom; without it, it stays at the
    plate's top plus the allowance and the note says where, which Z range and which tools
    would enter it.  Either way no feed outside the entries cuts deeper than the step-down
    plus the allowance (plus 0.05 mm) with any cell more than a simulation cell inside the
    tool's rim."""
    rough = _rough(centre_cutting)
    assert rough.parameters["centre_cutting"] is centre_cutting
    st = rough.stats
    sim = Cut(rough, PLATE_STOCK, TOOL)
    X, Y = np.meshgrid(sim.xs, sim.ys)
    # the roughing leaves walls up to half a millimetre beyond the allowance (the tip map's
    # growth and the grid; TestBSplineCAMRoughing.check_common (b))
    in_hole = np.hypot(X - HOLE[0], Y - HOLE[1]) <= HOLE[2] - ALLOWANCE - 0.5
    # the levels at which the hole is a closed pocket: below the plate's top + allowance
    closed = [z for z in rough.levels if z < PLATE_TOP + ALLOWANCE - 1e-6]
    assert closed and min(closed) == pytest.approx(PLATE_STOCK.z_min)
    # the closed pocket (20, 8) is wide enough for a helix at each of its levels
    assert st["entries"]["helical"] >= 4 and st["entries"]["zigzag"] == 0
    if centre_cutting:
        assert st["entries"]["plunge"] == len(closed)
        assert not _pocket_notes(rough), st["notes"]
        # cleared down to the block's bottom (a through hole)
        assert float(sim.height[in_hole].max()) <= PLATE_STOCK.z_min + 0.05
        # each plunge is a straight feed down at the hole's axis from the material's top (at
        # most the plate's top + allowance, which the levels above left round the hole) to
        # within a lap's ramp of its level (the boundary of the centres' 0.3 mm disc, 2 mm
        # round, at tan 3 degrees: 0.1 mm), then that lap ramps down to the level
        slope = math.tan(math.radians(RAMP_ANGLE_DEG))
        seen = []
        for a, b in st["entry_spans"]:
            span = rough.moves[a:b]
            if math.hypot(span[-1].x - HOLE[0], span[-1].y - HOLE[1]) > 1.0:
                continue  # a helix into the pocket
            down = [(p, q) for p, q in zip(span, span[1:]) if q.kind == "feed"
                    and q.z < p.z - 1e-9 and (q.x, q.y) == (p.x, p.y)]
            p, q = down[-1]  # (after the approach feed to the material's top)
            level = span[-1].z
            assert math.hypot(q.x - HOLE[0], q.y - HOLE[1]) <= 0.5
            assert level in closed and p.z <= PLATE_TOP + ALLOWANCE + 1e-6
            assert level < q.z <= level + slope * 3.0
            seen.append(level)
            # the lap at the ramp angle, then at the level
            for u, v in zip(span[span.index(q):], span[span.index(q) + 1:]):
                run = math.hypot(v.x - u.x, v.y - u.y)
                assert u.z - v.z <= slope * run * 1.001 + 1e-9 and v.z >= level - 1e-9
        assert sorted(seen) == sorted(closed)
        # the job simulation counts every cut in the hole as entry (the plunge, the lap's
        # ramp and the lap at the level on its track): none outside the entries ends there
        job = _job(rough, PLATE_STOCK)
        seg = job.segments
        cutting = ~job.entry & (job.axial > job.threshold_mm) & ~np.asarray(seg.rapid, bool)
        ends = np.hypot(seg.end[:, 0] - HOLE[0], seg.end[:, 1] - HOLE[1]) <= 1.0
        assert not (cutting & ends).any(), job.radial[cutting & ends]
    else:
        assert st["entries"]["plunge"] == 0
        # untouched below the level above its first closed level: the plate's top + allowance
        assert float(sim.height[in_hole].min()) >= PLATE_TOP + ALLOWANCE - 0.05
        notes = _pocket_notes(rough)
        assert len(notes) == 1 and notes[0].startswith("1 closed pocket"), st["notes"]
        note = notes[0]
        x, y = (float(v) for v in re.search(r"\(([-\d.]+), ([-\d.]+)\) mm", note).groups())
        assert math.hypot(x - HOLE[0], y - HOLE[1]) <= 0.5
        # the box is the hole's, within a cell and a half of the roughing's grid
        box = [float(v) for v in re.search(
            r"within x ([-\d.]+) to ([-\d.]+) and y ([-\d.]+) to ([-\d.]+) mm", note).groups()]
        hole_box = [HOLE[0] - HOLE[2], HOLE[0] + HOLE[2], HOLE[1] - HOLE[2], HOLE[1] + HOLE[2]]
        assert np.allclose(box, hole_box, atol=0.5), (box, hole_box)
        lo, hi = (float(v) for v in re.search(r"uncut from Z ([-\d.]+) to ([-\d.]+) mm",
                                              note).groups())
        assert lo == pytest.approx(PLATE_STOCK.z_min) and hi == pytest.approx(
            PLATE_TOP + ALLOWANCE)
        fits = float(re.search(r"a tool of at most ([\d.]+) mm enters it by a helix",
                               note).group(1))
        # a helix of the smallest radius a 9 mm tool's entry asks (max(2 cells, 0.05 D))
        # beside 1.5 cells fits a hole 11.4 mm wide only for a tool under 11.4 - 2 * 0.3
        assert 8.0 < fits < 2 * (HOLE[2] - ALLOWANCE) - 0.6
        assert "--centre-cutting" in note and "CentreCutting" in note
    # no feed outside the entries takes more than the step-down and the allowance where it
    # cuts more than a simulation cell inside its rim
    limit = STEPDOWN + ALLOWANCE + 0.05
    deep = [(i, d) for i, d in sim.inner if d > limit]
    assert not deep, f"{len(deep)} moves cut deeper than {limit} mm, up to {max(deep)}"
    # not vacuous: the passes do cut a whole step-down (at the rim only: hair-thin columns)
    assert max(d for _, d in sim.inner) >= STEPDOWN - 0.05
    # the job simulation's depth of cut is that same measure: at most the step-down and the
    # allowance outside the entries and in them, though the rim shaves columns several
    # step-downs tall beside the walls
    report = _job(rough, PLATE_STOCK).tools[1]
    assert report.axial_engagement_max_mm <= limit, report
    assert report.entry_axial_engagement_max_mm <= limit, report
    assert max(d for _, d in sim.any) > limit  # the columns the rim shaves


def test_slot_entered_by_a_zigzag_ramp():
    """A closed slot 12.2 mm wide, 40 mm long, too narrow for the 10 mm mill's helix: each of
    its levels is entered by a zig-zag ramp along its axis at the ramp angle (never steeper),
    no plunge and no note, and the slot is cleared to its floor plus the allowance; no feed
    outside the entries cuts deeper than the step-down and the allowance inside the rim."""
    rough = _rough(False, slot_plate, SLOT_STOCK)
    st = rough.stats
    assert st["entries"]["plunge"] == 0 and st["entries"]["helical"] == 0
    closed = [z for z in rough.levels if z < 10.0 + ALLOWANCE - 1e-6]
    assert st["entries"]["zigzag"] == len(closed) >= 3, (st["entries"], rough.levels)
    assert not _pocket_notes(rough), st["notes"]
    slope = math.tan(math.radians(RAMP_ANGLE_DEG))
    moves = rough.moves
    ramps = most = 0
    reach = 0.5 * SLOT[1] - ALLOWANCE - TOOL.radius  # the centres' reach from the axis
    for a, b in st["entry_spans"]:
        span = moves[a:b]
        feeds = [(p, q) for p, q in zip(span, span[1:]) if q.kind == "feed"
                 and (q.x, q.y) != (p.x, p.y)]
        # a zig-zag ramp starts along the slot's axis, the chord through the centres' middle
        # (the other entries, ramps along the level's passes round it, start off it)
        if not feeds or abs(feeds[0][1].y) > 0.05 or abs(feeds[0][0].y) > 0.05:
            continue
        ramps += 1
        level = span[-1].z
        turns = 0
        for (p, q), (_, r) in zip(feeds, feeds[1:] + [(None, None)]):
            # within the centres' reach, never below the level, never steeper than the ramp
            assert abs(q.y) <= reach + 1e-6
            assert abs(q.x) <= 0.5 * (SLOT[0] - SLOT[1]) + reach + 1e-6
            assert q.z >= level - 1e-9
            assert p.z - q.z <= slope * math.hypot(q.x - p.x, q.y - p.y) * 1.001 + 1e-9
            if r is not None and abs(q.y) < 1e-9 and abs(r.y) < 1e-9 and \
                    (q.x - p.x) * (r.x - q.x) < 0:
                turns += 1
        # it ends with a closed lap round the centres' boundary at the level, 0.3 mm or more
        # off the axis on both sides
        flat = [q for _, q in feeds if abs(q.z - level) < 1e-9]
        assert math.hypot(flat[0].x - flat[-1].x, flat[0].y - flat[-1].y) < 1e-6
        assert min(q.y for q in flat) <= -0.3 and max(q.y for q in flat) >= 0.3
        most = max(most, turns)
    # back and forth: one sweep of the 28 mm chord descends 1.5 mm, and the deepest ramp
    # starts above the slot's first level (the material's top the estimate holds beside it)
    assert most >= 2
    assert ramps == len(closed)
    sim = Cut(rough, SLOT_STOCK, TOOL)
    X, Y = np.meshgrid(sim.xs, sim.ys)
    half = 0.5 * SLOT[1]
    axis = np.clip(X, -0.5 * SLOT[0] + half, 0.5 * SLOT[0] - half)
    # (walls left up to half a millimetre beyond the allowance, as in the plate's hole)
    inside = np.hypot(X - axis, Y) <= half - ALLOWANCE - 0.5
    left = sim.height[inside] - (4.0 + ALLOWANCE)
    assert float(left.max()) <= 0.05, (X[inside][np.argmax(left)], Y[inside][np.argmax(left)])
    limit = STEPDOWN + ALLOWANCE + 0.05
    deep = [(i, d) for i, d in sim.inner if d > limit]
    assert not deep, f"{len(deep)} moves cut deeper than {limit} mm, up to {max(deep)}"
    # the job simulation's width of cut outside the entries (the ramps, the laps and the way
    # round them at the level) stays within 1.1 stepover and its 0.1 mm cell, as the main
    # job's check asks; no rapid cuts
    job = _job(rough, SLOT_STOCK)
    report = job.tools[1]
    assert report.radial_engagement_max_mm <= 1.1 * STEPOVER + 0.1, report
    assert report.entries >= len(closed) and not report.collisions


def test_centre_cutting_must_be_a_bool():
    with pytest.raises(ParameterError, match="centre_cutting"):
        _rough("yes", slot_plate, SLOT_STOCK)
