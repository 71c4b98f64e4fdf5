# SPDX-License-Identifier: LGPL-2.1-or-later
"""Whole-program simulation with tool changes: engagement, volumes and collisions against
closed forms (slot, stepover, ramp, face + ball groove, a slot through a cylinder stock), and
the one-tool simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.job_simulation import check_stock_form, simulate_job
from BSplineCAM.core.simulation.simulate import Grid, Tool, simulate_program
from BSplineCAM.core.simulation.stock import CylinderStock, Stock

CELL = 0.2
FLAT10 = Tool(10.0, "flat")
BALL6 = Tool(6.0, "ball")


def program(*lines: str) -> str:
    return "\n".join(["G21 G90 G17", "(header)", *lines, "M2"]) + "\n"


def slot_lines(y: float, z: float, x0: float = -10.0, x1: float = 60.0,
               feed: float = 600.0) -> list[str]:
    return [f"G0 X{x0} Y{y} Z5", f"G0 Z{z + 3}", f"G1 Z{z} F{feed}", f"G1 X{x1}", "G0 Z5"]


def grid_for(x0: float, x1: float, y0: float, y1: float) -> Grid:
    # whole cells from the corner, so cell centres sit at odd multiples of CELL / 2
    return Grid(x0, y0, CELL, round((x1 - x0) / CELL), round((y1 - y0) / CELL))


def feeds_of(job, line: int) -> np.ndarray:
    return np.flatnonzero((job.segments.line == line) & ~job.segments.rapid)


def test_full_width_slot() -> None:
    """A flat 10 mm tool slotting 2 mm deep through a 50 mm block: radial engagement 10 mm,
    axial 2 mm, volume 10 x 50 x 2 mm^3, removal rate D x depth x feed."""
    text = program("T1 M6", *slot_lines(0.0, -2.0))
    job = simulate_job(read_gcode(text), {1: FLAT10}, grid_for(-20, 70, -20, 20),
                       (0, 50, -20, 20, -10, 0))
    report = job.tools[1]
    cut = feeds_of(job, 7)
    assert len(cut) == 1
    assert abs(job.radial[cut[0]] - 10.0) <= CELL
    assert job.axial[cut[0]] == pytest.approx(2.0, abs=1e-5)
    assert report.radial_engagement_max_mm == pytest.approx(10.0, abs=CELL)
    assert report.axial_engagement_max_mm == pytest.approx(2.0, abs=1e-5)
    assert report.removed_volume_mm3 == pytest.approx(10 * 50 * 2, rel=1e-4)
    assert report.material_removal_rate_max_mm3_per_min == pytest.approx(10 * 2 * 600, rel=1e-3)
    assert report.max_radial_line == 7
    assert report.cutting_length_mm == pytest.approx(70.0)
    assert report.air_length_mm == pytest.approx(3.0)  # the plunge beside the block
    assert report.collisions == ()
    # cells outside the block's XY have no material and never change
    assert np.all(job.height[~job.in_stock] == -10.0)
    xs, ys = job.grid.centres()
    slot = (np.abs(ys[:, None]) <= 5.0) & job.in_stock
    assert np.allclose(job.height[slot], -2.0, atol=1e-5)
    assert np.all(job.height[job.in_stock & ~slot] == 0.0)


def test_slot_ending_in_the_block() -> None:
    """A slot that stops inside the block: rectangle plus the tool's half disc."""
    text = program("T1 M6", *slot_lines(0.0, -3.0, x1=30.0))
    job = simulate_job(read_gcode(text), {1: FLAT10}, grid_for(-20, 70, -20, 20),
                       (0, 50, -20, 20, -10, 0))
    expected = 3.0 * (10 * 30 + math.pi * 25 / 2)
    assert job.tools[1].removed_volume_mm3 == pytest.approx(expected, rel=5e-3)


