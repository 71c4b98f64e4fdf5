# SPDX-License-Identifier: LGPL-2.1-or-later
"""One-sided arc fitting of passes (issue 14, item 1): tolerance and one-sidedness measured on
the G-code text against the dense polyline, circles with known answers, rs274, simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import ROOT

from BSplineCAM.core import Surface
from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.program.gcode import PLANE_AXES, MoveKind, linearise, read_gcode
from BSplineCAM.core.toolpath import Move, generate, program_moves, to_moves
from BSplineCAM.core.toolpath.arcs import (
    Arc,
    counts,
    feed_length,
    fit_arcs,
    fit_polyline,
    plain_gcode,
)

CASE = ROOT / "examples" / "case-study.json"


def polyline_program(points: np.ndarray, moves: list) -> tuple[np.ndarray, object]:
    """The polyline and the program text read back (G0 to the first point, then ``moves``)."""
    start = Move("rapid", *map(float, points[0]))
    return points, read_gcode(plain_gcode([start, *moves], decimals=6))


def dense(points: np.ndarray, per: int = 200) -> np.ndarray:
    t = np.linspace(0.0, 1.0, per)[:, None]
    return (points[:-1, None, :] * (1 - t) + points[1:, None, :] * t).reshape(-1, 3)


def program_points(program, chord: float = 1e-9) -> np.ndarray:
    """Points along the program's feed moves, arcs cut into chords of sagitta ``chord``."""
    seg = linearise(program, chord)
    feed = ~seg.rapid
    return np.vstack([seg.start[feed], seg.end[feed][-1:]])


def vertical_gaps(points: np.ndarray, program, axis: int, chord: float = 1e-9) -> np.ndarray:
    """Program Z minus polyline Z at the polyline's dense abscissae along ``axis`` (0 x, 1 y);
    the program's arcs are cut into chords of sagitta ``chord`` (mm)."""
    path = program_points(program, chord)
    ref = dense(points)
    order = np.argsort(path[:, axis])
    z_path = np.interp(ref[:, axis], path[order, axis], path[order, 2])
    return z_path - ref[:, 2]


def circle(radius: float, a0: float, a1: float, n: int, centre=(0.0, 0.0)) -> np.ndarray:
    t = np.linspace(math.radians(a0), math.radians(a1), n)
    return np.column_stack([centre[0] + radius * np.cos(t), centre[1] + radius * np.sin(t)])


@pytest.mark.parametrize("plane", [18, 19])
@pytest.mark.parametrize("radius,a0,a1,n", [
    (20.0, 140.0, 40.0, 40),     # hill, along +x
    (20.0, 50.0, 130.0, 25),     # hill, along -x
    (35.0, -130.0, -60.0, 50),   # hollow (centre above), along +x
    (8.0, -40.0, -150.0, 30),    # hollow, along -x
])
def test_circle_passes_one_sided(plane, radius, a0, a1, n):
    """Chords of a circle in a vertical plane: arcs never below the polyline, at most the
    tolerance above it (vertically), on the dense polyline and from the G-code text."""
    tol = 0.01
    xz = circle(radius, a0, a1, n, (3.0, 5.0))
    pts = np.zeros((n, 3))
    h = 0 if plane == 18 else 1
    pts[:, h], pts[:, 1 - h], pts[:, 2] = xz[:, 0], 7.5, xz[:, 1]
    moves = fit_polyline(pts, tol, plane)
    pts, program = polyline_program(pts, moves)
    arcs = program.kind >= MoveKind.ARC_CW
    assert arcs.any() and np.all(program.plane[arcs] == plane)
    gaps = vertical_gaps(pts, program, h)
    assert gaps.min() >= -2e-6  # the text's 6 decimals, on slopes up to 1.2
    assert gaps.max() <= tol + 2e-6
    assert len(moves) < n - 1


def test_hill_circle_is_one_arc():
    """A hill whose chord sag is below the tolerance everywhere: its own circle fits, so a
    single arc of that radius replaces the pass (sweep 100 degrees < MAX_SWEEP_DEG)."""
    xz = circle(20.0, 140.0, 40.0, 60)
    pts = np.column_stack([xz[:, 0], np.zeros(60), xz[:, 1]])
    moves = fit_polyline(pts, 0.02, 18)
    assert len(moves) == 1 and isinstance(moves[0], Arc)
    assert moves[0].radius == pytest.approx(20.0, abs=1e-3)
    assert moves[0].kind == "ccw"  # over the top from -x to +x, seen from +Y: about +Y


