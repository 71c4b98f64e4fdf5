# SPDX-License-Identifier: LGPL-2.1-or-later
"""One-sided arc fitting of finishing passes: G2/G3 moves that never dip below the polyline.

A pass is a polyline of tool-tip (cutter-location) points whose chords already clear the
exact cutter-location curve (:mod:`chords`).  :func:`fit_arcs` replaces runs of its feed moves
by circular arcs in the coordinate plane that holds the run: G18 (XZ) where Y is constant (a
raster pass along X), G19 (YZ) where X is constant (along Y), and G17 (XY) where Z is constant
(a waterline contour) when the caller says which side of the contour is free (``side17``).
Raster passes at other angles lie in no coordinate plane and stay lines.

Each arc interpolates two vertices of the polyline and lies on its free side ("above": higher
Z in a vertical pass plane; outwards for a contour) by at least 0 and at most ``tolerance``
(mm) everywhere along the run, measured vertically (G18/G19) or along the chord's normal (G17,
which bounds the distance).  Circles through the run's end points A, B form a one-parameter
family, ordered by their signed sagitta s (|s| < |AB| / 2 for arcs under 180 degrees); the
offset of the arc from the chord grows monotonically with s at every point between A and B, so
each polyline vertex P gives a bound on s from the circle through A, B and P (and P lifted by
the tolerance), the end chords bound it through the arc's end tangents (at angle
2 atan(s / c) to the chord AB of half length c), and the lowest admissible s is taken.  Between
vertices, the arc minus a chord is concave or convex, so its extremes lie at the vertices or
where the arc's tangent is parallel to the chord (closed form); those points are checked
exactly, and where a chord's interior still pokes above the arc, s is raised by bisection.
Runs grow greedily from each start (galloping, then bisection on the end vertex), those of all
passes in lockstep so that each round is one vectorised evaluation; a run that admits no arc
is cut by a straight move.  Consecutive arcs meet at shared vertices (an arc
spline through the polyline's vertices; tangent continuity is not imposed).  Arcs are kept
numerically sane: radius in [MIN_RADIUS, MAX_RADIUS] mm, sweep at most MAX_SWEEP_DEG, chord at
least MIN_CHORD mm; a run whose straight chord fits one-sidedly becomes one line.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import NamedTuple, Union

import numpy as np

from ..errors import ParameterError
from ..typing import FloatArray
from .common import Move, check_positive

#: Largest arc radius (mm): flatter arcs are near-straight and stay lines.
MAX_RADIUS = 1000.0
#: Smallest arc radius (mm).
MIN_RADIUS = 0.01
#: Largest sweep of one arc (degrees); below 180 so that the R form (G2/G3 R) is unambiguous
#: and well conditioned.
MAX_SWEEP_DEG = 150.0
#: Shortest arc chord (mm): posts round coordinates to 0.001 mm.
MIN_CHORD = 0.02
#: Coordinates equal within this (mm) define the plane of a run.
PLANE_EPS = 1e-9
#: Arcs clear the polyline by at least this (mm): rounding of the closed forms.
MARGIN = 1e-7
#: Gaps above -ROUNDING (mm) count as on the free side: floating-point rounding.
ROUNDING = 1e-10
#: Bisection steps on the sagitta where a chord's interior bounds it.
BISECTIONS = 16

#: (first axis, second axis, normal axis) of each plane, as in :data:`BSplineCAM.core.gcode`.
PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


class Arc(NamedTuple):
    """A circular feed move: ``kind`` 'cw' (G2) or 'ccw' (G3) seen from the plane's normal
    axis (+Z for G17, +Y for G18, +X for G19); x, y, z the end point, cx, cy, cz the centre
    (absolute, mm), ``radius`` (mm), ``plane`` 17, 18 or 19.  In G17 z may change (helix)."""

    kind: str
    x: float
    y: float
    z: float
    cx: float
    cy: float
    cz: float
    radius: float
    plane: int


AnyMove = Union[Move, Arc]
#: side17(points (n, 3)) -> +1 if the free side of the contour is left of travel, -1 right.
SideFn = Callable[[FloatArray], float]


class _Fit(NamedTuple):
    """Result of fitting one run in 2-D: centre (2,), radius, sagitta sign, 'line' flag."""

    line: bool
    centre: FloatArray
    radius: float


class _Batch(NamedTuple):
    """Candidate runs padded to one length: points (K, L, 2), ``mask`` of real points."""

    pts: FloatArray
    mask: np.ndarray
    count: np.ndarray


def _pad(runs: Sequence[FloatArray]) -> _Batch:
    count = np.array([len(r) for r in runs])
    width = int(count.max())
    pts = np.zeros((len(runs), width, 2))
    for k, r in enumerate(runs):
        pts[k, :len(r)] = r
        pts[k, len(r):] = r[-1]  # padding repeats the end point
    mask = np.arange(width)[None, :] < count[:, None]
    return _Batch(pts, mask, count)


def _gaps(batch: _Batch, centre: FloatArray, radius: FloatArray, upper: np.ndarray,
          t: FloatArray, n: FloatArray) -> tuple[FloatArray, FloatArray]:
    """(min, max) gap, arc minus polyline along ``n`` (K, 2), of each run under its arc seen as
    a graph over ``t``: v_arc(u) = cv +- sqrt(r^2 - (u - cu)^2) (+ on the ``upper`` branch).
    Interior vertices and, per chord, the point where the arc's tangent is parallel to it
    (the arc minus a line is convex or concave, so the extremes lie there).  NaN where the
    run is no graph over ``t`` inside the circle's span."""
    u = np.einsum("kld,kd->kl", batch.pts, t)
    v = np.einsum("kld,kd->kl", batch.pts, n)
    cu = np.einsum("kd,kd->k", centre, t)[:, None]
    cv = np.einsum("kd,kd->k", centre, n)[:, None]
    r = radius[:, None]
    b = np.where(upper, 1.0, -1.0)[:, None]
    pair = batch.mask[:, 1:]
    du = np.diff(u, axis=1)
    mono = np.all((du > 0) | ~pair, axis=1) | np.all((du < 0) | ~pair, axis=1)
    w = u - cu
    span = np.all((np.abs(w) <= r * (1.0 + 1e-12)) | ~batch.mask, axis=1)
    gaps = cv + b * np.sqrt(np.maximum(r * r - w * w, 0.0)) - v
    last = (batch.count - 1)[:, None]
    cols = np.arange(u.shape[1])[None, :]
    interior = (cols >= 1) & (cols < last)
    lo = np.where(interior, gaps, np.inf).min(axis=1)
    hi = np.where(interior, gaps, -np.inf).max(axis=1)
    safe_du = np.where(pair & (du != 0), du, 1.0)
    slope = np.diff(v, axis=1) / safe_du
    wc = -b * slope * r / np.sqrt(1.0 + slope * slope)
    uc = cu + wc
    inside = ((uc - u[:, :-1]) * (uc - u[:, 1:]) < 0) & pair
    g = cv + b * np.sqrt(np.maximum(r * r - wc * wc, 0.0)) - (v[:, :-1] + slope * (uc - u[:, :-1]))
    lo = np.minimum(lo, np.where(inside, g, np.inf).min(axis=1))
    hi = np.maximum(hi, np.where(inside, g, -np.inf).max(axis=1))
    bad = ~(mono & span)
    lo[bad] = np.nan
    hi[bad] = np.nan
    return lo, hi