@pytest.mark.parametrize("stepover", [1.5, 3.0, 7.0])
def test_pass_beside_a_cleared_region(stepover: float) -> None:
    """A second pass at stepover s beside a slot engages s radially (within a cell) and
    removes s x length x depth."""
    text = program("T1 M6", *slot_lines(0.0, -2.0), *slot_lines(stepover, -2.0))
    job = simulate_job(read_gcode(text), {1: FLAT10}, grid_for(-20, 70, -20, 20),
                       (0, 50, -20, 20, -10, 0))
    second = feeds_of(job, 12)
    second = second[job.axial[second] > 0]
    assert len(second) == 1
    assert abs(job.radial[second[0]] - stepover) <= CELL + 1e-6
    assert job.volume[second[0]] == pytest.approx(stepover * 50 * 2, abs=CELL * 50 * 2)
    report = job.tools[1]
    assert report.removed_volume_mm3 == pytest.approx((10 + stepover) * 50 * 2,
                                                      abs=CELL * 50 * 2)
    # the length-weighted mean over the two cutting passes (70 mm each)
    assert report.radial_engagement_mean_mm == pytest.approx((10 + stepover) / 2, abs=CELL)


@pytest.mark.parametrize("depth", [2.0, 6.0])
def test_bullnose_pass_beside_a_cleared_region_is_measured_above_its_corner(depth) -> None:
    """A 10 mm bull-nose of 2 mm corner radius slots, then passes 4 mm beside the slot: the
    second pass also shaves the fillet the first one's corner left, but the radial
    engagement counts only material above the corner (at most half the cut's depth): the
    closed form s + R - (R - rc) - sqrt(rc^2 - (rc - h)^2), h = min(rc, depth / 2): the
    stepover itself when the cut is deeper than twice the corner, 4.27 mm at 2 mm deep.  The
    slot is the diameter either way."""
    tool = Tool(10.0, "bullnose", 2.0)
    s, R, rc = 4.0, 5.0, 2.0
    text = program("T1 M6", *slot_lines(0.0, -depth), *slot_lines(s, -depth))
    job = simulate_job(read_gcode(text), {1: tool}, grid_for(-20, 70, -20, 20),
                       (0, 50, -20, 20, -10, 0))
    first, second = feeds_of(job, 7), feeds_of(job, 12)
    first, second = first[job.axial[first] > 0], second[job.axial[second] > 0]
    assert abs(job.radial[first[0]] - 10.0) <= CELL + 1e-6
    h = min(rc, depth / 2)
    want = s + R - (R - rc) - math.sqrt(rc * rc - (rc - h) ** 2)
    assert abs(job.radial[second[0]] - want) <= CELL + 1e-6
    # the volume still counts the fillet: the pass shaves the previous one and leaves its
    # own, so it removes s x depth per mm
    assert job.volume[second[0]] == pytest.approx(50 * s * depth, rel=0.02)


def test_ball_groove_beside_a_groove_is_measured_at_half_its_depth() -> None:
    """A 10 mm ball grooves 2 mm deep into the top, then again 4 mm beside: the first
    groove's material all stood at the top, its full width 2 sqrt(2 R d - d^2) = 8 mm
    counts; of the second only the material higher than half the depth above its tip counts
    (the cusp between the grooves is lower): from the first groove's flank at that height
    to the second's far edge, s + 4 - sqrt(R^2 - (R - 1)^2) = 5 mm (6 mm counting the cusp)."""
    R, s, depth = 5.0, 4.0, 2.0
    text = program("T1 M6", *slot_lines(0.0, -depth), *slot_lines(s, -depth))
    job = simulate_job(read_gcode(text), {1: Tool(10.0, "ball")}, grid_for(-20, 70, -20, 20),
                       (0, 50, -20, 20, -10, 0))
    first, second = feeds_of(job, 7), feeds_of(job, 12)
    first, second = first[job.axial[first] > 0], second[job.axial[second] > 0]
    edge = math.sqrt(2 * R * depth - depth * depth)  # the groove's half width at the top
    flank = math.sqrt(R * R - (R - depth / 2) ** 2)  # its half width half way up
    assert abs(job.radial[first[0]] - 2 * edge) <= CELL + 1e-6
    assert abs(job.radial[second[0]] - (s + edge - flank)) <= CELL + 1e-6


