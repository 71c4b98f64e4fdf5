# SPDX-License-Identifier: LGPL-2.1-or-later
"""One-sided arc fitting of finishing passes: G2/G3 moves that never dip below the polyline.

A pass is a polyline of tool-tip (cutter-location) points whose chords already clear the
exact cutter-location curve (:mod:`chords`).  :func:`fit_arcs` replaces runs of its feed moves
by circular arcs in the coordinate plane that holds the run: G18 (XZ) where Y is constant (a
raster pass along X), G19 (YZ) where X is constant (along Y), and G17 (XY) where Z is constant
(a waterline contour) when the caller says which side of the contour is free (``side17``).
Raster passes at other angles lie in no coordinate plane and stay lines.

Each arc interpolates two vertices of the polyline and lies on its free side by at least 0
and at most ``tolerance`` (mm) everywhere along the run; the fits of batches of runs (single
arcs, biarcs, helices) are :mod:`.arcs_fit`'s.  Runs grow greedily from each start
(galloping, then bisection on the end vertex), those of all passes in lockstep so that each
round is one vectorised evaluation; a run that admits no arc is cut by a straight move.
Consecutive arcs meet at shared vertices (an arc spline through the polyline's vertices;
tangent continuity is not imposed).

Biarcs: after the single arcs, every run of three or more consecutive pieces (arcs or lines)
over a smooth stretch of the polyline (no turn above BIARC_KINK_DEG between its chords) is
tried as one biarc, two arcs tangent at a joint that need not be a vertex, the polyline's
tangents at the run's ends those of the circles through each end and its neighbours.  It is
accepted under the single arc's tests, so it only replaces three or more moves by two.

Helices: a stretch of feeds in no coordinate plane (X, Y and Z all changing, e.g. a helical
entry written as short feeds, or a descending spiral) is fitted by helical G17 arcs: XY on a
circle through the run's end points, Z linear in the angle: the vertices within
``tolerance`` / 10 of the helix in 3-D without ``side17`` (the polyline was sampled from a
helix, so nothing is cut that it does not cut); with ``side17``, the XY projection fitted
one-sidedly like a contour's.  A helical arc spans at least HELIX_MIN_POINTS vertices, so
that the fit is overdetermined.

The :class:`Arc` move, its G-code words, :func:`feed_length`, :func:`counts` and
:func:`plain_gcode` are :mod:`.arcs_moves`'s, re-exported here with the fitters' limits.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import NamedTuple

import numpy as np

from ..errors import ParameterError
from ..program.gcode import PLANE_AXES
from ..typing import FloatArray
from .arcs_fit import (
    MAX_RADIUS,
    MAX_SWEEP_DEG,
    _Biarc,
    _fit_biarcs,
    _fit_helices,
    _fit_runs,
    _gather,
    _tangents,
)
from .arcs_fit import _nanmedian_rows as _nanmedian_rows
from .arcs_moves import AnyMove, Arc, _arc, counts, feed_length, gcode_words, plain_gcode
from .common import Move, check_positive

#: Coordinates equal within this (mm) define the plane of a run.
PLANE_EPS = 1e-9
#: Vertices of the first window in which :func:`_runs` looks for a run's end.
RUN_WINDOW = 16
#: Fewest polyline vertices under one helical arc: with the end points fixed, the circle has
#: one free parameter and Z none, so three or more interior vertices overdetermine it.
HELIX_MIN_POINTS = 5
#: Largest turn (degrees) between successive chords inside a run tried as a biarc.
BIARC_KINK_DEG = 20.0
#: Starts whose shortest runs a sequence starting a run asks for at once (:func:`_greedy`).
FRESH_AHEAD = 16

#: side17(points (n, 3)) -> +1 if the free side of the contour is left of travel, -1 right.
SideFn = Callable[[FloatArray], float]


def _greedy(sizes: Sequence[int], evaluate: Callable[[list[tuple[int, int, int]]], list],
            first: int) -> list[list[tuple]]:
    """Greedy runs over positions 0 .. size - 1 of several sequences, all advanced in lockstep
    so that every round is one vectorised evaluation: per sequence a list of (start, end, fit
    or None), None meaning one step (end = start + 1).  From each start the run's end gallops
    (start + first, then doubling the step) until ``evaluate`` admits no fit, then bisects.
    ``evaluate`` takes (sequence, start, end) triples and returns a fit or None for each.

    Where no run fits (a stretch of straight feeds), each round would move a sequence on by
    one position: so a sequence starting a run after such a failure asks at once for the
    shortest runs from its next starts (twice as many each time they all fail, up to
    FRESH_AHEAD), and takes them in order (a failure is the single step to the next start)
    up to the first that fits; the runs are those of one end per round."""
    P = len(sizes)
    out: list[list[tuple]] = [[] for _ in range(P)]
    start = [0] * P
    step = [first] * P
    best: list = [None] * P
    lo = [0] * P
    hi: list = [None] * P  # bisection bracket once a run failed
    ahead = [1] * P  # starts asked for at once by a sequence starting a run

    def commit(p: int) -> None:
        if best[p] is None:
            out[p].append((start[p], start[p] + 1, None))
            start[p] += 1
        else:
            out[p].append((start[p], best[p][0], best[p][1]))
            start[p] = best[p][0]
        step[p], best[p], hi[p] = first, None, None

    active = list(range(P))
    while active:
        jobs = []
        runnable = []
        fresh: list = []  # sequences starting a run: (sequence, first row in jobs, rows)
        for p in active:
            n = sizes[p]
            while start[p] < n - 1 and start[p] + first > n - 1:
                commit(p)  # too few steps left for a run
            if start[p] >= n - 1:
                continue
            if hi[p] is None and best[p] is None:
                # the shortest runs from this start and the next ones (each needs first
                # steps left: end <= n - 1)
                s0 = start[p]
                k = min(ahead[p], n - first - s0)
                fresh.append((p, len(jobs), k))
                jobs += [(p, s0 + i, s0 + i + first) for i in range(k)]
                continue
            end = min(start[p] + step[p], n - 1) if hi[p] is None else (lo[p] + hi[p]) // 2
            jobs.append((p, start[p], end))
            runnable.append((p, len(jobs) - 1))
        if not jobs:
            break
        fits = evaluate(jobs)
        for p, at, k in fresh:
            n = sizes[p]
            ahead[p] = min(2 * ahead[p], FRESH_AHEAD)  # unless one fits
            for i in range(k):
                fit = fits[at + i]
                if fit is None:
                    commit(p)  # one step on: the next start's run is the next row
                    continue
                ahead[p] = 1
                end = jobs[at + i][2]
                best[p] = (end, fit)
                if end == n - 1:
                    commit(p)
                else:
                    step[p] *= 2
                break
        for p, r in runnable:
            end, fit = jobs[r][2], fits[r]
            n = sizes[p]
            if hi[p] is None:  # galloping
                if fit is not None:
                    best[p] = (end, fit)
                    if end == n - 1:
                        commit(p)
                    else:
                        step[p] *= 2
                elif best[p] is None:
                    commit(p)
                else:
                    lo[p], hi[p] = best[p][0], end
                    if hi[p] - lo[p] <= 1:
                        commit(p)
            else:  # bisecting: lo fits, hi does not
                if fit is not None:
                    lo[p], best[p] = end, (end, fit)
                else:
                    hi[p] = end
                if hi[p] - lo[p] <= 1:
                    commit(p)
        active = [p for p in active if start[p] < sizes[p] - 1]
    return out


def _fit_polylines(polylines: Sequence[FloatArray], tolerance: float, flags: Sequence[bool],
                   fitter: Callable | None = None, first: int = 2) -> list[list[tuple]]:
    """Greedy arc splines of polylines (:func:`_greedy` over their vertices, runs of at least
    ``first`` segments): per polyline a list of (start index, end index, _Fit or None), None meaning
    the straight segment.  ``fitter(runs, tolerance, flags)`` is :func:`_fit_runs` (2-D,
    ``flags`` = vertical) or :func:`_fit_helices` (3-D, ``flags`` = sided)."""
    flat = np.concatenate(polylines)
    row = np.concatenate([[0], np.cumsum([len(q) for q in polylines])[:-1]])  # of vertex 0
    flag = np.array(flags, bool)

    def evaluate(jobs: list[tuple[int, int, int]]) -> list:
        p, s, e = np.array(jobs).T
        if fitter is None:  # the runs gathered at once
            return _fit_runs(_gather(flat, row[p] + s, e - s + 1), tolerance, flag[p])
        return fitter([polylines[k][i:j + 1] for k, i, j in jobs], tolerance, flag[p])

    return _greedy([len(q) for q in polylines], evaluate, first)


def _with_biarcs(polylines: Sequence[FloatArray], fitted: list[list[tuple]], tolerance: float,
                 vertical: Sequence[bool]) -> list[list[tuple]]:
    """The pieces of :func:`_fit_polylines` with every run of three or more consecutive pieces
    that one biarc fits (:func:`_fit_biarcs`) replaced by it (two moves for three or more), the
    runs chosen greedily (:func:`_greedy` over the pieces' end vertices).  A run is tried only
    where the polyline is smooth: no turn above BIARC_KINK_DEG at its interior vertices; the
    biarc's end tangents are the polyline's (:func:`_tangents`)."""
    bounds = [[f[0][0]] + [piece[1] for piece in f] for f in fitted]
    kinks = []
    for q in polylines:
        d = np.diff(q, axis=0)
        length = np.hypot(d[:, 0], d[:, 1])
        cos = np.einsum("ij,ij->i", d[:-1], d[1:])
        kink = ~(cos >= math.cos(math.radians(BIARC_KINK_DEG)) * length[:-1] * length[1:])
        kink |= (length[:-1] == 0) | (length[1:] == 0)
        kinks.append(np.concatenate([[0, 0], np.cumsum(kink)]))  # kinks at vertices < index
    # everything laid end to end: vertex k of polyline p is row first[p] + k, its piece
    # bound b row first_bound[p] + b
    flat = np.concatenate(polylines)
    first = np.concatenate([[0], np.cumsum([len(q) for q in polylines])[:-1]])
    tangents = np.concatenate([_tangents(q) for q in polylines])
    kink_flat = np.concatenate(kinks)
    bound_flat = np.concatenate([np.asarray(b) for b in bounds])
    first_bound = np.concatenate([[0], np.cumsum([len(b) for b in bounds])[:-1]])
    flags = np.array(vertical, bool)

    def evaluate(jobs: list[tuple[int, int, int]]) -> list:
        out: list = [None] * len(jobs)
        p, s, e = np.array(jobs).T
        i = first[p] + bound_flat[first_bound[p] + s]
        j = first[p] + bound_flat[first_bound[p] + e]
        rows = np.flatnonzero(kink_flat[j] - kink_flat[i + 1] <= 0)
        if len(rows):
            i, j, p = i[rows], j[rows], p[rows]
            fits = _fit_biarcs(_gather(flat, i, j - i + 1), tangents[i], tangents[j],
                               tolerance, flags[p])
            for r, fit in zip(rows.tolist(), fits):
                out[r] = fit
        return out

    merged = _greedy([len(b) for b in bounds], evaluate, 3)
    result: list[list[tuple]] = []
    for p, pieces in enumerate(merged):
        result.append([fitted[p][s] if fit is None else (bounds[p][s], bounds[p][e], fit)
                       for s, e, fit in pieces])
    return result


def _runs(points: FloatArray) -> list[tuple[int, int, int | None]]:
    """Split a 3-D polyline into maximal runs lying in one coordinate plane: (start, stop
    inclusive, plane or None).  Y constant -> 18, else X constant -> 19, else Z -> 17.

    From each start i the run reaches the farthest vertex up to which some coordinate stays
    within PLANE_EPS of vertex i's; each coordinate's extent is searched in windows that
    double from RUN_WINDOW vertices.  A start whose next vertex keeps no coordinate is a
    one-segment run in no plane."""
    out = []
    n = len(points)
    i = 0
    while i < n - 1:
        ext = np.full(3, -1)  # last vertex up to which each coordinate stays put
        start, width = i + 1, RUN_WINDOW
        while start < n and (ext < 0).any():
            hi = min(n, start + width)
            far = np.abs(points[start:hi] - points[i]) > PLANE_EPS
            found = (ext < 0) & far.any(axis=0)
            ext[found] = start + np.argmax(far, axis=0)[found] - 1
            start, width = hi, 2 * width
        ext[ext < 0] = n - 1
        j = int(ext.max())
        if j == i:
            out.append((i, i + 1, None))
            i += 1
            continue
        same = ext == j
        out.append((i, j, 18 if same[1] else 19 if same[0] else 17 if same[2] else None))
        i = j
    return out


class _Plan(NamedTuple):
    """A 3-D run in a coordinate plane and its 2-D picture for the fitter (free side left);
    for a ``helix`` candidate (a run leaving every coordinate plane) the picture is 3-D, the
    XY part mirrored like a G17 run's and Z appended."""

    points: FloatArray
    plane: int
    flat: FloatArray
    vertical: bool
    sense: float
    helix: bool = False
    sided: bool = False


def _plan(pts3: FloatArray, plane: int, side: float, helix: bool = False,
          sided: bool = False) -> _Plan:
    if plane != 17:
        # horizontal axis along the pass, Z up; travel in -x (-y) is mirrored to +x (+y)
        h = 0 if plane == 18 else 1
        sense = 1.0 if pts3[-1, h] >= pts3[0, h] else -1.0
        return _Plan(pts3, plane, np.column_stack([sense * pts3[:, h], pts3[:, 2]]), True,
                     sense)
    flat = pts3[:, :2] * np.array([1.0, side])
    if helix:
        flat = np.column_stack([flat, pts3[:, 2]])
    return _Plan(pts3, plane, flat, False, side, helix, sided)


def _to3(plan: _Plan, start: FloatArray, point: FloatArray) -> FloatArray:
    """A point of the plan's 2-D picture in 3-D, the normal coordinate taken from ``start``."""
    out = start.copy()
    if plan.vertical:
        out[0 if plan.plane == 18 else 1] = plan.sense * point[0]
        out[2] = point[1]
    else:
        out[0], out[1] = point[0], plan.sense * point[1]
    return out


def _moves(plan: _Plan, fits: list[tuple]) -> list[AnyMove]:
    """Moves of one planned run from its fitted pieces."""
    pts3 = plan.points
    moves: list[AnyMove] = []
    for i, j, fit in fits:
        end = pts3[j]
        if isinstance(fit, _Biarc):
            joint = _to3(plan, pts3[i], fit.joint)
            moves.append(_arc(pts3[i], joint, _to3(plan, pts3[i], fit.centres[0]),
                              float(fit.radii[0]), plan.plane))
            moves.append(_arc(joint, end, _to3(plan, joint, fit.centres[1]),
                              float(fit.radii[1]), plan.plane))
        elif fit is None or fit.line:
            moves.append(Move("feed", float(end[0]), float(end[1]), float(end[2])))
        else:
            moves.append(_arc(pts3[i], end, _to3(plan, pts3[i], fit.centre), fit.radius,
                              plan.plane))
    return moves


def _fit_plans(plans: Sequence[_Plan], tolerance: float, biarcs: bool) -> list[list[tuple]]:
    """Fitted pieces of every plan: arcs in coordinate planes (then biarcs) and helices, each
    kind fitted in one lockstep batch."""
    out: list[list[tuple]] = [[] for _ in plans]
    planar = [k for k, p in enumerate(plans) if not p.helix]
    helical = [k for k, p in enumerate(plans) if p.helix]
    if planar:
        flats = [plans[k].flat for k in planar]
        vertical = [plans[k].vertical for k in planar]
        fitted = _fit_polylines(flats, tolerance, vertical)
        if biarcs:
            fitted = _with_biarcs(flats, fitted, tolerance, vertical)
        for k, f in zip(planar, fitted):
            out[k] = f
    if helical:
        fitted = _fit_polylines([plans[k].flat for k in helical], tolerance,
                                [plans[k].sided for k in helical], _fit_helices,
                                HELIX_MIN_POINTS - 1)
        for k, f in zip(helical, fitted):
            out[k] = f
    return out


def fit_polyline(points: Sequence, tolerance: float, plane: int,
                 side: float = 1.0, biarcs: bool = True) -> list[AnyMove]:
    """Feed moves (Move 'feed' and :class:`Arc`) from points[0] along a polyline lying in
    ``plane`` (17, 18 or 19; points (n, 3), mm), within ``tolerance`` (mm) on its free side:
    above in G18/G19, left of travel (``side`` +1) or right (-1) in G17; with ``biarcs``, runs
    of three or more pieces that one biarc fits become its two arcs."""
    tolerance = check_positive(tolerance, "tolerance", "mm")
    if plane not in PLANE_AXES:
        raise ParameterError(f"plane must be 17, 18 or 19, got {plane!r}")
    pts3 = np.asarray(points, dtype=float)
    if pts3.ndim != 2 or pts3.shape[1] != 3 or len(pts3) < 2:
        raise ParameterError(f"points must be an (n >= 2, 3) array in mm, got {pts3.shape}")
    plan = _plan(pts3, plane, 1.0 if side >= 0 else -1.0)
    return _moves(plan, _fit_plans([plan], tolerance, biarcs)[0])


def fit_arcs(moves: Iterable[Move], tolerance: float, side17: SideFn | None = None,
             biarcs: bool = True, helices: bool = True) -> list[AnyMove]:
    """Moves with runs of feeds replaced by one-sided arcs within ``tolerance`` (mm).

    Feeds in a vertical coordinate plane (Y or X constant) become G18 / G19 arcs above the
    polyline; feeds at constant Z become G17 arcs on the free side that ``side17`` names (no
    G17 arcs without it); with ``biarcs``, runs of three or more of those pieces that one
    biarc fits become its two arcs.  With ``helices``, stretches of feeds in no coordinate
    plane (segments changing X, Y and Z) become helical G17 arcs (:func:`_fit_helices`): with
    ``side17``, the XY projection one-sided like a contour's and every vertex's Z within
    ``tolerance`` / 10 of the helix; without it, every vertex within ``tolerance`` / 10 of the
    helix in 3-D (the polyline was sampled from a helix, so the helix cuts nothing it does
    not); in both cases the helix within ``tolerance`` of every chord.  Everything else is
    kept; rapids pass through unchanged.  All runs are fitted together."""
    tolerance = check_positive(tolerance, "tolerance", "mm")
    moves = list(moves)
    pieces: list = []  # Move, or the index of a plan
    plans: list[_Plan] = []

    def lines(run: FloatArray) -> None:
        pieces.extend(Move("feed", float(x), float(y), float(z)) for x, y, z in run[1:])

    def side_of(run: FloatArray) -> float:
        return 1.0 if side17 is None or float(side17(run)) >= 0 else -1.0

    def loose(run: FloatArray) -> None:
        """Feeds in no coordinate plane: a helix candidate or lines."""
        if helices and len(run) >= HELIX_MIN_POINTS:
            pieces.append(len(plans))
            plans.append(_plan(run, 17, side_of(run), helix=True, sided=side17 is not None))
        elif len(run) >= 2:
            lines(run)

    xyz = np.array([m[1:4] for m in moves], dtype=float).reshape(-1, 3)  # every end point
    k = 0
    position: FloatArray | None = None
    while k < len(moves):
        m = moves[k]
        if m.kind != "feed" or position is None:
            pieces.append(m)
            position = xyz[k]
            k += 1
            continue
        stop = k
        while stop < len(moves) and moves[stop].kind == "feed":
            stop += 1
        pts = np.vstack([position, xyz[k:stop]])
        stretch: int | None = None  # first vertex of the pending loose stretch
        for i, j, plane in _runs(pts):
            if plane is None or j - i < 2:
                stretch = i if stretch is None else stretch
                continue
            if stretch is not None:
                loose(pts[stretch:i + 1])
                stretch = None
            run = pts[i:j + 1]
            if plane == 17 and side17 is None:
                lines(run)
                continue
            pieces.append(len(plans))
            plans.append(_plan(run, plane, side_of(run) if plane == 17 else 1.0))
        if stretch is not None:
            loose(pts[stretch:])
        position = pts[-1]
        k = stop
    fitted = _fit_plans(plans, tolerance, biarcs)
    out: list[AnyMove] = []
    for piece in pieces:
        if isinstance(piece, int):
            out.extend(_moves(plans[piece], fitted[piece]))
        else:
            out.append(piece)
    return out


def contour_side(heights: Callable[[FloatArray], FloatArray], offset: float = 0.05
                 ) -> SideFn:
    """``side17`` for waterline contours: the free side is where the exact tool-tip height
    (``heights(xy)``, mm, e.g. a DropCutter's) lies below the contour's Z.  It is sampled
    ``offset`` mm left of the contour's chords (where the ball meets no surface counts as
    free); a level set has the same free side along its whole length, so the majority
    decides."""

    def side(points: FloatArray) -> float:
        d = np.diff(points[:, :2], axis=0)
        length = np.hypot(d[:, 0], d[:, 1])
        ok = length > 0
        left = np.column_stack([-d[ok, 1], d[ok, 0]]) / length[ok, None]
        mid = 0.5 * (points[:-1, :2] + points[1:, :2])[ok]
        z = np.asarray(heights(mid + offset * left), dtype=float)
        above = np.count_nonzero(z >= points[0, 2])
        below = len(z) - above  # NaN: the ball meets no surface there, free too
        return 1.0 if below >= above else -1.0

    return side


__all__ = ["MAX_RADIUS", "MAX_SWEEP_DEG", "Arc", "contour_side", "counts", "feed_length",
           "fit_arcs", "fit_polyline", "gcode_words", "plain_gcode"]