def _circle_sagitta(c: FloatArray, u: FloatArray, v: FloatArray) -> FloatArray:
    """Signed sagitta of the circle through (-c, 0), (c, 0) and (u, v) (chord frame)."""
    sign = np.where(v < 0, -1.0, 1.0)
    v = np.where(np.abs(v) < 1e-300, sign * 1e-300, v)
    q = (u * u + v * v - c * c) / (2.0 * v)  # the centre's offset along the chord's normal
    r = np.hypot(c, q)
    # q + sign r, written without cancellation: (q + sign r)(q - sign r) = -c^2
    same = q * sign >= 0
    return np.where(same, q + sign * r, -c * c / np.where(same, 1.0, q - sign * r))


def _fit_runs(runs: Sequence[FloatArray], tolerance: float, vertical: np.ndarray
              ) -> list[_Fit | None]:
    """One arc (or line) per run from its first to its last point, lying left of travel by
    [0, tolerance] (2-D points); None where none exists.  Where ``vertical``, the plane is
    vertical with the second coordinate up and the gaps are measured vertically."""
    K = len(runs)
    batch = _pad(runs)
    pts, mask, count = batch
    idx = np.arange(K)
    a = pts[:, 0]
    b = pts[idx, count - 1]
    chord = b - a
    length = np.hypot(chord[:, 0], chord[:, 1])
    ok = length >= MIN_CHORD
    t = chord / np.where(ok, length, 1.0)[:, None]
    n = np.column_stack([-t[:, 1], t[:, 0]])
    ok &= ~vertical | (n[:, 1] > 1e-9)
    c = 0.5 * length
    mid = 0.5 * (a + b)
    rel = pts - mid[:, None, :]
    u = np.einsum("kld,kd->kl", rel, t)
    v = np.einsum("kld,kd->kl", rel, n)
    cols = np.arange(pts.shape[1])[None, :]
    interior = (cols >= 1) & (cols < (count - 1)[:, None])
    ok &= np.all((np.diff(u, axis=1) > 0) | ~mask[:, 1:], axis=1)
    cc = np.where(ok, c, 1.0)[:, None]
    s_lo = np.where(interior, _circle_sagitta(cc, u, v), -np.inf).max(axis=1)
    lift = np.where(vertical, n[:, 1], 1.0)[:, None] * tolerance
    s_hi = np.where(interior, _circle_sagitta(cc, u, v + lift), np.inf).min(axis=1)
    # the arc leaves A above the first chord and reaches B above the last one: its tangent
    # makes the angle 2 atan(s / c) with the chord at both ends
    first = np.arctan2(v[:, 1] - v[:, 0], u[:, 1] - u[:, 0])
    last = np.arctan2(v[idx, count - 1] - v[idx, count - 2], u[idx, count - 1] - u[idx, count - 2])
    s_lo = np.maximum(s_lo, np.maximum(c * np.tan(first / 2.0), -c * np.tan(last / 2.0)))
    s_max = c * math.tan(math.radians(MAX_SWEEP_DEG) / 4.0)
    s_min_radius = MAX_RADIUS - np.sqrt(np.maximum(MAX_RADIUS ** 2 - c * c, 0.0))
    # the straight chord: every vertex on or below it, within the tolerance
    gap_line = np.where(vertical[:, None],
                        a[:, None, 1] + (pts[..., 0] - a[:, None, 0])
                        * (chord[:, 1] / np.where(chord[:, 0] > 0, chord[:, 0], 1.0))[:, None]
                        - pts[..., 1],
                        -v)
    line = ok & (s_lo <= 0.0) & (s_hi >= 0.0) & np.all(
        ((gap_line >= -1e-12) & (gap_line <= tolerance)) | ~mask, axis=1)
    line &= ~vertical | (chord[:, 0] > 0)

    def arc_of(sag: FloatArray, rows: np.ndarray):
        """Centre, radius and chord-frame gaps of the arcs of sagitta ``sag`` on ``rows``."""
        sub = _Batch(pts[rows], mask[rows], count[rows])
        cs, nn = c[rows], n[rows]
        good = ((sag <= s_hi[rows]) & (np.abs(sag) <= s_max[rows])
                & (np.abs(sag) >= s_min_radius[rows]))
        sag_safe = np.where(good & (sag != 0), sag, 1.0)
        r = (cs * cs + sag_safe * sag_safe) / (2.0 * np.abs(sag_safe))
        good &= r >= MIN_RADIUS
        o = mid[rows] - (np.sign(sag_safe) * (r - np.abs(sag_safe)))[:, None] * nn
        lo, hi = _gaps(sub, o, r, sag_safe > 0, t[rows], nn)
        good &= np.isfinite(lo)
        return o, r, lo, hi, good

    s = s_lo + MARGIN
    s = np.where((s > 0) & (s < s_min_radius), s_min_radius, s)
    rows = np.flatnonzero(ok & ~line)
    centre = np.zeros((K, 2))
    radius = np.full(K, np.nan)
    lo = np.full(K, np.nan)
    hi = np.full(K, np.nan)
    good = np.zeros(K, bool)
    if len(rows):
        o, r, lo_r, hi_r, g = arc_of(s[rows], rows)
        centre[rows], radius[rows], lo[rows], hi[rows], good[rows] = o, r, lo_r, hi_r, g
        # a chord's interior still pokes above the arc: bisect on the sagitta (the gaps grow
        # with it) up to the upper bound
        need = rows[g & (lo_r < -ROUNDING)]
        if len(need):
            top_s = np.minimum(s_hi[need], s_max[need])
            o, r, lo_t, hi_t, g_t = arc_of(top_s, need)
            fine = g_t & (lo_t >= -ROUNDING)
            good[need[~fine]] = False
            need, lo_s, hi_s = need[fine], s[need[fine]], top_s[fine]
            centre[need], radius[need], lo[need], hi[need] = o[fine], r[fine], lo_t[fine], hi_t[fine]
            for _ in range(BISECTIONS if len(need) else 0):
                m = 0.5 * (lo_s + hi_s)
                o, r, lo_m, hi_m, g_m = arc_of(m, need)
                take = g_m & (lo_m >= 0.5 * MARGIN)
                hi_s = np.where(take, m, hi_s)
                lo_s = np.where(take, lo_s, m)
                sel = need[take]
                centre[sel], radius[sel], lo[sel], hi[sel] = o[take], r[take], lo_m[take], hi_m[take]
    upper = np.einsum("kd,kd->k", mid - centre, n) > 0
    good &= ~(lo < -ROUNDING)
    vert = np.flatnonzero(good & vertical)
    if len(vert):
        # exact check, vertically: the arc as a graph over the horizontal axis, and no
        # vertical tangent inside (both ends on the arc's upper or lower half)
        sub = _Batch(pts[vert], mask[vert], count[vert])
        ex = np.tile([1.0, 0.0], (len(vert), 1))
        ez = np.tile([0.0, 1.0], (len(vert), 1))
        lo_v, hi_v = _gaps(sub, centre[vert], radius[vert], upper[vert], ex, ez)
        wa = a[vert, 1] - centre[vert, 1]
        wb = b[vert, 1] - centre[vert, 1]
        halves = ((wa > 0) == upper[vert]) & ((wb > 0) == upper[vert]) \
            & (np.abs(wa) > 1e-12) & (np.abs(wb) > 1e-12)
        good[vert] = (lo_v >= -ROUNDING) & (hi_v <= tolerance) & halves
    flat = np.flatnonzero(good & ~vertical)
    good[flat] = hi[flat] <= tolerance
    out: list[_Fit | None] = []
    for k in range(K):
        if line[k]:
            out.append(_Fit(True, mid[k], math.inf))
        elif good[k]:
            out.append(_Fit(False, centre[k], float(radius[k])))
        else:
            out.append(None)
    return out