def test_ramp_is_an_entry_with_growing_axial_engagement() -> None:
    """A ramp into the block in ten moves: each move's axial engagement is its end depth
    (linear), all are entries, and the radial maximum leaves them out."""
    steps = [f"G1 X{2 * k} Z{-0.2 * k:.1f}" for k in range(1, 11)]
    text = program("T2 M6", "G0 X0 Y0 Z5", "G0 Z0", "F300", *steps, "G0 Z5")
    tool = Tool(6.0, "flat")
    job = simulate_job(read_gcode(text), {2: tool}, grid_for(-20, 40, -10, 10),
                       (-20, 40, -10, 10, -10, 0))
    ramp = np.flatnonzero(job.entry)
    assert len(ramp) == 10
    depths = np.arange(1, 11) * 0.2
    assert np.allclose(job.axial[ramp], depths, atol=1e-4)
    assert np.all(np.abs(job.radial[ramp] - 6.0) <= CELL)
    report = job.tools[2]
    assert report.entries == 10
    assert report.entry_axial_engagement_max_mm == pytest.approx(2.0, abs=1e-4)
    assert report.entry_radial_engagement_max_mm == pytest.approx(6.0, abs=CELL)
    assert report.radial_engagement_max_mm == 0.0  # nothing but entries cut
    assert report.max_radial_line is None
    # volume: at (x, y) the flat end reaches depth min(x + w, 20) / 10, w = sqrt(9 - y^2);
    # integrated: a wedge 6 wide, 20 long and 2 deep (120 mm^3) plus the disc 2 deep (18 pi)
    assert report.removed_volume_mm3 == pytest.approx(120 + 18 * math.pi, rel=5e-3)


def test_entry_is_the_path_of_the_descent_not_its_bounding_circle() -> None:
    """A ramp 40 mm along X down 2 mm, half the way back over it (an entry: it clears the
    wedge the ramp left), then a step and a pass 8 mm beside the ramp's line: inside the
    circle round the ramp's box, but off its path, so no entry and their engagement counts
    (the old footprint, that circle, took both for entry moves and left them out)."""
    text = program("T1 M6", "G0 X0 Y0 Z5", "G0 Z0.5", "G1 Z0 F300", "G1 X40 Z-2",
                   "G1 X20", "G1 Y8", "G1 X30", "G0 Z5")
    prog = read_gcode(text)
    from BSplineCAM.core.simulation.job_simulation import entry_moves

    marked = entry_moves(prog)
    feeds = np.flatnonzero(prog.kind != 0)
    # plunge to Z0 (no descent into the stock top), ramp, way back: entries; step, pass: not
    assert marked[feeds[1]] and marked[feeds[2]]
    assert not marked[feeds[3]] and not marked[feeds[4]]
    job = simulate_job(prog, {1: FLAT10}, grid_for(-10, 50, -10, 20), (-10, 50, -10, 20, -5, 0))
    pass_ = job.segments.move == feeds[4]
    assert not job.entry[pass_].any()
    assert float(job.radial[pass_].max()) == pytest.approx(8.0, abs=2 * CELL)
    # the step sideways out of the slot cuts head-on, the full diameter; both count
    assert job.tools[1].radial_engagement_max_mm == pytest.approx(10.0, abs=CELL)


def two_tool_text() -> str:
    face = []
    for i, y in enumerate(range(0, 31, 5)):
        x0, x1 = (-6, 36) if i % 2 == 0 else (36, -6)
        face += [f"G0 X{x0} Y{y} Z12", "G1 Z8 F800", f"G1 X{x1}", "G0 Z12"]
    groove = ["G0 X-5 Y15 Z12", "G1 Z5 F400", "G1 X35", "G0 Z12"]
    return program("(T1: flat end mill 10 mm)", "T1 M6", "S10000 M3", *face,
                   "(T2: ball end mill 6 mm)", "M6 T2", "M3 S12000", *groove, "M5")


