# SPDX-License-Identifier: LGPL-2.1-or-later
"""Machining time with acceleration (core/machining_time.py) against closed forms of the
trapezoidal profile, grbl's junction-deviation corner (derived here from the circle it stands
for), LinuxCNC's arc speed limit, and a plain move-by-move look-ahead planner written out as
grbl's planner_recalculate loops; and the CLI options that set the machine's limits."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import CASE_STUDY, ROOT
from hypothesis import given, settings
from hypothesis import strategies as st

from BSplineCAM.core.errors import BSplineCAMError, ParameterError
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.machining_time import (
    ARC_NORMAL_RATIO,
    ARC_TANGENTIAL_RATIO,
    MachineLimits,
    machining_time,
    parse_axis_values,
)

A = 500.0  # mm/s^2


def program(*moves: str, start: str = "X0 Y0 Z0") -> str:
    return "\n".join(["G21 G90 G17", f"G0 {start}", *moves, "M2", ""])


def planned(text: str, **limits) -> object:
    return machining_time(read_gcode(text), MachineLimits.checked(**limits))


def lost(v: float, v0: float, a: float) -> float:
    """Time lost against L / v by running from v0 up to v (or down to v0) at a: the area
    between the cruise line and the ramp, (v - v0)^2 / (2 a v)."""
    return (v - v0) ** 2 / (2.0 * a * v)


# --- one move ---------------------------------------------------------------------------------
@pytest.mark.parametrize("length, feed", [(100.0, 600.0), (250.0, 3000.0), (40.0, 1200.0)])
def test_long_move_takes_length_over_feed_plus_feed_over_acceleration(length, feed):
    """Rest to rest, long enough to cruise: t = L / v + v / a."""
    v = feed / 60.0
    t = planned(program(f"G1 X{length} F{feed}"), acceleration=A)
    assert t.total == pytest.approx(length / v + v / A, rel=1e-12)
    assert t.nominal == pytest.approx(length / v, rel=1e-12)


@pytest.mark.parametrize("length", [0.1, 0.5, 2.0])
def test_move_too_short_to_reach_the_feed(length):
    """The profile is a triangle peaking at sqrt(a L): t = 2 sqrt(L / a)."""
    t = planned(program(f"G1 X{length} F6000"), acceleration=A)
    assert math.sqrt(A * length) < 100.0
    assert t.total == pytest.approx(2.0 * math.sqrt(length / A), rel=1e-12)


def test_diagonal_move_uses_the_axes_limits():
    """Along (3, 4, 0) / 5 with X at 500 and Y at 200 mm/s^2 the path acceleration is
    min(500 / 0.6, 200 / 0.8) = 250 mm/s^2; the speed is capped likewise by the rapid rate
    per axis."""
    t = planned(program("G1 X30 Y40 F1200"), acceleration=(500.0, 200.0, 100.0))
    v = 20.0
    assert t.total == pytest.approx(50.0 / v + v / 250.0, rel=1e-12)
    rapid = planned(program("G0 X300 Y400"), acceleration=(500.0, 200.0, 100.0),
                    rapid_rate=3000.0)
    v = 50.0  # 3000 mm/min along the path; X moves at 30 mm/s, Y at 40: both within 50
    assert rapid.total == pytest.approx(500.0 / v + v / 250.0, rel=1e-12)
    assert rapid.rapids == rapid.total and rapid.feed == 0.0


# --- corners ----------------------------------------------------------------------------------
def junction_speed(turn_deg: float, a_junction: float, deviation: float) -> float:
    """The corner speed of the junction-deviation model from its geometry: a circle tangent to
    both moves, its distance to the corner ``deviation``, run at centripetal ``a_junction``.
    The moves meet at an inner angle alpha = 180 - turn; the circle's centre lies on the
    bisector at r / sin(alpha / 2) from the corner, so r / sin(alpha/2) - r = deviation."""
    half = math.radians(180.0 - turn_deg) / 2.0
    radius = deviation * math.sin(half) / (1.0 - math.sin(half))
    return math.sqrt(a_junction * radius)


def test_right_angle_corner_against_straight_continuation():
    length, feed, deviation = 50.0, 1800.0, 0.05
    v = feed / 60.0
    straight = planned(program(f"G1 X{length} F{feed}", f"G1 X{2 * length}"),
                       acceleration=A, junction_deviation=deviation)
    assert straight.total == pytest.approx(2 * length / v + v / A, rel=1e-12)
    assert straight.exit_speed[0] == pytest.approx(v, rel=1e-12)
    corner = planned(program(f"G1 X{length} F{feed}", f"G1 Y{length}"),
                     acceleration=A, junction_deviation=deviation)
    # the bend t2 - t1 = (-1, 1, 0) / sqrt 2 lets the axes give a sqrt(2) together
    vj = junction_speed(90.0, A * math.sqrt(2.0), deviation)
    assert 0 < vj < v
    assert corner.exit_speed[0] == pytest.approx(vj, rel=1e-12)
    expected = 2 * (length / v + lost(v, 0.0, A) + lost(v, vj, A))
    assert corner.total == pytest.approx(expected, rel=1e-12)
    assert corner.total > straight.total


@pytest.mark.parametrize("turn", [30.0, 60.0, 120.0, 150.0])
def test_corner_speed_follows_the_turn_angle(turn):
    """Sharper turns are slower; the junction speed matches the circle's geometry in 2D with
    equal axis accelerations (bend direction at 45 degrees off the axes or not)."""
    a = math.radians(turn)
    end = (100.0 + 100.0 * math.cos(a), 100.0 * math.sin(a))
    t = planned(program("G1 X100 F6000", f"G1 X{end[0]:.12f} Y{end[1]:.12f}"),
                acceleration=A, junction_deviation=0.02)
    bend = np.array([math.cos(a) - 1.0, math.sin(a), 0.0])
    bend /= np.linalg.norm(bend)
    a_j = min(A / abs(c) for c in bend if abs(c) > 1e-15)
    assert t.exit_speed[0] == pytest.approx(junction_speed(turn, a_j, 0.02), rel=1e-9)


def test_reversal_stops_and_zero_deviation_stops_at_corners():
    rev = planned(program("G1 X10 F600", "G1 X0"), acceleration=A)
    assert rev.exit_speed[0] == 0.0
    assert rev.total == pytest.approx(2 * (10.0 / 10.0 + 10.0 / A), rel=1e-12)
    sharp = planned(program("G1 X10 F600", "G1 X10 Y10"), acceleration=A,
                    junction_deviation=0.0)
    assert sharp.exit_speed[0] == 0.0


def test_gap_in_the_program_is_a_stop():
    """After G28 the position is unknown: the move before stops, the next starts from rest."""
    text = "\n".join(["G21 G90", "G0 X0 Y0 Z0", "G1 X10 F600", "G28", "G0 X0 Y0 Z5",
                      "G1 X10 F600", "M2", ""])
    t = machining_time(read_gcode(text))
    feeds = ~t.rapid
    assert np.all(t.entry_speed[feeds] == 0.0) and np.all(t.exit_speed[feeds] == 0.0)


# --- arcs -------------------------------------------------------------------------------------
def test_full_circle_at_feed_uses_the_tangential_share():
    """A full G2 circle of radius 20 at 600 mm/min (well under its speed cap), rest to rest,
    accelerates at half the axes' acceleration (LinuxCNC's tangential ratio)."""
    radius, v = 20.0, 10.0
    assert v < math.sqrt(A * ARC_NORMAL_RATIO * radius)
    t = planned(program("G2 X0 Y0 I20 J0 F600"), acceleration=A)
    at = ARC_TANGENTIAL_RATIO * A
    assert t.total == pytest.approx(2 * math.pi * radius / v + v / at, rel=1e-12)


def test_small_arc_is_capped_by_centripetal_acceleration():
    radius = 2.0
    cap = math.sqrt(A * math.sqrt(3.0) / 2.0 * radius)  # v^2 / r = a sqrt(3) / 2
    assert cap < 100.0
    t = planned(program("G3 X0 Y0 I2 J0 F6000"), acceleration=A)
    at = 0.5 * A
    length = 2 * math.pi * radius
    assert t.nominal_speed[-1] == pytest.approx(cap, rel=1e-12)
    assert t.total == pytest.approx(length / cap + cap / at, rel=1e-12)


@pytest.mark.parametrize("plane, arc, line", [
    ("G17", "G2 X10 Y0 I5 J0", "G1 X10 Y-20"),  # CW half circle over the top, down -Y
    ("G18", "G2 X10 Z0 I5 K0", "G1 X10 Z20"),   # G18 arcs turn in (Z, X): CW ends going +Z
    ("G19", "G3 Y10 Z0 J5 K0", "G1 Y10 Z20"),    # G19 arcs turn in (Y, Z): CCW ends +Z
])
def test_arc_tangent_to_the_next_line_does_not_slow_down(plane, arc, line):
    """An arc and a line leaving along the arc's end tangent meet at full speed, in each
    plane; the same line turned back is a reversal (stop)."""
    text = "\n".join(["G21 G90", plane, "G0 X0 Y0 Z0", f"{arc} F600", f"{line}", "M2", ""])
    t = machining_time(read_gcode(text), MachineLimits.checked(acceleration=A))
    assert t.exit_speed[0] == pytest.approx(10.0, rel=1e-9)
    back = line.replace("-20", "20") if "-20" in line else line.replace("20", "-20")
    text = text.replace(line, back)
    t = machining_time(read_gcode(text), MachineLimits.checked(acceleration=A))
    assert t.exit_speed[0] == 0.0


def test_helix_takes_its_axial_travel_into_account():
    """One turn of radius 10 descending 5 mm: length hypot(2 pi r, 5); Z at 100 mm/s^2 limits
    the arc's acceleration."""
    t = planned(program("G2 X0 Y0 Z-5 I10 J0 F600"), acceleration=(500.0, 500.0, 100.0))
    length = math.hypot(2 * math.pi * 10.0, 5.0)
    at = 0.5 * 100.0
    assert t.total == pytest.approx(length / 10.0 + 10.0 / at, rel=1e-12)