def _fit_polylines(polylines: Sequence[FloatArray], tolerance: float,
                   vertical: Sequence[bool]) -> list[list[tuple]]:
    """Greedy arc splines of 2-D polylines, all advanced in lockstep so that every round is
    one vectorised evaluation: per polyline a list of (start index, end index, _Fit or None),
    None meaning the straight segment (end = start + 1).  From each start the run's end
    gallops (start + 2, + 4, + 8, ...) until a run admits no arc, then bisects."""
    P = len(polylines)
    out: list[list[tuple]] = [[] for _ in range(P)]
    start = [0] * P
    step = [2] * P
    best: list = [None] * P
    lo = [0] * P
    hi: list = [None] * P  # bisection bracket once a run failed

    def commit(p: int) -> None:
        if best[p] is None:
            out[p].append((start[p], start[p] + 1, None))
            start[p] += 1
        else:
            out[p].append((start[p], best[p][0], best[p][1]))
            start[p] = best[p][0]
        step[p], best[p], hi[p] = 2, None, None

    active = list(range(P))
    while active:
        ends = []
        runnable = []
        for p in active:
            n = len(polylines[p])
            while start[p] < n - 1 and start[p] + 2 > n - 1:
                commit(p)  # one segment left: a line
            if start[p] >= n - 1:
                continue
            end = min(start[p] + step[p], n - 1) if hi[p] is None else (lo[p] + hi[p]) // 2
            ends.append(end)
            runnable.append(p)
        if not runnable:
            break
        fits = _fit_runs([polylines[p][start[p]:e + 1] for p, e in zip(runnable, ends)],
                         tolerance, np.array([vertical[p] for p in runnable], bool))
        for p, end, fit in zip(runnable, ends, fits):
            n = len(polylines[p])
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
        active = [p for p in runnable if start[p] < len(polylines[p]) - 1]
    return out