def test_two_tools_add_up_to_the_block_minus_the_part() -> None:
    """T1 (flat 10) faces a 30 x 30 x 10 block down to z 8, T2 (ball 6) cuts a groove with its
    tip at z 5: per-tool volumes are the closed forms, they add up to the block minus the
    final shape, and the final Z-map is the closed-form one."""
    prog = read_gcode(two_tool_text())
    assert set(prog.tool.tolist()) == {1, 2}
    grid = grid_for(-10, 40, -10, 40)
    job = simulate_job(prog, {1: FLAT10, 2: BALL6}, grid, (0, 30, 0, 30, 0, 10))
    xs, ys = grid.centres()
    dy = np.abs(ys[:, None] - 15.0) + 0 * xs[None, :]
    final = np.where(dy < 3.0, 8.0 - np.sqrt(np.maximum(9.0 - dy * dy, 0.0)), 8.0)
    inside = job.in_stock
    assert np.allclose(job.height[inside], final[inside], atol=1e-4)
    area = CELL * CELL
    block_minus_part = float(np.sum(10.0 - final[inside]) * area)
    v1 = job.tools[1].removed_volume_mm3
    v2 = job.tools[2].removed_volume_mm3
    assert v1 == pytest.approx(30 * 30 * 2, rel=1e-5)
    assert v2 == pytest.approx(30 * math.pi * 9 / 2, rel=5e-3)
    assert v1 + v2 == pytest.approx(block_minus_part, rel=1e-5)
    assert job.removed_volume() == pytest.approx(v1 + v2)
    # the snapshot after T1 is the faced block
    assert np.allclose(job.snapshots[1][inside], 8.0, atol=1e-5)
    assert np.allclose(job.snapshots[2], job.height)
    # the deepest cell centre is 0.1 mm off the groove's axis
    assert job.tools[2].axial_engagement_max_mm == pytest.approx(math.sqrt(9 - 0.01), abs=1e-4)
    assert job.tools[2].radial_engagement_max_mm == pytest.approx(6.0, abs=CELL)
    assert job.collisions == ()


def test_rapid_through_stock_is_a_collision() -> None:
    text = program("T1 M6", "G0 X-10 Y0 Z5", "G0 Z-1", "G0 X60", "G0 Z5")
    job = simulate_job(read_gcode(text), {1: FLAT10}, grid_for(-20, 70, -20, 20),
                       (0, 50, -20, 20, -10, 0))
    (hit,) = job.tools[1].collisions
    assert hit.line == 6
    assert hit.depth_mm == pytest.approx(1.0, abs=1e-5)
    assert 0 <= hit.x <= 50 and abs(hit.y) <= 5
    assert job.collisions == (hit,)
    assert job.tools[1].cutting_length_mm == 0.0


def test_feed_in_air() -> None:
    text = program("T1 M6", "G0 X-10 Y0 Z5", "G1 Z1 F500", "G1 X60", "G1 Y10", "G0 Z5")
    job = simulate_job(read_gcode(text), {1: FLAT10}, grid_for(-20, 70, -20, 20),
                       (0, 50, -20, 20, -10, 0))
    report = job.tools[1]
    assert report.air_length_mm == pytest.approx(4 + 70 + 10)
    assert report.cutting_length_mm == 0.0
    assert report.removed_volume_mm3 == 0.0
    assert np.all(job.height[job.in_stock] == 0.0)


def test_missing_tool_names_tool_and_line() -> None:
    text = program("T1 M6", *slot_lines(0.0, -1.0), "(next)", "T3 M6", *slot_lines(5.0, -1.0))
    with pytest.raises(ParameterError, match=r"line 10: tool change to T3"):
        simulate_job(read_gcode(text), {1: FLAT10, 2: BALL6}, grid_for(-20, 70, -20, 20),
                     (0, 50, -20, 20, -10, 0))


