# SPDX-License-Identifier: LGPL-2.1-or-later
"""The Z-map's compiled stamping (BSplineCAM/core/kernels/zmap_kernels.py) against the numpy
engine's envelopes: bit-identical height maps and identical rapid collisions for ball, flat
and bull-nose tools on long and short, steep and vertical moves, arcs, threads, random
programs and the case study, and identical ``verify`` metrics (the numba half skips where
numba is missing)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CASE_STUDY
from hypothesis import given, settings
from hypothesis import strategies as st

from BSplineCAM.core import Surface, kernels, threads
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.program.gcode_words import Segments
from BSplineCAM.core.simulation import simulate as sim
from BSplineCAM.core.simulation.verify import verify

TOOLS = [sim.Tool(6.0), sim.Tool(6.0, "flat"), sim.Tool(6.0, "bullnose", 1.0),
         sim.Tool(4.0, "bullnose", 2.0), sim.Tool(10.0, "flat")]
IDS = ["ball6", "flat6", "bull6r1", "bull4r2", "flat10"]


@pytest.fixture(autouse=True)
def _numba():
    pytest.importorskip("numba")


def _segments(points, rapid=None) -> Segments:
    p = np.asarray(points, dtype=float)
    n = len(p) - 1
    rapid = np.zeros(n, bool) if rapid is None else np.asarray(rapid, bool)
    return Segments(p[:-1].copy(), p[1:].copy(), rapid, np.arange(1, n + 1), np.arange(n))


def _both(run):
    """``run()`` under the numpy engine, then under numba."""
    out = []
    for choice in ("numpy", "numba"):
        with kernels.forced(choice) as e:
            assert e.name == choice
            out.append(run())
    return out


def _same(a: sim.Simulation, b: sim.Simulation) -> None:
    assert a.height.dtype == b.height.dtype
    # bit for bit (the maps hold float32 values)
    assert np.array_equal(a.height.astype(np.float32).view(np.uint32),
                          b.height.astype(np.float32).view(np.uint32))
    assert a.collisions == b.collisions


def _agree(segments: Segments, tool: sim.Tool, grid: sim.Grid, top: float) -> sim.Simulation:
    a, b = _both(lambda: sim.simulate(segments, tool, grid, top))
    _same(a, b)
    return a


@pytest.mark.parametrize("tool", TOOLS, ids=IDS)
def test_long_short_steep_and_vertical_moves(tool):
    grid = sim.Grid.covering(-10.0, 110.0, -10.0, 40.0, 0.2)
    points = [[0, 0, 8], [100, 3, 6],          # long, shallow (the float64-then-round path)
              [100.4, 3.1, 5.9], [100.5, 3.1, 5.9],  # short
              [101, 8, 1],                      # steep
              [101, 8, -2],                     # vertical plunge
              [101, 8, 4],                      # vertical climb
              [60, 20, 4], [60.0001, 20, 4],    # level, a tenth of a micron
              [30, 25, -1], [0, 25, 7.5]]       # down and up ramps
    out = _agree(_segments(points), tool, grid, 10.0)
    assert np.min(out.height) < 10.0


@pytest.mark.parametrize("tool", TOOLS, ids=IDS)
def test_rapid_collisions(tool):
    grid = sim.Grid.covering(-10.0, 50.0, -10.0, 50.0, 0.25)
    points = [[0, 0, 20], [0, 0, 4], [40, 0, 4], [40, 40, 3], [20, 20, 3.5], [0, 40, 20],
              [10, 10, 5], [30, 30, 2], [35, 5, 30]]
    rapid = [True, False, False, False, True, True, True, False]
    out = _agree(_segments(points, rapid), tool, grid, 8.0)
    assert out.collisions  # the rapids through the stock are seen


@pytest.mark.parametrize("tool", TOOLS[:3], ids=IDS[:3])
def test_arcs_linearised(tool):
    text = "\n".join([
        "G21 G90 G17", "G0 X0 Y0 Z20", "G1 Z5 F500",
        "G2 X20 Y0 I10 J0 Z3", "G3 X20 Y20 I0 J10", "G2 X0 Y20 R10 Z4.5",
        "G1 X-5 Y10", "G3 X5 Y10 I5 J0 Z2", "G0 Z20", "M2"]) + "\n"
    program = read_gcode(text)
    grid = sim.Grid.covering(-12.0, 32.0, -12.0, 32.0, 0.1)
    a, b = _both(lambda: sim.simulate_program(program, tool, grid, 6.0))
    _same(a, b)


@pytest.mark.parametrize("tool", TOOLS[:3], ids=IDS[:3])
def test_threads_split_rows(monkeypatch, tool):
    """A raster split over threads (interleaved row blocks) gives the one-thread map."""
    x = np.linspace(0.0, 40.0, 81)
    points = []
    for i, y in enumerate(np.linspace(0.0, 30.0, 31)):
        xs = x if i % 2 == 0 else x[::-1]
        points += [[a, y, 3.0 + math.sin(a / 5.0) * math.cos(y / 7.0)] for a in xs]
    segments = _segments(points)
    grid = sim.Grid.covering(-5.0, 45.0, -5.0, 35.0, 0.1)
    with threads.forced(1):
        one = _agree(segments, tool, grid, 5.0)
    monkeypatch.setattr(sim, "THREADED_CELLS", 1)
    with threads.forced(3), kernels.forced("numba"):
        _same(one, sim.simulate(segments, tool, grid, 5.0))


_coordinate = st.floats(-5.0, 25.0, allow_nan=False)
_height = st.floats(-2.0, 12.0, allow_nan=False)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(_coordinate, _coordinate, _height, st.booleans()),
                min_size=2, max_size=14),
       st.sampled_from(range(len(TOOLS))), st.sampled_from([0.1, 0.25, 0.5]))
def test_random_programs(moves, which, cell):
    points = [m[:3] for m in moves]
    rapid = [m[3] for m in moves[1:]]
    grid = sim.Grid.covering(-8.0, 28.0, -8.0, 28.0, cell)
    _agree(_segments(points, rapid), TOOLS[which], grid, 8.0)


def _case_study_program(surface: Surface, radius: float) -> str:
    """Zig-zag ball-end rows over the case study (tip = S + R n - R z), 2 mm apart."""
    us = np.linspace(0, 1, 26)
    ws = np.linspace(0, 1, 61)
    n = surface.normals(us, ws, grid=True)
    n = np.where(n[..., 2:3] < 0, -n, n)
    tip = surface.evaluate_grid(us, ws) + radius * n
    tip[..., 2] -= radius
    lines = ["G21 G90 G17", "G0 X0 Y0 Z50", f"G0 X{tip[0, 0, 0]:.4f} Y{tip[0, 0, 1]:.4f}",
             f"G1 Z{tip[0, 0, 2]:.4f} F500"]
    for i in range(len(us)):
        for p in tip[i] if i % 2 == 0 else tip[i, ::-1]:
            lines.append(f"G1 X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f} F1500")
    return "\n".join([*lines, "G0 Z50", "M2"]) + "\n"


def test_case_study_verify_metrics():
    surface = Surface.from_json(CASE_STUDY)
    program = read_gcode(_case_study_program(surface, 3.0))
    a, b = _both(lambda: verify(surface, program, sim.Tool(6.0), cell=0.25))
    _same(a.simulation, b.simulation)
    assert a.metrics == b.metrics
    assert a.metrics["gouge_max_mm"] < 0.01


@pytest.mark.parametrize("tool", TOOLS[1:3], ids=IDS[1:3])
def test_case_study_other_tools(tool):
    surface = Surface.from_json(CASE_STUDY)
    program = read_gcode(_case_study_program(surface, 3.0))
    grid = sim.Grid.covering(-5.0, 105.0, -5.0, 105.0, 0.25)
    a, b = _both(lambda: sim.simulate_program(program, tool, grid, 40.0))
    _same(a, b)


def test_compiled_time_is_reported():
    grid = sim.Grid.covering(0.0, 10.0, 0.0, 10.0, 0.5)
    with kernels.forced("numba") as e:
        sim.simulate(_segments([[0, 0, 1], [10, 10, 0]]), sim.Tool(3.0), grid, 2.0)
        assert "stamp_loops" in e.compile_seconds