# --- look-ahead -------------------------------------------------------------------------------
def reference_plan(moves, a, v, junction):
    """grbl's planner_recalculate as plain loops: entry speeds^2 limited by the junctions,
    a backward pass from the final stop, a forward pass from the start; then each move's
    trapezoid time by the (v - v0)^2 / (2 a v) losses or the triangle's peak."""
    n = len(moves)
    entry = [0.0] + list(junction) + [0.0]
    for i in range(n - 1, -1, -1):
        entry[i] = min(entry[i], entry[i + 1] + 2 * a[i] * moves[i])
    for i in range(n):
        entry[i + 1] = min(entry[i + 1], entry[i] + 2 * a[i] * moves[i])
    total = 0.0
    for i in range(n):
        v0, v1, L = math.sqrt(entry[i]), math.sqrt(entry[i + 1]), moves[i]
        if (v[i] ** 2 - v0**2 + v[i] ** 2 - v1**2) / (2 * a[i]) <= L:
            total += L / v[i] + lost(v[i], v0, a[i]) + lost(v[i], v1, a[i])
        else:
            peak = math.sqrt(a[i] * L + (v0**2 + v1**2) / 2)
            total += (2 * peak - v0 - v1) / a[i]
    return total


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.05, 40.0), st.sampled_from([1, -1]),
                          st.sampled_from([300.0, 1200.0, 4000.0])), min_size=1, max_size=25))