@pytest.mark.parametrize("stock", [(0, 0, 0, 1, 0, 1), (0, 1, 0, 1, 2, 1),
                                   (0, 1, 0, math.nan, 0, 1), (0, 1, 0, 1),
                                   (0, 1, 0, 1, 0, 10**400), (0, 1, 0, 1, -math.inf, 2e6)])
def test_bad_stock(stock) -> None:
    with pytest.raises(ParameterError, match="stock"):
        simulate_job(read_gcode(program("T1 M6", *slot_lines(0, -1))), {1: FLAT10},
                     grid_for(-20, 70, -20, 20), stock)


@pytest.mark.parametrize("tool", [Tool(6.0, "ball"), Tool(8.0, "bullnose", 1.5), FLAT10])
def test_same_height_as_the_one_tool_simulator(tool: Tool) -> None:
    """Without tool changes and with a block covering the grid, the final Z-map is that of
    ``simulate_program`` (cut in one pass, batched in another order): lines, arcs, diagonals
    longer than the pieces, a helix and plunges."""
    text = program(
        "G0 X5 Y5 Z3", "G1 Z-1 F500", "G1 X75 Y38", "G1 Y10 Z-2", "G2 X60 Y25 I-15 J0",
        "G3 X20 Y20 Z-3 R25", "G1 X70 Y2 Z-1.5", "G0 Z3", "G0 X50 Y20", "G1 Z-4",
        "G2 X50 Y20 Z-5 I0 J6", "G0 Z3",
    )
    prog = read_gcode(text)
    grid = Grid(0.0, 0.0, 0.25, 320, 160)
    job = simulate_job(prog, {0: tool}, grid, (0, 80, 0, 40, -math.inf, 0.0))
    reference = simulate_program(prog, tool, grid, 0.0)
    assert np.allclose(job.height, reference.height, atol=2e-5)
    assert job.removed_volume() == pytest.approx(reference.removed_volume(), rel=1e-5)
    assert job.tools[0].removed_volume_mm3 == pytest.approx(job.removed_volume())


def test_progress_reported_and_can_abandon_the_run() -> None:
    class Stop(Exception):
        pass

    calls: list[float] = []

    lines = ["T1 M6", "G0 X-6 Y0 Z5", "G1 Z-1 F1000"]
    for k in range(3000):
        lines.append(f"G1 X{(k % 100) + 0.5} Y{(k // 100) * 0.5}")
    prog = read_gcode(program(*lines))
    grid = Grid(-10, -10, 0.2, 650, 200)
    simulate_job(prog, {1: FLAT10}, grid, (0, 100, 0, 20, -10, 0), progress=calls.append)
    assert calls[-1] == 1.0 and all(0 <= a <= b <= 1 for a, b in zip(calls, calls[1:]))

    def stop(fraction: float) -> None:
        raise Stop

    with pytest.raises(Stop):
        simulate_job(prog, {1: FLAT10}, grid, (0, 100, 0, 20, -10, 0), progress=stop)


def plane_job_text() -> str:
    """T1 (flat 10) faces a 40 x 30 block from z 14 to 11; T2 (ball 6) rasters z 10 every
    1 mm across x, over the plane z = 10 of 40 x 30 mm."""
    lines = ["T1 M6"]
    for k, y in enumerate(range(0, 31, 5)):
        x0, x1 = (-6, 46) if k % 2 == 0 else (46, -6)
        lines += [f"G0 X{x0} Y{y} Z16", "G1 Z11 F800", f"G1 X{x1}", "G0 Z16"]
    lines += ["M6 T2"]
    for k, y in enumerate(np.arange(0.0, 30.01, 1.0)):
        x0, x1 = (-4, 44) if k % 2 == 0 else (44, -4)
        lines += [f"G0 X{x0} Y{y} Z16", "G1 Z10 F600", f"G1 X{x1}", "G0 Z16"]
    return program(*lines)