def _runs(points: FloatArray) -> list[tuple[int, int, int | None]]:
    """Split a 3-D polyline into maximal runs lying in one coordinate plane: (start, stop
    inclusive, plane or None).  Y constant -> 18, else X constant -> 19, else Z -> 17."""
    out = []
    n = len(points)
    i = 0
    while i < n - 1:
        same = np.abs(points[i + 1] - points[i]) <= PLANE_EPS
        j = i + 1
        while j + 1 < n:
            nxt = same & (np.abs(points[j + 1] - points[i]) <= PLANE_EPS)
            if not nxt.any():
                break
            same = nxt
            j += 1
        plane = 18 if same[1] else 19 if same[0] else 17 if same[2] else None
        out.append((i, j, plane))
        i = j
    return out


class _Plan(NamedTuple):
    """A 3-D run in a coordinate plane and its 2-D picture for the fitter (free side left)."""

    points: FloatArray
    plane: int
    flat: FloatArray
    vertical: bool
    sense: float


def _plan(pts3: FloatArray, plane: int, side: float) -> _Plan:
    if plane != 17:
        # horizontal axis along the pass, Z up; travel in -x (-y) is mirrored to +x (+y)
        h = 0 if plane == 18 else 1
        sense = 1.0 if pts3[-1, h] >= pts3[0, h] else -1.0
        return _Plan(pts3, plane, np.column_stack([sense * pts3[:, h], pts3[:, 2]]), True,
                     sense)
    return _Plan(pts3, plane, pts3[:, :2] * np.array([1.0, side]), False, side)