def test_collinear_moves_against_a_loop_planner(moves):
    """Moves along X (forward or back) at changing feeds: the running-minimum planner equals
    grbl's loops, and no plan is faster than the nominal time."""
    x, lines = 0.0, []
    lengths, speeds, junction = [], [], []
    for i, (length, sign, feed) in enumerate(moves):
        x += sign * length
        lines.append(f"G1 X{x:.6f} F{feed:g}")
        # keep the written coordinate's length: the program reads 6 decimals
        lengths.append(abs(round(x, 6) - (round(x - sign * length, 6) if i else 0.0)))
        speeds.append(feed / 60.0)
        if i:
            reverse = sign != moves[i - 1][1]
            junction.append(0.0 if reverse else min(speeds[-1], speeds[-2]) ** 2)
    t = planned(program(*lines), acceleration=A)
    keep = [i for i, L in enumerate(lengths) if L > 1e-9]
    assert len(keep) == len(lengths)
    expected = reference_plan(lengths, [A] * len(lengths), speeds, junction)
    assert t.total == pytest.approx(expected, rel=1e-9)
    assert t.total >= t.nominal * (1 - 1e-12)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-5, 5)),
                min_size=2, max_size=30),
       st.floats(1.0, 5000.0), st.floats(0.0, 0.5))
def test_polyline_is_feasible_and_slower_than_nominal(points, accel, deviation):
    """Random 3D polylines with rapids between: every planned move's speed change is
    reachable at its acceleration, every entry is within the junction limit, and the time
    is at least the nominal time and tends to it as the acceleration grows."""
    lines = [f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f} F{900 + 100 * (i % 7)}"
             if i % 5 else f"G0 X{x:.4f} Y{y:.4f} Z{z:.4f}"
             for i, (x, y, z) in enumerate(points)]
    text = program(*lines)
    prog = read_gcode(text)
    t = machining_time(prog, MachineLimits.checked(accel, junction_deviation=deviation))
    assert t.total >= t.nominal * (1 - 1e-12)
    length = prog.lengths()
    # equal axis limits: along a unit direction d the path may accelerate at a / max |d_i|
    chord = np.abs(prog.end - prog.start).max(axis=1) / np.where(length > 0, length, 1.0)
    path_accel = accel / np.where(chord > 0, chord, 1.0)
    slack = 2 * path_accel * length * (1 + 1e-9) + 1e-9
    assert np.all(np.abs(t.exit_speed**2 - t.entry_speed**2) <= slack)
    assert np.all(t.entry_speed <= t.nominal_speed * (1 + 1e-12))
    assert np.all(t.exit_speed[:-1][length[:-1] > 0] <= t.nominal_speed[1:][length[:-1] > 0]
                  * (1 + 1e-9) + 1e-12)
    fast = machining_time(prog, MachineLimits.checked(1e5, junction_deviation=10.0))
    assert fast.total <= t.total * (1 + 1e-12)