def test_verify_job_surface_and_faces() -> None:
    """verify_job measures the final Z-map as verify/verify_faces do: a ball raster at 1 mm
    stepover on a plane leaves scallops of R - sqrt(R^2 - (s/2)^2), no gouge; the per-tool
    volumes are the faced layer and the last millimetre less the scallops."""
    from BSplineCAM.core.geometry.faces import Face
    from BSplineCAM.core.geometry.nurbs import NurbsSurface
    from BSplineCAM.core.geometry.surface import Surface
    from BSplineCAM.core.simulation.verify import verify_job

    x, y = np.meshgrid(np.linspace(0, 40, 5), np.linspace(0, 30, 4), indexing="ij")
    surface = Surface(np.stack([x, y, np.full_like(x, 10.0)], axis=-1), "clamped", "plane")
    poles = np.array([[[0, 0, 10], [0, 30, 10]], [[40, 0, 10], [40, 30, 10]]], dtype=float)
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    face = Face(NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1), square)
    prog = read_gcode(plane_job_text())
    tools = {1: FLAT10, 2: BALL6}
    scallop = 3.0 - math.sqrt(9.0 - 0.25)
    for model in (surface, [face]):
        result = verify_job(model, prog, tools, (0, 40, 0, 30, 0, 14), cell=0.1)
        m = result.metrics
        assert m["gouge_max_mm"] < 1e-4
        # at the cell centres nearest the middle between passes (1 mm apart at whole y)
        _, ys = result.simulation.grid.centres()
        d = np.abs(ys - np.round(ys))[result.inner.any(axis=1)]
        assert m["scallop_max_mm"] == pytest.approx(3.0 - math.sqrt(9.0 - d.max() ** 2),
                                                    abs=1e-4)
        assert m["tool"]["shape"] == "ball" and set(m["tools"]) == {"1", "2"}
        assert m["tools"]["1"]["removed_volume_mm3"] == pytest.approx(40 * 30 * 3, rel=1e-4)
        v2 = m["tools"]["2"]["removed_volume_mm3"]
        assert 40 * 30 * (1 - scallop) < v2 < 40 * 30
        assert m["removed_volume_mm3"] == pytest.approx(result.job.removed_volume())
        assert result.simulation.height.shape == result.design.shape


def test_verify_job_without_stock_matches_verify() -> None:
    """Without a stock block verify_job cuts the block verify does (the grid, top from
    stock_top), so a one-tool program gives the same height map and figures."""
    from BSplineCAM.core.geometry.surface import Surface
    from BSplineCAM.core.simulation.verify import verify, verify_job

    x, y = np.meshgrid(np.linspace(0, 40, 5), np.linspace(0, 30, 4), indexing="ij")
    surface = Surface(np.stack([x, y, np.full_like(x, 10.0)], axis=-1), "clamped", "plane")
    lines = ["T1 M6"]
    for k, yy in enumerate(np.arange(0.0, 30.01, 1.5)):
        x0, x1 = (-4, 44) if k % 2 == 0 else (44, -4)
        lines += [f"G0 X{x0} Y{yy} Z16", "G1 Z10 F600", f"G1 X{x1}", "G0 Z16"]
    prog = read_gcode(program(*lines))
    one = verify(surface, prog, BALL6, cell=0.25)
    job = verify_job(surface, prog, {1: BALL6}, cell=0.25)
    assert np.allclose(job.simulation.height, one.simulation.height, atol=2e-5)
    for key in ("gouge_max_mm", "scallop_max_mm", "coverage", "uncut_fraction",
                "removed_volume_mm3"):
        assert job.metrics[key] == pytest.approx(one.metrics[key], rel=1e-5, abs=1e-5), key
    assert job.metrics["warnings"] == []
    small = verify_job(surface, prog, {1: BALL6}, (5, 40, 0, 30, 0, 11), cell=0.25)
    assert any("uncovered" in w for w in small.metrics["warnings"])