def test_waterline_contour_outside():
    """A constant-Z circle (G17) with its free side outwards: every arc point lies outside the
    polygon's chords (radially) and within the tolerance of them."""
    tol = 0.01  # the circle's own chords sag 0.0066 mm
    xy = circle(12.0, 0.0, 300.0, 80, (1.0, -2.0))
    pts = np.column_stack([xy, np.full(len(xy), 4.0)])
    moves = fit_polyline(pts, tol, 17, side=-1.0)  # counter-clockwise: outside is right
    assert sum(isinstance(m, Arc) for m in moves) >= 1 and len(moves) < 20
    _, program = polyline_program(pts, moves)
    path = program_points(program)
    centre = np.array([1.0, -2.0])
    # polygon's radius at each path point's angle (chord of the segment holding it)
    ang = np.arctan2(path[:, 1] - centre[1], path[:, 0] - centre[0]) % (2 * np.pi)
    step = math.radians(300.0) / 79
    k = np.clip((ang // step).astype(int), 0, 78)
    inner = 12.0 * math.cos(step / 2) / np.cos(ang - (k + 0.5) * step)
    radial = np.hypot(path[:, 0] - centre[0], path[:, 1] - centre[1])
    inside_span = ang <= math.radians(300.0)
    assert np.all(radial[inside_span] - inner[inside_span] >= -1e-6)
    assert np.all(radial[inside_span] - inner[inside_span] <= tol + 1e-6)
    assert np.allclose(path[:, 2], 4.0)


def test_oblique_pass_stays_lines():
    """A raster pass at 30 degrees lies in no coordinate plane: no arcs."""
    s = np.linspace(0, 20, 30)
    pts = np.column_stack([s * math.cos(0.5), s * math.sin(0.5), 5 - 0.01 * (s - 10) ** 2])
    moves = fit_arcs([Move("rapid", *pts[0]), *(Move("feed", *p) for p in pts[1:])], 0.01)
    assert not any(isinstance(m, Arc) for m in moves) and len(moves) == 30


def test_bad_arguments_name_option():
    pts = np.zeros((3, 3))
    with pytest.raises(ParameterError, match="tolerance.*mm"):
        fit_polyline(pts, -1.0, 18)
    with pytest.raises(ParameterError, match="plane"):
        fit_polyline(pts, 0.01, 20)
    with pytest.raises(ParameterError, match="points"):
        fit_polyline(np.zeros((3, 2)), 0.01, 18)


def test_plane_words_restore_g17():
    xz = circle(20.0, 140.0, 40.0, 30)
    pts = np.column_stack([xz[:, 0], np.zeros(30), xz[:, 1]])
    text = plain_gcode([Move("rapid", *pts[0]), *fit_polyline(pts, 0.02, 18),
                        Move("rapid", 0.0, 0.0, 30.0)])
    lines = text.splitlines()
    g18 = lines.index("G18")
    assert lines[g18 + 1].startswith(("G2 ", "G3 ")) and "G17" in lines[g18 + 2:]
    assert lines[lines.index("G17", g18) + 1].startswith("G0")
    assert PLANE_AXES[18] == (2, 0, 1)


@pytest.fixture(scope="module")
def case_study():
    surface = Surface.from_json(CASE)
    tp = generate(surface, "raster", 6.0, 0.01, 0.002)
    return surface, tp


def test_case_study_moves_and_one_sidedness(case_study):
    """Arcs on the case-study raster: far fewer moves, never below the polyline, at most half
    the chordal tolerance above it (vertically), measured on the program text."""
    _, tp = case_study
    lines = to_moves(tp)
    arcs = program_moves(tp, arcs=True)
    c = counts(arcs)
    assert c["arcs"] > 1000 and c["moves"] < 0.7 * len(lines)
    program = read_gcode(plain_gcode(arcs, decimals=6))
    assert int(np.count_nonzero(program.kind >= MoveKind.ARC_CW)) == c["arcs"]
    assert set(np.unique(program.plane[program.kind >= MoveKind.ARC_CW])) <= {18, 19}
    # pass by pass along X (G18 passes at constant Y)
    for p in tp.passes[::7]:
        sel = np.flatnonzero((np.abs(program.start[:, 1] - p[0, 1]) < 1e-6)
                             & (np.abs(program.end[:, 1] - p[0, 1]) < 1e-6) & (program.kind > 0)
                             & (np.abs(program.end[:, 0] - program.start[:, 0]) > 1e-9))
        sub = type(program)(**{**program.__dict__, **{
            k: getattr(program, k)[sel] for k in
            ("kind", "start", "end", "centre", "plane", "feed", "line")}})
        gaps = vertical_gaps(p, sub, 0, 1e-8)
        assert gaps.min() >= -2e-6 and gaps.max() <= 0.001 + 2e-6


def _runs_one_vertex_at_a_time(points):
    """The plane runs of a polyline found vertex by vertex: from each start, extend while some
    coordinate stays within PLANE_EPS of the start's."""
    from BSplineCAM.core.toolpath.arcs import PLANE_EPS

    out, n, i = [], len(points), 0
    while i < n - 1:
        same = np.abs(points[i + 1] - points[i]) <= PLANE_EPS
        j = i + 1
        while j + 1 < n:
            nxt = same & (np.abs(points[j + 1] - points[i]) <= PLANE_EPS)
            if not nxt.any():
                break
            same, j = nxt, j + 1
        out.append((i, j, 18 if same[1] else 19 if same[0] else 17 if same[2] else None))
        i = j
    return out


@pytest.mark.parametrize("seed", range(6))
def test_plane_runs_match_a_vertex_by_vertex_search(seed):
    """:func:`arcs._runs` (windows that double) against the plain search written out above,
    on polylines of random stretches: constant Y, X or Z (drifting by up to the tolerance,
    and runs long and short against the window), and stretches in no plane."""
    from BSplineCAM.core.toolpath.arcs import PLANE_EPS, RUN_WINDOW, _runs

    rng = np.random.default_rng(seed)
    pieces = [rng.uniform(0, 50, (1, 3))]
    for _ in range(40):
        k = int(rng.choice([1, 2, 3, RUN_WINDOW - 1, RUN_WINDOW, RUN_WINDOW + 1, 70]))
        last = pieces[-1][-1]
        step = rng.uniform(-1, 1, (k, 3))
        axis = int(rng.integers(0, 4))  # 3: in no plane
        if axis < 3:
            step[:, axis] = rng.uniform(-0.4, 0.4, k) * PLANE_EPS
            step[:, axis] = 0.0 if rng.random() < 0.5 else step[:, axis]
        pieces.append(last + np.cumsum(step, axis=0))
    points = np.vstack(pieces)
    assert _runs(points) == _runs_one_vertex_at_a_time(points)


def test_feed_length_of_lines_helices_and_arcs_in_each_plane():
    """:func:`feed_length` against closed forms: a sloped line, a quarter helix in G17
    (ccw), a quarter arc in G18 and a three-quarter arc in G19 (cw), rapids not counted."""
    moves = [
        Move("rapid", 0.0, 0.0, 5.0),
        Move("feed", 10.0, 0.0, 0.0),                          # sqrt(100 + 25)
        Arc("ccw", 0.0, 10.0, -2.0, 0.0, 0.0, 0.0, 10.0, 17),  # quarter turn, 2 mm down
        Move("rapid", 0.0, 10.0, -2.0),
        Arc("ccw", 10.0, 10.0, -12.0, 0.0, 10.0, -12.0, 10.0, 18),  # (z, x): 0 -> 90 deg
        Move("rapid", 0.0, 0.0, 4.0),
        # G19, in (y, z) about (0, 0, 0), radius 4, seen from +X: cw from 90 deg to 180
        # deg is the long way round, 270 deg
        Arc("cw", 0.0, -4.0, 0.0, 0.0, 0.0, 0.0, 4.0, 19),
    ]
    expected = (math.sqrt(125.0) + math.hypot(10.0 * math.pi / 2, 2.0)
                + 10.0 * math.pi / 2 + 4.0 * 1.5 * math.pi)
    assert feed_length(moves) == pytest.approx(expected, rel=1e-12)
    assert feed_length(moves[:1]) == 0.0


def test_feed_length_of_the_case_study_program_as_read(case_study):
    """The arcs program's feed length is what the G-code reader measures on its text."""
    _, tp = case_study
    moves = program_moves(tp, arcs=True)
    program = read_gcode(plain_gcode(moves, decimals=6))
    feed = program.kind != MoveKind.RAPID
    assert feed_length(moves) == pytest.approx(float(program.lengths()[feed].sum()), rel=1e-7)


def test_case_study_simulated_from_text(case_study):
    """The arcs program simulated from its text: gouge <= 1 um, scallop <= h + tolerance."""
    from BSplineCAM.core.simulation.simulate import Tool
    from BSplineCAM.core.simulation.verify import verify

    surface, tp = case_study
    text = plain_gcode(program_moves(tp, arcs=True))
    m = verify(surface, read_gcode(text), Tool(6.0), cell=0.1).metrics
    assert m["gouge_max_mm"] <= 1e-3
    assert m["scallop_max_mm"] <= 0.01 + 0.002


def test_waterline_arcs_stay_on_the_free_side():
    """Waterline contours of a dome become G17 arcs on the free side: at every point of every
    arc (from the program text) the exact drop-cutter tip height lies at or below the arc's
    Z (no gouge), and the arc stays within half the chordal tolerance of its contour."""
    from BSplineCAM.core.toolpath import DropCutter

    x, y = np.meshgrid(np.linspace(0, 60, 9), np.linspace(0, 60, 9), indexing="ij")
    z = 10 + 40 * np.exp(-((x - 30) ** 2 + (y - 30) ** 2) / 180)
    surface = Surface(np.stack([x, y, z], axis=-1), "clamped", "dome")
    tp = generate(surface, "waterline", 6.0, 0.05, 0.002)
    fitted = program_moves(tp, arcs=True, surface=surface)
    assert counts(fitted)["arcs"] > 50
    program = read_gcode(plain_gcode(fitted, decimals=6))
    arcs = np.flatnonzero(program.kind >= MoveKind.ARC_CW)
    assert np.all(program.plane[arcs] == 17)
    seg = linearise(program, 1e-7)
    on_arc = np.isin(seg.move, arcs)
    pts = seg.end[on_arc]
    dc = DropCutter(surface, 3.0)
    tip = dc.heights(pts[:, :2])[0]
    assert np.nanmax(tip - pts[:, 2]) <= 1e-6
    # within tolerance: each arc point is close to the polyline it replaces
    lines = np.array([[m.x, m.y, m.z] for m in to_moves(tp)])
    from scipy.spatial import cKDTree

    near = cKDTree(lines).query(pts[::5], k=4)[1]
    best = np.full(len(near), np.inf)
    for j in np.concatenate([near.T, np.maximum(near.T - 1, 0)]):  # segments j .. j+1
        a, b = lines[j], lines[np.minimum(j + 1, len(lines) - 1)]
        ab = b - a
        t = np.clip(np.einsum("ij,ij->i", pts[::5] - a, ab)
                    / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(a + t[:, None] * ab - pts[::5], axis=1))
    assert best.max() <= 0.001 + 1e-5


def _greedy_one_end_per_call(sizes, evaluate, first):
    """The greedy runs as documented, one end asked per call (the reference for
    :func:`arcs._greedy`, which asks for several at once)."""
    out = []
    for p, n in enumerate(sizes):
        runs, start = [], 0
        while start < n - 1:
            if start + first > n - 1:
                runs.append((start, start + 1, None))
                start += 1
                continue
            step, best, lo, hi = first, None, 0, None
            while True:
                end = min(start + step, n - 1) if hi is None else (lo + hi) // 2
                fit = evaluate([(p, start, end)])[0]
                if hi is None:
                    if fit is not None:
                        best = (end, fit)
                        if end == n - 1:
                            break
                        step *= 2
                        continue
                    if best is None:
                        break
                    lo, hi = best[0], end
                elif fit is not None:
                    lo, best = end, (end, fit)
                else:
                    hi = end
                if hi - lo <= 1:
                    break
            if best is None:
                runs.append((start, start + 1, None))
                start += 1
            else:
                runs.append((start, best[0], best[1]))
                start = best[0]
        out.append(runs)
    return out


@pytest.mark.parametrize("seed", range(6))
def test_greedy_runs_match_one_end_per_call(seed):
    """arcs._greedy asks for several ends at once (the shortest runs of the next starts after
    a stretch where nothing fits); its runs are those of the plain greedy, one end per call,
    on fit tests that are not monotone (a longer run may fit where a shorter one did not).
    Where nothing fits it needs far fewer calls than positions."""
    from BSplineCAM.core.toolpath import arcs

    rng = np.random.default_rng(seed)
    sizes = [int(n) for n in rng.integers(2, 400, 7)] + [1, 3]
    straight = rng.random(len(sizes)) < 0.5  # sequences with long stretches where nothing fits
    memo: dict = {}

    def evaluate(jobs):
        out = []
        for p, s, e in jobs:
            if (p, s, e) not in memo:
                quiet = straight[p] and (s // 50) % 2 == 0
                ok = not quiet and rng.random() < (0.9 if e - s <= 8 else 0.5)
                memo[p, s, e] = ("fit", p, s, e) if ok else None
            out.append(memo[p, s, e])
        return out

    for first in (2, 4):
        assert arcs._greedy(sizes, evaluate, first) == _greedy_one_end_per_call(
            sizes, evaluate, first)
    # a sequence where nothing fits: a few calls in all, not one per start
    calls = []
    runs = arcs._greedy([1000], lambda jobs: calls.append(len(jobs)) or [None] * len(jobs), 4)
    assert runs == [[(s, s + 1, None) for s in range(999)]]
    assert len(calls) < 1000 / 8
