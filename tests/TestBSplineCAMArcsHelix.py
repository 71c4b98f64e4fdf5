# SPDX-License-Identifier: LGPL-2.1-or-later
"""Helical G17 arcs and biarcs of the arc fitter (issue 14, item 1): helices sampled as
polylines against their closed form, noise and non-helices kept as lines, a G18 biarc built
by the equal-distance construction, round trips through the G-code reader."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import CASE_STUDY

from BSplineCAM.core.program.gcode import MoveKind, linearise, read_gcode
from BSplineCAM.core.toolpath import Move, generate, to_moves
from BSplineCAM.core.toolpath.arcs import (
    MAX_SWEEP_DEG,
    Arc,
    _fit_biarcs,
    counts,
    fit_arcs,
    fit_polyline,
    plain_gcode,
)


def ij_gcode(moves: list, feed: float = 1000.0) -> str:
    """G17 program text with arcs in I/J form (``G17 G2 X.. Y.. Z.. I.. J.. F..``)."""
    lines = ["G17 G21 G90"]
    x = y = 0.0
    for m in moves:
        if isinstance(m, Arc):
            assert m.plane == 17
            word = "G2" if m.kind == "cw" else "G3"
            lines.append(f"G17 {word} X{m.x:.6f} Y{m.y:.6f} Z{m.z:.6f} I{m.cx - x:.6f} "
                         f"J{m.cy - y:.6f} F{feed:g}")
        else:
            word = "G0" if m.kind == "rapid" else "G1"
            lines.append(f"{word} X{m.x:.6f} Y{m.y:.6f} Z{m.z:.6f} F{feed:g}")
        x, y = m.x, m.y
    lines.append("M2")
    return "\n".join(lines) + "\n"


def feeds(points: np.ndarray) -> list:
    return [Move("rapid", *map(float, points[0])), *(Move("feed", *map(float, p))
                                                      for p in points[1:])]


def path_points(program, chord: float = 1e-6) -> np.ndarray:
    """Points along the feed moves of a program, arcs cut into chords of sagitta ``chord``."""
    seg = linearise(program, chord)
    feed = ~seg.rapid
    return np.vstack([seg.start[feed], seg.end[feed][-1:]])


def distance_to_polyline(points: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance (mm) of each point to the nearest segment of a 3-D polyline."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    best = np.full(len(points), np.inf)
    for start in range(0, len(points), 256):
        p = points[start:start + 256, None, :]
        t = np.clip(np.einsum("pkd,kd->pk", p - a, ab) / np.einsum("kd,kd->k", ab, ab), 0, 1)
        d = np.linalg.norm(a + t[..., None] * ab - p, axis=2).min(axis=1)
        best[start:start + 256] = d
    return best


def helix(radius, rate, turns, n, centre=(2.0, -1.0), z0=10.0, phase=0.3):
    """Samples of a helix: angle theta from ``phase`` over ``turns`` turns (negative: clockwise),
    z = z0 + rate * (theta - phase) (mm per radian)."""
    theta = phase + np.linspace(0.0, 2.0 * np.pi * turns, n)
    pts = np.column_stack([centre[0] + radius * np.cos(theta),
                           centre[1] + radius * np.sin(theta), z0 + rate * (theta - phase)])
    return pts, theta


def helix_error(points: np.ndarray, radius, rate, centre, z0, phase) -> np.ndarray:
    """An upper bound of the distance (mm) from points along the path (in order, starting at
    the helix's first point) to the helix: to the helix point at the same unwrapped angle."""
    w = points[:, :2] - np.asarray(centre)
    theta = phase + np.unwrap(np.arctan2(w[:, 1], w[:, 0]) - phase)
    theta += 2 * np.pi * np.round((phase - theta[0]) / (2 * np.pi))
    return np.hypot(np.hypot(w[:, 0], w[:, 1]) - radius,
                    points[:, 2] - (z0 + rate * (theta - phase)))


@pytest.mark.parametrize("radius,rate,turns,n", [
    (5.0, -1.0 / (2 * np.pi), 2.0, 401),   # descending ramp, 1 mm per turn, counter-clockwise
    (12.0, -0.2, -1.5, 541),               # clockwise, steeper
    (3.0, 0.05, 0.75, 91),                 # ascending, under a turn
])
def test_sampled_helix_is_helical_arcs(radius, rate, turns, n):
    """A helix sampled as a polyline (chord sag far below the tolerance) becomes few G17
    arcs: centre and radius of the helix, end Z on it, sweep at most MAX_SWEEP_DEG; the
    program read back from I/J text stays within the tolerance of the helix and of the
    polyline, and every vertex within the tolerance of the program."""
    tol = 0.01
    centre, z0, phase = (2.0, -1.0), 10.0, 0.3
    pts, _ = helix(radius, rate, turns, n, centre, z0, phase)
    moves = fit_arcs(feeds(pts), tol)
    arcs = [m for m in moves if isinstance(m, Arc)]
    sweep_deg = 360.0 * abs(turns)
    assert len(arcs) == len(moves) - 1  # every feed is an arc
    assert math.ceil(sweep_deg / MAX_SWEEP_DEG) <= len(arcs) <= math.ceil(sweep_deg
                                                                          / MAX_SWEEP_DEG) + 1
    for arc in arcs:
        assert arc.plane == 17 and arc.kind == ("ccw" if turns > 0 else "cw")
        assert arc.radius == pytest.approx(radius, abs=1e-6)
        assert (arc.cx, arc.cy) == pytest.approx(centre, abs=1e-6)
    ends = np.array([[a.x, a.y, a.z] for a in arcs])
    assert np.all(helix_error(np.vstack([pts[:1], ends]), radius, rate, centre, z0, phase)
                  <= 1e-9)
    assert np.ptp(ends[:, 2]) > 0  # Z changes along the arcs
    program = read_gcode(ij_gcode(moves))
    assert np.all(program.plane[program.kind >= MoveKind.ARC_CW] == 17)
    path = path_points(program)
    assert helix_error(path, radius, rate, centre, z0, phase).max() <= tol
    assert distance_to_polyline(path, pts).max() <= tol
    assert distance_to_polyline(pts, path).max() <= tol


def test_helix_noise_above_tenth_stays_lines(rng):
    """Samples of a helix with noise well above tolerance / 10 (no side17): no arcs; below it,
    arcs within the tolerance of the polyline."""
    tol = 0.01
    pts, _ = helix(5.0, -0.15, 1.0, 201)
    noisy = pts + rng.normal(scale=0.5 * tol, size=pts.shape)
    moves = fit_arcs(feeds(noisy), tol)
    assert counts(moves) == {"moves": 201, "arcs": 0, "lines": 200, "rapids": 1}
    quiet = pts + rng.uniform(-tol / 40, tol / 40, size=pts.shape)
    moves = fit_arcs(feeds(quiet), tol)
    assert counts(moves)["arcs"] >= 3 and len(moves) < 20
    path = path_points(read_gcode(ij_gcode(moves)))
    assert distance_to_polyline(path, quiet).max() <= tol


@pytest.mark.parametrize("shape", ["quadratic", "wavy", "spiral"])
def test_descending_non_helix_stays_lines(shape):
    """Descending polylines that are no helix within tolerance / 10, not even over five
    vertices: Z not linear in the angle (quadratic, or wavy), or a spiral whose radius
    shrinks 0.8 mm per radian sampled every 10 degrees: lines only."""
    tol = 0.01
    theta = np.radians(np.arange(0.0, 300.0, 10.0 if shape == "spiral" else 5.0))
    radius = np.full(len(theta), 6.0)
    if shape == "quadratic":
        z = 5.0 - 0.5 * theta ** 2
    elif shape == "wavy":
        z = 5.0 - 0.3 * theta + 0.05 * np.sin(theta * 18.0)
    else:
        radius = 8.0 - 0.8 * theta
        z = 5.0 - 0.3 * theta
    pts = np.column_stack([radius * np.cos(theta), radius * np.sin(theta), z])
    moves = fit_arcs(feeds(pts), tol)
    assert not any(isinstance(m, Arc) for m in moves) and len(moves) == len(pts)


def test_fine_descending_spiral_is_local_helices():
    """The same spiral sampled every 5 degrees is a helix within tolerance / 10 over runs of
    vertices: helical arcs (Z changing, radii between the spiral's extremes), the program
    read back within the tolerance of the polyline and the polyline within it of the
    program."""
    tol = 0.01
    theta = np.radians(np.arange(0.0, 300.0, 5.0))
    radius = 8.0 - 0.8 * theta
    pts = np.column_stack([radius * np.cos(theta), radius * np.sin(theta), 5.0 - 0.3 * theta])
    moves = fit_arcs(feeds(pts), tol)
    arcs = [m for m in moves if isinstance(m, Arc)]
    assert len(arcs) >= 5 and len(moves) < len(pts) // 3
    assert all(radius.min() < a.radius < radius.max() for a in arcs)
    path = path_points(read_gcode(ij_gcode(moves)))
    assert distance_to_polyline(path, pts).max() <= tol
    assert distance_to_polyline(pts, path).max() <= tol


def test_helix_with_side17_one_sided():
    """With side17 (free side outside a counter-clockwise helix: right of travel) the XY
    projection of every helical arc lies outside the polygon's chords by at most the
    tolerance, and its Z follows the polyline's."""
    tol = 0.01
    radius, rate = 8.0, -0.1
    pts, _ = helix(radius, rate, 1.2, 200, centre=(0.0, 0.0), phase=0.0)
    moves = fit_arcs(feeds(pts), tol, side17=lambda run: -1.0)
    assert counts(moves)["arcs"] >= 3 and len(moves) < 12
    path = path_points(read_gcode(ij_gcode(moves)))
    step = 2 * np.pi * 1.2 / 199
    rho = np.hypot(path[:, 0], path[:, 1])
    assert rho.min() >= radius * math.cos(step / 2) - 1e-6  # outside every chord
    assert rho.max() <= radius + tol
    assert distance_to_polyline(path, pts).max() <= tol


def equal_distance_biarc(a, b, ta, tb):
    """Closed form of the equal-distance biarc (Bolton 1975): tangent lengths d from
    |b - a - d (ta + tb)| = 2 d, joint midway between a + d ta and b - d tb; each arc's centre
    on the normal at its end point, equidistant from the joint."""
    v = b - a
    t = ta + tb
    dot = ta @ tb
    d = (-(v @ t) + math.sqrt((v @ t) ** 2 + 2 * (1 - dot) * (v @ v))) / (2 * (1 - dot))
    joint = 0.5 * (a + d * ta + b - d * tb)
    arcs = []
    for p, tangent in ((a, ta), (b, tb)):
        normal = np.array([-tangent[1], tangent[0]])
        lam = (joint - p) @ (joint - p) / (2 * normal @ (joint - p))
        arcs.append((p + lam * normal, abs(lam)))
    return joint, arcs


def sampled_biarc(step: float):
    """A hill made of two tangent arcs of different radii (A = (0, 0) at 40 degrees up,
    B = (20, 0) at 30 degrees down, (horizontal, vertical) coordinates), sampled about every
    ``step`` mm of arc length with the joint inside a chord."""
    a, b = np.array([0.0, 0.0]), np.array([20.0, 0.0])
    ta = np.array([math.cos(math.radians(40)), math.sin(math.radians(40))])
    tb = np.array([math.cos(math.radians(-30)), math.sin(math.radians(-30))])
    joint, ((c1, r1), (c2, r2)) = equal_distance_biarc(a, b, ta, tb)
    spans = []
    for (c, r), p, q in (((c1, r1), a, joint), ((c2, r2), joint, b)):
        t0, t1 = (math.atan2(*(x - c)[::-1]) for x in (p, q))
        spans.append((c, r, t0, t1, r * abs(t1 - t0)))
    total = spans[0][4] + spans[1][4]
    s = np.linspace(0.0, total, int(math.ceil(total / step)) + 1)
    pts = []
    for x in s:
        c, r, t0, t1, length = spans[0] if x <= spans[0][4] else spans[1]
        f = (x if x <= spans[0][4] else x - spans[0][4]) / length
        angle = t0 + f * (t1 - t0)
        pts.append(c + r * np.array([math.cos(angle), math.sin(angle)]))
    return np.array(pts), ta, tb, joint, (c1, r1), (c2, r2)


def vertical_gaps(points: np.ndarray, program) -> np.ndarray:
    """Program Z minus polyline Z at dense abscissae along X (G18 pass)."""
    path = path_points(program, 1e-8)
    t = np.linspace(0.0, 1.0, 100)[:, None]
    ref = (points[:-1, None, :] * (1 - t) + points[1:, None, :] * t).reshape(-1, 3)
    order = np.argsort(path[:, 0])
    return np.interp(ref[:, 0], path[order, 0], path[order, 2]) - ref[:, 2]


def test_g18_biarc_pass_is_two_arcs():
    """A G18 pass sampled from two tangent arcs of radii 13.6 and 24.0 mm: exactly two arcs,
    each at most the tolerance above the polyline and never below it (from the text)."""
    tol = 0.01
    xz, *_ , (c1, r1), (c2, r2) = sampled_biarc(0.5)
    assert abs(r1 - r2) > 5.0
    pts = np.column_stack([xz[:, 0], np.full(len(xz), 3.0), xz[:, 1]])
    moves = fit_polyline(pts, tol, 18)
    assert len(moves) == 2 and all(isinstance(m, Arc) and m.plane == 18 for m in moves)
    program = read_gcode(plain_gcode([Move("rapid", *pts[0]), *moves], decimals=6))
    gaps = vertical_gaps(pts, program)
    assert gaps.min() >= -2e-6 and gaps.max() <= tol + 2e-6


def test_biarc_construction_matches_closed_form():
    """The fitter's biarc through the sampled two-arc hill, with the curve's end tangents,
    is the closed-form one; it is rejected when the tolerance is below the chords' sag."""
    xz, ta, tb, joint, (c1, r1), (c2, r2) = sampled_biarc(0.5)
    fit = _fit_biarcs([xz], ta[None], tb[None], 0.01, np.array([True]))[0]
    assert fit is not None
    assert fit.joint == pytest.approx(joint, abs=1e-9)
    assert fit.centres[0] == pytest.approx(c1, abs=1e-9)
    assert fit.centres[1] == pytest.approx(c2, abs=1e-9)
    assert fit.radii == pytest.approx([r1, r2], abs=1e-9)
    sag = min(r1, r2) * (1 - math.cos(0.5 * 0.5 / max(r1, r2)))  # below every chord's sag
    assert _fit_biarcs([xz], ta[None], tb[None], 0.5 * sag, np.array([True]))[0] is None


@pytest.fixture(scope="module")
def case_study_moves():
    from BSplineCAM.core import Surface

    tp = generate(Surface.from_json(CASE_STUDY), "raster", 6.0, 0.01, 0.002)
    return tp, to_moves(tp)


def test_case_study_biarcs_fewer_moves_one_sided(case_study_moves):
    """Biarcs on the case-study raster: fewer moves than single arcs alone; on every pass
    holding a biarc (an arc ending off the polyline's vertices) the program from the text is
    never below the polyline and at most the tolerance above it (vertically)."""
    tp, lines = case_study_moves
    tol = 0.5 * float(tp.parameters["tolerance"])
    single = fit_arcs(lines, tol, biarcs=False)
    both = fit_arcs(lines, tol)
    assert counts(both)["moves"] < counts(single)["moves"]
    vertices = {(round(m.x, 9), round(m.y, 9), round(m.z, 9)) for m in lines}
    joints = [m for m in both if isinstance(m, Arc)
              and (round(m.x, 9), round(m.y, 9), round(m.z, 9)) not in vertices]
    assert joints and all(m.plane in (18, 19) for m in joints)
    program = read_gcode(plain_gcode(both, decimals=6))
    for y in sorted({m.y for m in joints if m.plane == 18})[:20]:
        p = next(q for q in tp.passes if abs(q[0, 1] - y) < 1e-9)
        sel = np.flatnonzero((np.abs(program.start[:, 1] - y) < 1e-6)
                             & (np.abs(program.end[:, 1] - y) < 1e-6) & (program.kind > 0)
                             & (np.abs(program.end[:, 0] - program.start[:, 0]) > 1e-9))
        sub = type(program)(**{**program.__dict__, **{
            k: getattr(program, k)[sel] for k in
            ("kind", "start", "end", "centre", "plane", "feed", "line")}})
        gaps = vertical_gaps(p, sub)
        assert gaps.min() >= -2e-6 and gaps.max() <= tol + 2e-6


def test_nanmedian_rows_against_numpy():
    """The helix fit's row median against np.nanmedian: rows of odd and even counts of
    numbers among NaNs, a row of NaNs (NaN), one number, ties."""
    import warnings

    from BSplineCAM.core.toolpath.arcs import _nanmedian_rows

    rng = np.random.default_rng(8)
    a = rng.normal(size=(200, 7))
    a[rng.random(a.shape) < 0.35] = np.nan
    a[0] = np.nan
    a[1] = [np.nan] * 6 + [2.5]
    a[2] = [1.0, 1.0, 3.0, 3.0, np.nan, np.nan, 1.0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # numpy warns on the row of NaNs
        ref = np.nanmedian(a, axis=1)
    np.testing.assert_array_equal(_nanmedian_rows(a), ref)