def test_helix_closing_turn_is_part_of_the_entry() -> None:
    """A helical entry (radius 3, two turns down 1 mm) then one level turn on the same circle
    and a pass out of it: the level turn clears the wedge the helix left (a full-width cut)
    and counts as entry; the pass beyond the helix's circle does not."""
    r, turns, n = 3.0, 2, 24
    lines = ["T1 M6", f"G0 X{r} Y0 Z5", "G0 Z0.5", "G1 Z0 F300"]
    for k in range(1, turns * n + 1):
        a = 2 * math.pi * k / n
        lines.append(f"G1 X{r * math.cos(a):.5f} Y{r * math.sin(a):.5f} Z{-k / (turns * n):.5f}")
    for k in range(1, n + 1):
        a = 2 * math.pi * k / n
        lines.append(f"G1 X{r * math.cos(a):.5f} Y{r * math.sin(a):.5f} Z-1")
    lines += ["G1 X12 Y0 Z-1", "G0 Z5"]
    prog = read_gcode(program(*lines))
    from BSplineCAM.core.simulation.job_simulation import entry_moves

    marked = entry_moves(prog)
    feeds = np.flatnonzero(prog.kind != 0)
    helix = feeds[1:1 + turns * n]
    closing = feeds[1 + turns * n:1 + (turns + 1) * n]
    assert marked[helix].all() and marked[closing].all()
    assert not marked[feeds[-1]]  # the pass out of the circle
    job = simulate_job(prog, {1: FLAT10}, grid_for(-20, 20, -20, 20), (-20, 20, -20, 20, -5, 0))
    report = job.tools[1]
    assert report.entry_radial_engagement_max_mm == pytest.approx(10.0, abs=2 * CELL)
    # the pass out cuts a slot beside the helix's hole: at most the diameter, and it is the
    # only non-entry cutting move
    assert report.radial_engagement_max_mm <= 10.0 + CELL


def test_closing_lap_of_a_ramp_round_a_closed_pass_is_part_of_the_entry() -> None:
    """A ramp down 2 mm along the first half of a square pass's first side, then the rest of
    the square at the level and back along the ramp's track to its end (the closing lap,
    which clears the wedge the ramp left), then a step out of the square: the closing lap
    counts as entry, though moves off the ramp's track came between; the square's other
    sides (one ends on the track, its midpoint off it) and the step out do not."""
    ramp = [f"G1 X{5 * k} Z{-0.5 * k:.1f}" for k in range(1, 5)]
    text = program("T1 M6", "G0 X0 Y0 Z5", "G0 Z0.5", "G1 Z0 F300", *ramp,
                   "G1 X40", "G1 Y40", "G1 X0", "G1 Y0", "G1 X10", "G1 X20",
                   "G1 Y10", "G0 Z5")
    prog = read_gcode(text)
    from BSplineCAM.core.simulation.job_simulation import entry_moves

    marked = entry_moves(prog)
    feeds = np.flatnonzero(prog.kind != 0)
    assert marked[feeds[1:5]].all()  # the ramp
    assert not marked[feeds[5:9]].any()  # round the square
    assert marked[feeds[9]] and marked[feeds[10]]  # the closing lap
    assert not marked[feeds[11]]  # the step out
    job = simulate_job(prog, {1: FLAT10}, grid_for(-10, 50, -10, 50), (-10, 50, -10, 50, -5, 0))
    lap = np.isin(job.segments.move, feeds[9:11])
    assert job.entry[lap].all() and float(job.axial[lap].max()) > 1.0  # it cut the wedge
    assert job.tools[1].entries >= 1


# -- a cylinder stock (CAM's "CreateCylinder") ------------------------------------------------
CYLINDER = CylinderStock(25.0, 0.0, 20.0, -10.0, 0.0)