def _moves(plan: _Plan, fits: list[tuple]) -> list[AnyMove]:
    """Moves of one planned run from its fitted pieces."""
    pts3 = plan.points
    moves: list[AnyMove] = []
    for i, j, fit in fits:
        end = pts3[j]
        if fit is None or fit.line:
            moves.append(Move("feed", float(end[0]), float(end[1]), float(end[2])))
            continue
        centre3 = pts3[i].copy()
        if plan.vertical:
            centre3[0 if plan.plane == 18 else 1] = plan.sense * fit.centre[0]
            centre3[2] = fit.centre[1]
        else:
            centre3[0], centre3[1] = fit.centre[0], plan.sense * fit.centre[1]
        moves.append(_arc(pts3[i], end, centre3, fit.radius, plan.plane))
    return moves


def fit_polyline(points: Sequence, tolerance: float, plane: int,
                 side: float = 1.0) -> list[AnyMove]:
    """Feed moves (Move 'feed' and :class:`Arc`) from points[0] along a polyline lying in
    ``plane`` (17, 18 or 19; points (n, 3), mm), within ``tolerance`` (mm) on its free side:
    above in G18/G19, left of travel (``side`` +1) or right (-1) in G17."""
    tolerance = check_positive(tolerance, "tolerance", "mm")
    if plane not in PLANE_AXES:
        raise ParameterError(f"plane must be 17, 18 or 19, got {plane!r}")
    pts3 = np.asarray(points, dtype=float)
    if pts3.ndim != 2 or pts3.shape[1] != 3 or len(pts3) < 2:
        raise ParameterError(f"points must be an (n >= 2, 3) array in mm, got {pts3.shape}")
    plan = _plan(pts3, plane, 1.0 if side >= 0 else -1.0)
    return _moves(plan, _fit_polylines([plan.flat], tolerance, [plan.vertical])[0])


def _arc(start: FloatArray, end: FloatArray, centre: FloatArray, radius: float,
         plane: int) -> Arc:
    a1, a2, _ = PLANE_AXES[plane]
    s = start - centre
    e = end - centre
    cross = s[a1] * e[a2] - s[a2] * e[a1]
    kind = "ccw" if cross > 0 else "cw"
    return Arc(kind, float(end[0]), float(end[1]), float(end[2]), float(centre[0]),
               float(centre[1]), float(centre[2]), float(radius), plane)


