# SPDX-License-Identifier: LGPL-2.1-or-later
"""Partial raster passes on faces (core/toolpath/raster_partial.py), the scallop evenness
(core/simulation/evenness.py) and the machine figures (core/simulation/measures.py).

The end-to-end cases machine a plane-with-fillets step built in numpy (a flat top, a convex
fillet, a 60 degree ramp, a concave fillet, a flat floor; tangent joints) with and without
partial passes and simulate each program from its G-code text against the exact faces."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_helpers import assert_above_drop, cylinder_quarter, gcode, plane, rectangle

from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.evenness import running_max, scallop_evenness
from BSplineCAM.core.simulation.measures import program_measures, toolpath_lengths
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.simulation.verify import verify_faces
from BSplineCAM.core.toolpath.common import ToolParameters, curved_stepover, flat_stepover
from BSplineCAM.core.toolpath.faces_raster import _stepover_samples, generate_faces_raster
from BSplineCAM.core.toolpath.faceset import FaceSet
from BSplineCAM.core.toolpath.raster import scallop_line_offsets
from BSplineCAM.core.toolpath.raster_partial import (
    MARGIN,
    Piece,
    StepoverSamples,
    fill_band,
    order_pieces,
    partial_offsets,
    stretches,
)

D, H, TOL = 6.0, 0.05, 0.01
R = D / 2


# -- the part: a flat top, a convex fillet, a ramp, a concave fillet, a flat floor -------------
def arc_face(cx: float, cz: float, rho: float, a0: float, a1: float, length: float,
             index: int) -> Face:
    """The arc of the circle of centre (cx, cz) and radius rho in XZ from angle a0 to a1
    (rad, less than a half turn apart), extruded along y from 0 to ``length``: a rational
    quadratic (the middle pole at the tangents' meeting point, weight cos of half the arc)."""
    half, mid = 0.5 * (a1 - a0), 0.5 * (a0 + a1)
    far = rho / math.cos(half)
    arc = [(cx + rho * math.cos(a0), cz + rho * math.sin(a0)),
           (cx + far * math.cos(mid), cz + far * math.sin(mid)),
           (cx + rho * math.cos(a1), cz + rho * math.sin(a1))]
    poles = np.array([[[x, y, z] for y in (0.0, length)] for x, z in arc])
    w = math.cos(half)
    s = NurbsSurface(poles, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1,
                     weights=np.array([[1.0, 1.0], [w, w], [1.0, 1.0]]))
    return Face(s, rectangle(s), index=index)


def strip(x0: float, z0: float, x1: float, z1: float, length: float, index: int) -> Face:
    """The plane strip from (x0, z0) to (x1, z1) in XZ, y from 0 to ``length``."""
    poles = np.array([[[x0, 0, z0], [x0, length, z0]], [[x1, 0, z1], [x1, length, z1]]],
                     dtype=float)
    s = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    return Face(s, rectangle(s), index=index)


def step_faces(slope_deg: float = 60.0, rho: float = 4.0, run: float = 2.0, top: float = 10.0,
               flat: float = 40.0, length: float = 20.0) -> list[Face]:
    """Top (x from -flat to 0 at z = top), fillet of radius rho down to ``slope_deg``, ramp of
    horizontal ``run``, fillet back to level, floor of width ``flat``: five tangent faces."""
    t = math.radians(slope_deg)
    faces = [strip(-flat, top, 0.0, top, length, 1),
             arc_face(0.0, top - rho, rho, math.pi / 2, math.pi / 2 - t, length, 2)]
    pa = (rho * math.sin(t), top - rho * (1 - math.cos(t)))
    pb = (pa[0] + run, pa[1] - run * math.tan(t))
    faces.append(strip(*pa, *pb, length, 3))
    centre = (pb[0] + rho * math.sin(t), pb[1] + rho * math.cos(t))
    faces.append(arc_face(*centre, rho, 1.5 * math.pi - t, 1.5 * math.pi, length, 4))
    floor = centre[1] - rho
    faces.append(strip(centre[0], floor, centre[0] + flat, floor, length, 5))
    return faces


def machined(faces, partial: bool, angle: float = 0.0):
    """The raster of ``faces``, its program and the program's verification (cell 0.1 mm)."""
    fs = FaceSet(faces)
    tp = generate_faces_raster(fs, D, H, TOL, angle=angle, partial=partial)
    program = read_gcode(gcode(tp))
    return fs, tp, program, verify_faces(faces, program, Tool(D), cell=0.1).metrics


@pytest.fixture(scope="module")
def step_runs():
    faces = step_faces()
    return {partial: machined(faces, partial) for partial in (False, True)}


@pytest.mark.venv_only
def test_partial_passes_cut_less_and_leave_an_even_scallop(step_runs):
    """Over the ramp the passes need about 0.77 mm, over the flats 1.09 mm: whole passes all
    go 0.77 mm apart, the partial raster's main passes 1.09 mm apart with a partial pass
    between two of them over the ramp.  Shorter by a clear margin, every scallop within
    h + tolerance, no gouge, the selection covered, and a more even scallop."""
    _, whole, _, mw = step_runs[False]
    fs, part, program, mp = step_runs[True]
    assert len(part.extra["partial_passes_mm"]) > 10
    assert not whole.extra["partial_passes_mm"]
    steps = np.diff(part.extra["line_offsets_mm"])
    assert np.median(steps) == pytest.approx(flat_stepover(R, H), rel=1e-6)
    assert mp["cutting_length_mm"] < 0.92 * mw["cutting_length_mm"], (mp, mw)
    for m in (mw, mp):
        assert m["scallop_max_mm"] <= H + TOL, m["scallop_max_mm"]
        assert m["gouge_max_mm"] <= 1e-3
        assert m["coverage"] == 1.0
    assert mp["scallop_evenness"] > mw["scallop_evenness"] + 0.15, (mp, mw)
    assert mp["scallop_evenness"] > 0.7
    assert mp["scallop_mean_mm"] > 1.3 * mw["scallop_mean_mm"]
    assert_above_drop(fs, part)
    # the time on the machine follows, and the partial passes keep the tool down: at most
    # two retracts between passes
    assert (program_measures(program)["machining_time_with_acceleration_s"]
            < program_measures(read_gcode(gcode(whole)))["machining_time_with_acceleration_s"])
    assert sum(link is None for link in part.links) <= 2


@pytest.mark.venv_only
def test_partial_passes_lie_over_the_ramp_only(step_runs):
    """Every partial pass spans the ramp and its fillets (x from 0 to 9.4 mm) plus about a
    tool radius each side, and lies between two main passes."""
    _, tp, _, _ = step_runs[True]
    mains = np.asarray(tp.extra["line_offsets_mm"])
    for b, a0, a1 in tp.extra["partial_passes_mm"]:
        assert -MARGIN * R - 0.5 <= a0 <= 0.0 + 0.5, a0
        assert 9.4 - 0.5 <= a1 <= 9.4 + MARGIN * R + 0.5, a1
        k = np.searchsorted(mains, b)
        assert mains[k - 1] < b < mains[k]


# -- closed forms: a plane, a cylinder along its axis ------------------------------------------
def test_plane_passes_at_the_flat_stepover_without_partial_passes():
    top = plane(0.0, 20.0, 0.0, 15.0, 2.0)
    fs = FaceSet([Face(top, rectangle(top), index=1)])
    tp = generate_faces_raster(fs, D, H, TOL)
    steps = np.diff(tp.extra["line_offsets_mm"])
    np.testing.assert_allclose(steps[:-1], flat_stepover(R, H), rtol=1e-9)
    assert steps[-1] <= flat_stepover(R, H) + 1e-9
    assert tp.extra["partial_passes_mm"] == []
    assert tp.parameters["partial"] is True
    assert all(link is not None for link in tp.links)


def cylinder_allowance(x_centre: np.ndarray, rho: float) -> np.ndarray:
    """XY spacing of passes along the axis of a convex cylinder of radius rho whose ball
    centres lie at x_centre (mm): the contact arc for the normal cusp h cos(slope) (the
    vertical cusp h), carried to the offset circle of radius rho + R, projected on XY."""
    phi = np.arcsin(np.clip(np.abs(x_centre) / (rho + R), 0.0, 1.0))
    arc = curved_stepover(R, H * np.cos(phi), np.full(len(phi), -1.0 / rho))
    return arc * (rho + R) / rho * np.cos(phi)


def test_cylinder_along_its_axis_spacing_is_the_closed_form():
    """Passes along the axis of a cylinder (steep across them everywhere but its crest): the
    allowance is the same along every pass, so no partial pass pays; the lines are those of
    the whole-pass rule, each step the closed-form spacing at the steepest point of its band."""
    rho, length = 10.0, 20.0
    surface = cylinder_quarter(rho, length)
    fs = FaceSet([Face(surface, rectangle(surface), index=1)])
    tool = ToolParameters.validate(D, H, TOL)
    along, across = np.array([0.0, 1.0]), np.array([-1.0, 0.0])
    b, a, allowed, _ = _stepover_samples(fs, tool, along, across)
    np.testing.assert_allclose(allowed, cylinder_allowance(-b, rho), rtol=1e-6)
    widen = 0.5 * tool.flat_stepover
    b0, b1 = float(b.min()), float(b.max())
    lines, pieces = partial_offsets(StepoverSamples(b, a, allowed), b0, b1, (0.0, length),
                                    tool, widen)
    assert pieces == []
    order = np.argsort(b)
    assert lines == scallop_line_offsets(b[order], allowed[order], b0, b1, tool, widen)
    lines = np.asarray(lines)
    steps = np.diff(lines)[:-1]

    def closed_form_step(start: float) -> float:
        """The rule's step from ``start`` on the closed-form allowance: the allowance where
        the band, widened, is steepest, shrunk from the widest until it holds."""
        step = min(float(allowed.max()), R)
        for _ in range(8):
            far = min(max(abs(start - widen), abs(start + step + widen)), float(np.abs(b).max()))
            need = float(cylinder_allowance(np.array([far]), rho)[0])
            if need >= 0.999 * step:
                break
            step = need
        return step

    expected = [closed_form_step(start) for start in lines[:-2]]
    np.testing.assert_allclose(steps, expected, rtol=0.03)  # to the samples' spacing
    top = np.argmin(np.abs(lines))
    crest_step = curved_stepover(R, H, np.array([-1.0 / rho]))[0] * (rho + R) / rho
    assert steps[top] == pytest.approx(crest_step, rel=0.03)


@pytest.mark.venv_only
def test_cylinder_raster_with_and_without_partial_passes_is_the_same():
    rho, length = 10.0, 12.0
    surface = cylinder_quarter(rho, length)
    runs = [generate_faces_raster(FaceSet([Face(surface, rectangle(surface), index=1)]), D, H,
                                  TOL, angle=90.0, partial=p) for p in (False, True)]
    assert runs[0].extra["line_offsets_mm"] == runs[1].extra["line_offsets_mm"]
    assert runs[1].extra["partial_passes_mm"] == []
    assert len(runs[0].passes) == len(runs[1].passes)
    for p, q in zip(runs[0].passes, runs[1].passes):
        np.testing.assert_array_equal(p, q)


# -- the pieces: stretches, nesting, every allowance met ----------------------------------------
def test_stretches_grow_merge_and_clip():
    got = stretches(np.array([5.0, 1.0, 1.5, 12.0]), 0.0, 13.0, 1.0, 2.0)
    assert got == [(0.0, 6.0), (11.0, 13.0)]  # 1..5 merged (gap 3.5 < 2 + 2), clipped at 0, 13
    assert stretches(np.array([]), 0.0, 1.0, 1.0, 2.0) == []
    assert stretches(np.array([1.0, 6.0]), 0.0, 10.0, 1.0, 2.0) == [(0.0, 2.0), (5.0, 7.0)]


def lines_at(pieces: list[Piece], a: float) -> np.ndarray:
    return np.unique([p.b for p in pieces if p.a0 <= a <= p.a1])


def test_filled_band_meets_every_allowance_and_nests():
    """Samples along a band of 1 mm: most allow 1 mm, a stretch 0.3 mm, a shorter one 0.1 mm.
    The pieces halve the gap three and four times there, each deeper piece within the one
    above it, and at every sample's along-coordinate the lines round its offset are no further
    apart than it allows."""
    rng = np.random.default_rng(4)
    a = rng.uniform(0.0, 60.0, 4000)
    b = rng.uniform(0.0, 1.0, 4000)
    allowed = np.where((a > 20) & (a < 30), 0.3, 1.0)
    allowed = np.where((a > 24) & (a < 26), 0.1, allowed)
    samples = StepoverSamples(b, a, allowed)
    pieces = fill_band(samples, 0.0, 1.0, (0.0, 60.0), 0, 0.0, R)
    mains = [Piece(0.0, 0.0, 60.0, 0, 0), Piece(1.0, 0.0, 60.0, 1, 0)]
    assert max(p.depth for p in pieces) == 4
    for p in pieces:
        if p.depth > 1:  # within a piece of the level above that bounds it
            assert any(q.depth == p.depth - 1 and q.a0 <= p.a0 and p.a1 <= q.a1
                       and abs(q.b - p.b) < 1.0 / 2 ** (p.depth - 1) for q in pieces)
        assert p.a0 >= 20 - MARGIN * R - 1e-9 and p.a1 <= 30 + MARGIN * R + 1e-9
    for ai, bi, wi in zip(a[::7], b[::7], allowed[::7]):
        ys = lines_at(mains + pieces, ai)
        k = np.searchsorted(ys, bi)
        assert ys[min(k, len(ys) - 1)] - ys[max(k - 1, 0)] <= wi + 1e-12
    # a band whose samples all allow its width needs nothing
    assert fill_band(StepoverSamples(b, a, np.full(len(a), 1.0)), 0.0, 1.0, (0.0, 60.0), 0,
                     0.0, R) == []


def test_main_step_widens_only_when_it_pays():
    """A band crossing a short steep stretch takes the flat step with partial passes; one
    steep along its whole length keeps the whole-pass step (a partial pass as long as the
    pass saves nothing)."""
    tool = ToolParameters.validate(D, H, TOL)
    flat = tool.flat_stepover
    rng = np.random.default_rng(9)
    a = rng.uniform(0.0, 100.0, 20000)
    b = rng.uniform(0.0, 20.0, 20000)
    short = StepoverSamples(b, a, np.where((a > 40) & (a < 45), 0.6 * flat, flat))
    lines, pieces = partial_offsets(short, 0.0, 20.0, (0.0, 100.0), tool, 0.0)
    np.testing.assert_allclose(np.diff(lines)[:-1], flat, rtol=1e-9)
    assert pieces and all(p.depth == 1 and p.a1 - p.a0 < 5 + 2 * MARGIN * R + 1e-9
                          for p in pieces)
    whole = StepoverSamples(b, a, np.full(len(a), 0.6 * flat))
    lines, pieces = partial_offsets(whole, 0.0, 20.0, (0.0, 100.0), tool, 0.0)
    np.testing.assert_allclose(np.diff(lines)[:-1], 0.6 * flat, rtol=1e-9)
    assert pieces == []


def test_order_keeps_the_tool_near_every_next_piece():
    """Main passes 1 mm apart over x from 0 to 50, three partial pieces per band over x from
    20 to 30 (depths 1, 2, 2): every run is cut once, the main passes zig-zag, and from the
    second band on every move between runs is shorter than two tool radii."""
    pieces, runs = [], []
    for k in range(6):
        pieces.append(Piece(float(k), 0.0, 50.0, k, 0))
    for k in range(5):
        for b, depth in ((k + 0.5, 1), (k + 0.25, 2), (k + 0.75, 2)):
            pieces.append(Piece(b, 20.0, 30.0, k, depth))
    for i, p in enumerate(pieces):
        x = np.linspace(p.a0, p.a1, 5)
        runs.append((i, np.column_stack([x, np.full(5, p.b), np.zeros(5)])))
    ordered = order_pieces(runs, pieces, np.array([1.0, 0.0]))
    cut = sum(float(np.abs(np.diff(r[:, 0])).sum()) for r in ordered)
    assert cut == pytest.approx(6 * 50 + 15 * 10)
    jumps = [float(np.hypot(*(q[0, :2] - p[-1, :2]))) for p, q in zip(ordered, ordered[1:])]
    first_main_done = next(i for i, r in enumerate(ordered) if r[0, 1] == 1.0)
    assert max(jumps[first_main_done:]) < 2 * R, jumps
    mains = [r for r in ordered if np.ptp(r[:, 0]) > 0 and r[0, 1] == int(r[0, 1])]
    assert mains[0][0, 0] < mains[0][-1, 0]  # forward, then back
    assert ordered[-1][0, 0] > ordered[-1][-1, 0]


# -- evenness and the machine figures ----------------------------------------------------------
def test_running_max_matches_brute_force():
    x = np.random.default_rng(2).normal(size=(17, 11))
    for half in (0, 1, 3, 9):
        got = running_max(x, half, 0)
        ref = np.array([[x[max(0, i - half):i + half + 1, j].max() for j in range(11)]
                        for i in range(17)])
        np.testing.assert_array_equal(got, ref)
        np.testing.assert_array_equal(running_max(x.T, half, 1), ref.T)


def cusps(y: np.ndarray, spacing: np.ndarray) -> np.ndarray:
    """Scallop (parabolic) of a ball of radius R at passes ``spacing`` apart (per cell), at
    offsets y: d^2 / 2R, d the distance to the nearer pass."""
    phase = np.mod(y, spacing)
    d = np.minimum(phase, spacing - phase)
    return d ** 2 / (2 * R)


def test_even_pattern_scores_near_one_and_a_fine_one_low():
    """Cusps of h at the flat stepover everywhere: evenness near 1, mean over max near 1/3.
    The same cusps over a fifth of the width and passes half as far apart elsewhere (a
    quarter of the scallop): evenness near 0.2 + 0.8 / 4."""
    cell, h = 0.05, H
    ys, xs = np.mgrid[0:600, 0:200] * cell
    s = flat_stepover(R, h)
    even = cusps(ys + 0.3 * xs, np.full(ys.shape, s))
    inner = np.ones(ys.shape, bool)
    got = scallop_evenness(even, inner, cell, Tool(D))
    assert got["scallop_evenness"] > 0.93
    assert got["scallop_mean_over_max"] == pytest.approx(1 / 3, abs=0.03)
    assert got["scallop_evenness_window_mm"] == pytest.approx(s, rel=0.02)
    mixed = cusps(ys, np.where(ys < 6.0, s, 0.5 * s))
    got = scallop_evenness(mixed, inner, cell, Tool(D))
    assert got["scallop_evenness"] == pytest.approx(0.2 + 0.8 / 4, abs=0.06)
    assert scallop_evenness(np.zeros(ys.shape), inner, cell, Tool(D))["scallop_evenness"] == 1


def test_program_measures_split_cutting_air_and_time():
    text = ("G21 G90\nG0 X0 Y0 Z5\nG0 Z1\nG1 Z0 F100\nG1 X10 F600\nG1 Y1\nG1 X0\n"
            "G0 Z5\nM2\n")
    program = read_gcode(text)
    m = program_measures(program, along_passes_mm=20.0)
    assert m["cutting_length_mm"] == pytest.approx(1 + 10 + 1 + 10)
    assert m["rapid_length_mm"] == pytest.approx(4 + 5)
    assert m["air_length_mm"] == pytest.approx(9 + 1 + 1)  # rapids, the plunge, the link
    assert m["machining_time_s"] == pytest.approx(60 * (1 / 100 + 21 / 600 + 9 / 5000))
    assert m["machining_time_with_acceleration_s"] > m["machining_time_s"]
    assert "air_length_mm" not in program_measures(program)


def test_toolpath_lengths_split_passes_and_links():
    top = plane(0.0, 8.0, 0.0, 6.0, 2.0)
    tp = generate_faces_raster(FaceSet([Face(top, rectangle(top), index=1)]), D, H, TOL)
    lengths = toolpath_lengths(tp)
    assert lengths["along_passes_mm"] + lengths["link_length_mm"] == pytest.approx(
        tp.stats.cutting_length_mm)
    assert lengths["link_length_mm"] == pytest.approx(
        sum(np.hypot(*(q[0, :2] - p[-1, :2])) for p, q in zip(tp.passes, tp.passes[1:])))