def test_slot_through_a_cylinder() -> None:
    """A 10 mm slot 2 mm deep right through a cylinder stock (r 20 mm): the volume is the
    strip |y| <= 5 of the disk times the depth, 2 (a sqrt(r^2 - a^2) + r^2 asin(a/r)) * 2 with
    a = 5, within half a cell round the two rim arcs inside the strip (the box would give
    10 x 40 x 2); the cells outside the circle keep the bottom and are never counted."""
    text = program("T1 M6", *slot_lines(0.0, -2.0))
    job = simulate_job(read_gcode(text), {1: FLAT10}, grid_for(-20, 70, -30, 30), CYLINDER)
    r, a, depth = CYLINDER.radius, 5.0, 2.0
    strip = 2 * (a * math.sqrt(r * r - a * a) + r * r * math.asin(a / r))
    arcs = 4 * r * math.asin(a / r)  # rim length inside the strip, both ends
    removed = job.tools[1].removed_volume_mm3
    print(f"slot through the cylinder: removed {removed:.2f} mm^3, expected "
          f"{strip * depth:.2f} mm^3")
    assert removed == pytest.approx(strip * depth, abs=arcs * CELL / 2 * depth)
    xs, ys = job.grid.centres()
    circle = np.hypot(xs[None, :] - CYLINDER.x, ys[:, None] - CYLINDER.y) <= r
    assert np.array_equal(job.in_stock, circle)
    assert np.all(job.height[~circle] == CYLINDER.z_min)
    slot = (np.abs(ys[:, None]) <= 5.0) & circle
    assert np.allclose(job.height[slot], -2.0, atol=1e-5)
    assert np.all(job.height[circle & ~slot] == CYLINDER.z_max)
    assert job.cylinder == CYLINDER and job.stock == CYLINDER.bounds
    assert job.collisions == ()


def test_rapid_past_a_cylinder_and_through_it() -> None:
    """A rapid 1 mm below the top that passes the corner of the cylinder's box (3.5 mm from
    the corner, 31.8 mm from the axis) cuts nothing from the cylinder but collides with the
    box; one across the axis collides, 1 mm deep, inside the circle."""
    past = program("T1 M6", "G0 X-10 Y10 Z5", "G0 Z-1", "G0 X10 Y30", "G0 Z5")
    grid = grid_for(-20, 70, -30, 40)
    job = simulate_job(read_gcode(past), {1: FLAT10}, grid, CYLINDER)
    assert job.collisions == () and job.removed_volume() == 0.0
    boxed = simulate_job(read_gcode(past), {1: FLAT10}, grid, CYLINDER.bounds)
    assert len(boxed.collisions) == 1
    through = program("T1 M6", "G0 X-10 Y0 Z5", "G0 Z-1", "G0 X60", "G0 Z5")
    job = simulate_job(read_gcode(through), {1: FLAT10}, grid, CYLINDER)
    (hit,) = job.collisions
    assert hit.line == 6 and hit.depth_mm == pytest.approx(1.0, abs=1e-5)
    assert math.hypot(hit.x - CYLINDER.x, hit.y - CYLINDER.y) <= CYLINDER.radius


def test_stock_forms() -> None:
    """Six numbers, a Stock block and a CylinderStock: the block forms give the same Z-map;
    a cylinder beyond the machine's reach is refused naming the stock and mm."""
    box = (0, 50, -20, 20, -10, 0)
    assert check_stock_form(box) == tuple(float(v) for v in box)
    assert check_stock_form(Stock(*box)) == tuple(float(v) for v in box)
    assert check_stock_form(CYLINDER) is CYLINDER
    text = read_gcode(program("T1 M6", *slot_lines(0.0, -2.0)))
    a = simulate_job(text, {1: FLAT10}, grid_for(-20, 70, -20, 20), box)
    b = simulate_job(text, {1: FLAT10}, grid_for(-20, 70, -20, 20), Stock(*box))
    assert np.array_equal(a.height, b.height) and b.cylinder is None
    with pytest.raises(ParameterError, match="stock") as info:
        check_stock_form(CylinderStock(2e6, 0.0, 5.0, 0.0, 1.0))
    assert "mm" in str(info.value)
    with pytest.raises(ParameterError, match="stock"):
        check_stock_form("cylinder")