def fit_arcs(moves: Iterable[Move], tolerance: float, side17: SideFn | None = None
             ) -> list[AnyMove]:
    """Moves with runs of feeds replaced by one-sided arcs within ``tolerance`` (mm).

    Feeds in a vertical coordinate plane (Y or X constant) become G18 / G19 arcs above the
    polyline; feeds at constant Z become G17 arcs on the free side that ``side17`` names (no
    G17 arcs without it); everything else is kept.  Rapids pass through unchanged.  All runs
    are fitted together (:func:`_fit_polylines`).
    """
    tolerance = check_positive(tolerance, "tolerance", "mm")
    moves = list(moves)
    pieces: list = []  # Move, or the index of a plan
    plans: list[_Plan] = []
    k = 0
    position: FloatArray | None = None
    while k < len(moves):
        m = moves[k]
        if m.kind != "feed" or position is None:
            pieces.append(m)
            position = np.array([m.x, m.y, m.z], dtype=float)
            k += 1
            continue
        stop = k
        while stop < len(moves) and moves[stop].kind == "feed":
            stop += 1
        pts = np.vstack([position, [[f.x, f.y, f.z] for f in moves[k:stop]]])
        for i, j, plane in _runs(pts):
            run = pts[i:j + 1]
            if plane is None or j - i < 2 or (plane == 17 and side17 is None):
                pieces.extend(Move("feed", float(x), float(y), float(z)) for x, y, z in run[1:])
                continue
            side = 1.0 if plane != 17 else (1.0 if float(side17(run)) >= 0 else -1.0)
            pieces.append(len(plans))
            plans.append(_plan(run, plane, side))
        position = pts[-1]
        k = stop
    fitted = _fit_polylines([p.flat for p in plans], tolerance, [p.vertical for p in plans])
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


def counts(moves: Sequence[AnyMove]) -> dict:
    """Numbers of rapid, line and arc moves (for reports)."""
    arcs = sum(isinstance(m, Arc) for m in moves)
    rapids = sum(m.kind == "rapid" for m in moves)
    return {"moves": len(moves), "arcs": arcs, "lines": len(moves) - arcs - rapids,
            "rapids": rapids}


def gcode_words(arc: Arc, decimals: int = 4) -> str:
    """The motion words of an arc in R form (``G2 X.. Y.. Z.. R..``): every post keeps R,
    while FreeCAD's linuxcnc, fanuc and mach3_mach4 posts drop K (needed by G18/G19)."""
    word = "G2" if arc.kind == "cw" else "G3"
    return (f"{word} X{arc.x:.{decimals}f} Y{arc.y:.{decimals}f} Z{arc.z:.{decimals}f} "
            f"R{arc.radius:.{decimals}f}")


def plain_gcode(moves: Sequence[AnyMove], feed: float = 1000.0, decimals: int = 4) -> str:
    """A minimal program (G21 G90, G0 / G1 / G2 / G3 with F, the plane word before arcs and
    G17 restored after them, M2)."""
    lines = ["G17 G21 G90"]
    plane = 17
    for m in moves:
        if isinstance(m, Arc):
            if m.plane != plane:
                lines.append(f"G{m.plane}")
                plane = m.plane
            lines.append(f"{gcode_words(m, decimals)} F{feed:g}")
            continue
        if plane != 17:
            lines.append("G17")
            plane = 17
        word = "G0" if m.kind == "rapid" else "G1"
        tail = "" if m.kind == "rapid" else f" F{feed:g}"
        lines.append(f"{word} X{m.x:.{decimals}f} Y{m.y:.{decimals}f} Z{m.z:.{decimals}f}{tail}")
    if plane != 17:
        lines.append("G17")
    lines.append("M2")
    return "\n".join(lines) + "\n"


__all__ = ["MAX_RADIUS", "MAX_SWEEP_DEG", "Arc", "contour_side", "counts", "fit_arcs",
           "fit_polyline", "gcode_words", "plain_gcode"]