def test_acceleration_time_of_a_finishing_program_exceeds_nominal():
    """A raster of short moves (0.5 mm steps on a wave): much slower than nominal at
    50 mm/s^2, close to nominal at 50 000 mm/s^2."""
    xs = np.arange(0.0, 60.0, 0.5)
    lines = []
    for row in range(6):
        y = 2.0 * row
        seq = xs if row % 2 == 0 else xs[::-1]
        lines += [f"G1 X{x:.3f} Y{y:.3f} Z{np.sin(x / 3.0) * 2:.4f} F3000" for x in seq]
    prog = read_gcode(program(*lines, start="X0 Y0 Z0"))
    slow = machining_time(prog, MachineLimits.checked(50.0))
    fast = machining_time(prog, MachineLimits.checked(50_000.0, junction_deviation=1.0))
    assert slow.total > 1.2 * slow.nominal
    assert fast.nominal <= fast.total < 1.05 * fast.nominal
    assert slow.metrics()["acceleration_time_ratio"] == pytest.approx(slow.total / slow.nominal)


# --- limits -----------------------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, message", [
    ({"acceleration": 0.0}, r"acceleration must lie in \[1, 100000\] mm/s\^2, got 0"),
    ({"acceleration": float("nan")}, "acceleration"),
    ({"acceleration": (500.0, 500.0)}, r"one value or three \(X, Y, Z\) in mm/s\^2"),
    ({"acceleration": (500.0, -1.0, 500.0)}, r"acceleration \(Y\) must lie"),
    ({"rapid_rate": 0.0}, "rapid rate must lie in .* mm/min"),
    ({"junction_deviation": -0.1}, r"junction deviation must lie in \[0, 10\] mm"),
])
def test_limits_are_validated(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        MachineLimits.checked(**kwargs)


def test_axis_values_parse():
    assert parse_axis_values("500", "--accel", "mm/s^2") == (500.0,)
    assert parse_axis_values("800, 800,300", "--accel", "mm/s^2") == (800.0, 800.0, 300.0)
    with pytest.raises(BSplineCAMError, match=r"--accel takes one number .* mm/s\^2"):
        parse_axis_values("fast", "--accel", "mm/s^2")


# --- command line -----------------------------------------------------------------------------
def run_cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "BSplineCAM.orchestration.cli", *args],
                          capture_output=True, text=True, env=env, timeout=600)


@pytest.mark.parametrize("option, value, message", [
    ("--accel", "0", "--accel must lie in [1, 100000] mm/s^2"),
    ("--accel", "1,2", "--accel takes one value or three (X, Y, Z) in mm/s^2"),
    ("--accel", "quick", "--accel takes one number or three"),
    ("--junction-deviation", "-1", "--junction-deviation must lie in [0, 10] mm"),
    ("--rapid", "0", "--rapid-rate must lie in"),
])
def test_cli_refuses_bad_machine_limits(tmp_path: Path, option, value, message):
    ngc = tmp_path / "p.ngc"
    ngc.write_text(program("G1 X10 Y10 F600"))
    out = tmp_path / "out"
    proc = run_cli("verify", str(CASE_STUDY), str(ngc), "--tool-diameter", "6", option, value,
                   "--out", str(out))
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and message in proc.stderr
    assert not out.exists() or not any(out.iterdir())


def test_cli_reports_time_with_acceleration(tmp_path: Path):
    ngc = tmp_path / "p.ngc"
    lines = [f"G1 X{x:.1f} Y{50 + 10 * math.sin(x / 7):.4f} Z20 F2400" for x in range(10, 91)]
    ngc.write_text(program(*lines, start="X10 Y50 Z20"))
    out = tmp_path / "out"
    proc = run_cli("verify", str(CASE_STUDY), str(ngc), "--tool-diameter", "6", "--cell", "1",
                   "--stock-top", "program", "--accel", "200,200,100", "--rapid", "4000",
                   "--junction-deviation", "0.02", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    report = json.loads((out / "verify.json").read_text())
    expected = machining_time(read_gcode(ngc.read_text()),
                              MachineLimits.checked((200.0, 200.0, 100.0), 4000.0, 0.02))
    assert report["machining_time_with_acceleration_s"] == pytest.approx(expected.total)
    assert report["machining_time_with_acceleration_s"] > report["machining_time_s"]
    assert report["machining_time_s"] == pytest.approx(expected.nominal)
    assert report["machine_limits"]["acceleration_mm_per_s2"] == [200.0, 200.0, 100.0]
    summary = json.loads(proc.stdout)
    assert summary["machining_time_with_acceleration_s"] == pytest.approx(expected.total)
