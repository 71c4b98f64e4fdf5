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

Biarcs: after the single arcs, every run of three or more consecutive pieces (arcs or lines)
over a smooth stretch of the polyline (no turn above BIARC_KINK_DEG between its chords) is
tried as one biarc, two arcs tangent at a joint that need not be a vertex: the polyline's
tangents at the run's ends (of the circles through each end and its neighbours, turned onto
the end chord where they point below it) and the joint of the equal-distance construction
(Bolton; Meek & Walton).  It is accepted under the single arc's tests (each arc on the free
side by [0, ``tolerance``], measured on the part of the polyline it spans, and the same
limits), so it only replaces three or more moves by two.

Helices: a stretch of feeds in no coordinate plane (X, Y and Z all changing, e.g. a helical
entry written as short feeds, or a descending spiral) is fitted by helical G17 arcs: XY on a
circle through the run's end points, Z linear in the angle (the end Z is the run's).  The
helix must lie within ``tolerance`` of every chord of the polyline in 3-D (bounded by its
sagitta over the chord plus the larger end-vertex error) and the vertices must lie on it: in
3-D within ``tolerance`` / 10 without ``side17`` (the polyline was sampled from a helix, so
nothing is cut that it does not cut); with ``side17``, the XY projection is fitted one-sidedly
like a contour's and each vertex's Z lies within ``tolerance`` / 10 of the helix.  A helical
arc spans at least HELIX_MIN_POINTS vertices, so that the fit is overdetermined.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from typing import NamedTuple, Union

import numpy as np

from ..errors import ParameterError
from ..program.gcode import PLANE_AXES
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
#: Vertices of the first window in which :func:`_runs` looks for a run's end.
RUN_WINDOW = 16
#: Arcs clear the polyline by at least this (mm): rounding of the closed forms.
MARGIN = 1e-7
#: Gaps above -ROUNDING (mm) count as on the free side: floating-point rounding.
ROUNDING = 1e-10
#: Bisection steps on the sagitta where a chord's interior bounds it.
BISECTIONS = 16
#: Fewest polyline vertices under one helical arc: with the end points fixed, the circle has
#: one free parameter and Z none, so three or more interior vertices overdetermine it.
HELIX_MIN_POINTS = 5
#: Largest turn (degrees) between successive chords inside a run tried as a biarc.
BIARC_KINK_DEG = 20.0
#: Starts whose shortest runs a sequence starting a run asks for at once (:func:`_greedy`).
FRESH_AHEAD = 16


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
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    # each row gathered from the runs laid end to end; padding repeats the end point
    col = np.minimum(np.arange(width)[None, :], count[:, None] - 1)
    pts = np.concatenate(runs)[first[:, None] + col]
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


def _nanmedian_rows(a: FloatArray) -> FloatArray:
    """``np.nanmedian(a, axis=1)`` of a 2-D array (NaN for a row of NaNs, without a warning),
    by one sort: numpy's own takes a masked-array path on small arrays that cost 0.3 ms a
    call, and the helix fit is called once per greedy round."""
    srt = np.sort(a, axis=1)  # NaNs last
    count = np.count_nonzero(~np.isnan(a), axis=1)
    rows = np.arange(len(a))
    lo = srt[rows, np.maximum((count - 1) // 2, 0)]  # a row of NaNs: index 0, masked below
    hi = srt[rows, count // 2]
    return np.where(count > 0, (lo + hi) / 2.0, np.nan)


def _fit_helices(runs: Sequence[FloatArray], tolerance: float, sided: np.ndarray
                 ) -> list[_Fit | None]:
    """One helical G17 arc per 3-D run (x, y, z; the XY part mirrored so that a ``sided``
    run's free side is left of travel) from its first to its last point; None where none
    fits.  The XY circle passes through the end points: the one-sided G17 arc of
    :func:`_fit_runs` where ``sided``, else the median of the circles through the ends and
    each interior vertex.  Z is linear in the angle.  With e_i the distance from vertex i to
    the helix point at its angle and d_i the chord's angle, the helix lies within
    r (1 - cos(d_i / 2)) + max(e_i, e_i+1) of chord i (its sagitta over its own chord, plus
    the interpolated end errors; Z of a helix is linear along its own chord): that bound must
    be at most ``tolerance`` (mm) and every e_i (every |dz_i| where ``sided``) at most
    ``tolerance`` / 10, so that the vertices lie on the helix."""
    K = len(runs)
    batch = _pad(runs)
    pts, mask, count = batch
    idx = np.arange(K)
    xy = pts[..., :2]
    z = pts[..., 2]
    a = xy[:, 0]
    b = xy[idx, count - 1]
    chord = b - a
    length = np.hypot(chord[:, 0], chord[:, 1])
    ok = length >= MIN_CHORD
    t = chord / np.where(ok, length, 1.0)[:, None]
    n = np.column_stack([-t[:, 1], t[:, 0]])
    c = 0.5 * np.where(ok, length, 1.0)
    mid = 0.5 * (a + b)
    rel = xy - mid[:, None, :]
    u = np.einsum("kld,kd->kl", rel, t)
    v = np.einsum("kld,kd->kl", rel, n)
    cols = np.arange(pts.shape[1])[None, :]
    interior = (cols >= 1) & (cols < (count - 1)[:, None])
    sag = np.where(interior, _circle_sagitta(c[:, None], u, v), np.nan)
    s = _nanmedian_rows(sag)
    s_max = c * math.tan(math.radians(MAX_SWEEP_DEG) / 4.0)
    s_min_radius = MAX_RADIUS - np.sqrt(np.maximum(MAX_RADIUS ** 2 - c * c, 0.0))
    median_ok = (np.abs(s) <= s_max) & (np.abs(s) >= s_min_radius) & (s != 0)
    s_safe = np.where(ok & median_ok, s, 1.0)
    radius = (c * c + s_safe * s_safe) / (2.0 * np.abs(s_safe))
    centre = mid - (np.sign(s_safe) * (radius - np.abs(s_safe)))[:, None] * n
    ok &= median_ok | sided
    rows = np.flatnonzero(sided & ok)
    if len(rows):
        fits = _fit_runs([runs[k][:, :2] for k in rows], tolerance, np.zeros(len(rows), bool))
        for k, fit in zip(rows, fits):
            if fit is None or fit.line:
                ok[k] = False
            else:
                centre[k], radius[k] = fit.centre, fit.radius
    ok &= (radius >= MIN_RADIUS) & (radius <= MAX_RADIUS)
    w = xy - centre[:, None, :]
    theta = np.arctan2(w[..., 1], w[..., 0])
    pair = mask[:, 1:]
    step = np.where(pair, (np.diff(theta, axis=1) + math.pi) % (2 * math.pi) - math.pi, 0.0)
    sweep = step.sum(axis=1)
    ok &= np.all((step * np.sign(sweep)[:, None] > 0) | ~pair, axis=1)
    ok &= (np.abs(sweep) <= math.radians(MAX_SWEEP_DEG)) & (sweep != 0)
    angle = np.concatenate([np.zeros((K, 1)), np.cumsum(step, axis=1)], axis=1)
    z_a = z[:, 0]
    z_b = z[idx, count - 1]
    z_helix = z_a[:, None] + ((z_b - z_a) / np.where(sweep != 0, sweep, 1.0))[:, None] * angle
    dz = np.where(mask, np.abs(z - z_helix), 0.0)
    err = np.where(mask, np.hypot(np.hypot(w[..., 0], w[..., 1]) - radius[:, None], dz), 0.0)
    bound = radius[:, None] * (1.0 - np.cos(0.5 * step)) + np.maximum(err[:, 1:], err[:, :-1])
    ok &= np.all((bound <= tolerance) | ~pair, axis=1)
    ok &= np.where(sided, dz.max(axis=1), err.max(axis=1)) <= 0.1 * tolerance
    return [_Fit(False, centre[k], float(radius[k])) if ok[k] else None for k in range(K)]


class _Biarc(NamedTuple):
    """Two tangent arcs meeting at ``joint`` (2,): centres (2, 2), radii (2,) (2-D frame)."""

    joint: FloatArray
    centres: FloatArray
    radii: FloatArray


def _tangents(pts: FloatArray) -> FloatArray:
    """Unit tangents at the vertices of a 2-D polyline: at an interior vertex that of the
    circle through it and its neighbours, (|b| a + |a| b) / norm for the unit chords a, b
    before and after it and their lengths; at the ends the neighbour's mirrored in the end
    chord.  NaN at zero-length chords."""
    d = np.diff(pts, axis=0)
    length = np.hypot(d[:, 0], d[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = d / length[:, None]
        if len(pts) < 3:
            return np.vstack([unit[0], unit[0]])
        inner = unit[:-1] * length[1:, None] + unit[1:] * length[:-1, None]
        inner /= np.hypot(inner[:, 0], inner[:, 1])[:, None]
        first = 2.0 * (unit[0] @ inner[0]) * unit[0] - inner[0]
        last = 2.0 * (unit[-1] @ inner[-1]) * unit[-1] - inner[-1]
    return np.vstack([first, inner, last])


def _unit(d: FloatArray) -> FloatArray:
    length = np.hypot(d[..., 0], d[..., 1])[..., None]
    return d / np.where(length > 0, length, 1.0)


def _cross(p: FloatArray, q: FloatArray) -> FloatArray:
    return p[..., 0] * q[..., 1] - p[..., 1] * q[..., 0]


def _biarc_geometry(a: FloatArray, b: FloatArray, d0: FloatArray, d1: FloatArray,
                    ta: FloatArray, tb: FloatArray) -> tuple:
    """Equal-distance biarcs from ``a`` (tangent ``ta``) to ``b`` (tangent ``tb``), all (K, 2),
    ``d0`` and ``d1`` the first and last chords: (ok, joint (K, 2), centres (K, 2, 2), radii
    (K, 2)), ok False where degenerate or out of the module's limits.  The end tangents are
    first turned onto the end chords where they point below them (an arc leaving A below its
    first chord, or reaching B from below its last one, cannot be one-sided).  With
    v = B - A, t = ta + tb and tangent lengths d1 = d2 = d, |v - d t| = 2 d gives
    2 (1 - ta.tb) d^2 + 2 (v.t) d - v.v = 0, d = v.v / (v.t + sqrt((v.t)^2 + 2 (1 - ta.tb) v.v));
    the joint is the middle of A + d ta and B - d tb (Bolton 1975, "Biarc curves", CAD 7;
    Meek & Walton 1992, "Approximating smooth planar curves by arc splines", sec. 2)."""
    ok = np.all(np.isfinite(ta), axis=1) & np.all(np.isfinite(tb), axis=1)
    ta = np.where((_cross(d0, ta) < 0.0)[:, None], _unit(d0), ta)
    tb = np.where((_cross(d1, tb) > 0.0)[:, None], _unit(d1), tb)
    v = b - a
    dot = np.einsum("kd,kd->k", ta, tb)
    vt = np.einsum("kd,kd->k", v, ta + tb)
    vv = np.einsum("kd,kd->k", v, v)
    den = vt + np.sqrt(np.maximum(vt * vt + 2.0 * (1.0 - dot) * vv, 0.0))
    ok &= den > 0.0
    d = vv / np.where(ok, den, 1.0)
    joint = 0.5 * (a + d[:, None] * ta + b - d[:, None] * tb)
    centres = np.empty((len(a), 2, 2))
    radii = np.empty((len(a), 2))
    half = math.radians(MAX_SWEEP_DEG) / 2.0
    for k, (p, tang, sense) in enumerate(((a, ta, 1.0), (b, tb, -1.0))):
        w = joint - p
        ww = np.einsum("kd,kd->k", w, w)
        normal = np.column_stack([-tang[:, 1], tang[:, 0]])
        den = 2.0 * np.einsum("kd,kd->k", normal, w)
        ok &= (ww >= MIN_CHORD * MIN_CHORD) & (np.abs(den) * MAX_RADIUS >= ww)
        lam = ww / np.where(ok, den, 1.0)
        centres[:, k] = p + lam[:, None] * normal
        radii[:, k] = np.abs(lam)
        along = np.einsum("kd,kd->k", tang, w)
        # forward from A, backward from B; the tangent-chord angle is half the sweep
        ok &= (sense * along > 0.0) & (np.arctan2(np.abs(_cross(tang, w)), np.abs(along)) <= half)
    ok &= radii.min(axis=1) >= MIN_RADIUS
    return ok, joint, centres, radii


def _fit_biarcs(runs: Sequence[FloatArray], ta: FloatArray, tb: FloatArray, tolerance: float,
                vertical: np.ndarray) -> list[_Biarc | None]:
    """An equal-distance biarc per 2-D run (:func:`_biarc_geometry`, end tangents ``ta``,
    ``tb`` (K, 2)), accepted under the single arc's tests: each arc on the free (left) side of
    the part of the polyline it spans by [0, ``tolerance``] (mm), measured vertically where
    ``vertical`` (the arc a graph over the horizontal axis, no vertical tangent inside) and
    along the normal of the arc's own chord otherwise.  The run must be a graph over each
    arc's frame; it is cut where its abscissa reaches the joint's, and the gap at the cut is
    checked with the others (:func:`_gaps`)."""
    K = len(runs)
    pts, mask, count = _pad(runs)
    idx = np.arange(K)
    a = pts[:, 0]
    b = pts[idx, count - 1]
    ok, joint, centres, radii = _biarc_geometry(a, b, pts[:, 1] - a,
                                                b - pts[idx, count - 2], ta, tb)
    pair = mask[:, 1:]
    width = pts.shape[1]
    cols = np.arange(width + 1)[None, :]
    good = ok.copy()
    with np.errstate(invalid="ignore", divide="ignore"):
        for arc, (p, q) in enumerate(((a, joint), (joint, b))):
            t = np.where(vertical[:, None], np.array([1.0, 0.0]), _unit(q - p))
            n = np.column_stack([-t[:, 1], t[:, 0]])
            u = np.einsum("kld,kd->kl", pts, t)
            uj = np.einsum("kd,kd->k", joint, t)
            good &= np.all((np.diff(u, axis=1) > 0) | ~pair, axis=1)
            good &= (u[:, 0] < uj) & (uj < u[idx, count - 1])
            # vertices before the cut: u < uj (arc 0) or u <= uj (arc 1); padding has u_B > uj
            m = np.count_nonzero(((u < uj[:, None]) if arc == 0 else (u <= uj[:, None])) & mask,
                                 axis=1)
            m = np.clip(m, 1, count - 1)
            p0, p1 = pts[idx, m - 1], pts[idx, m]
            u0, u1 = u[idx, m - 1], u[idx, m]
            f = (uj - u0) / np.where(u1 > u0, u1 - u0, 1.0)
            cut = p0 + f[:, None] * (p1 - p0)
            if arc == 0:  # A, vertices before the cut, the cut (repeated as padding)
                take = np.minimum(cols, (m - 1)[:, None])
                sub = np.where((cols < m[:, None])[..., None],
                               np.take_along_axis(pts, take[..., None], axis=1), cut[:, None])
                sub_count = m + 1
            else:  # the cut, vertices after it, B (repeated as padding)
                take = np.clip(m[:, None] + cols - 1, 0, (count - 1)[:, None])
                sub = np.where((cols == 0)[..., None], cut[:, None],
                               np.take_along_axis(pts, take[..., None], axis=1))
                sub_count = count - m + 1
            sub_mask = cols < sub_count[:, None]
            centre = centres[:, arc]
            upper = np.einsum("kd,kd->k", 0.5 * (p + q) - centre, n) > 0
            wa, wb = p[:, 1] - centre[:, 1], q[:, 1] - centre[:, 1]
            halves = ((wa > 0) == upper) & ((wb > 0) == upper) \
                & (np.minimum(np.abs(wa), np.abs(wb)) > 1e-12)
            good &= ~vertical | halves
            lo, hi = _gaps(_Batch(sub, sub_mask, sub_count), centre, radii[:, arc], upper, t, n)
            gap = np.einsum("kd,kd->k", joint - cut, n)
            good &= (lo >= -ROUNDING) & (hi <= tolerance) & (gap >= -ROUNDING) & (gap <= tolerance)
    return [_Biarc(joint[k], centres[k], radii[k]) if good[k] else None for k in range(K)]


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
    fit = _fit_runs if fitter is None else fitter

    def evaluate(jobs: list[tuple[int, int, int]]) -> list:
        return fit([polylines[p][s:e + 1] for p, s, e in jobs], tolerance,
                   np.array([flags[p] for p, _, _ in jobs], bool))

    return _greedy([len(q) for q in polylines], evaluate, first)


def _with_biarcs(polylines: Sequence[FloatArray], fitted: list[list[tuple]], tolerance: float,
                 vertical: Sequence[bool]) -> list[list[tuple]]:
    """The pieces of :func:`_fit_polylines` with every run of three or more consecutive pieces
    that one biarc fits (:func:`_fit_biarcs`) replaced by it (two moves for three or more), the
    runs chosen greedily (:func:`_greedy` over the pieces' end vertices).  A run is tried only
    where the polyline is smooth: no turn above BIARC_KINK_DEG at its interior vertices; the
    biarc's end tangents are the polyline's (:func:`_tangents`)."""
    bounds = [[f[0][0]] + [piece[1] for piece in f] for f in fitted]
    tangents = [_tangents(q) for q in polylines]
    kinks = []
    for q in polylines:
        d = np.diff(q, axis=0)
        length = np.hypot(d[:, 0], d[:, 1])
        cos = np.einsum("ij,ij->i", d[:-1], d[1:])
        kink = ~(cos >= math.cos(math.radians(BIARC_KINK_DEG)) * length[:-1] * length[1:])
        kink |= (length[:-1] == 0) | (length[1:] == 0)
        kinks.append(np.concatenate([[0, 0], np.cumsum(kink)]))  # kinks at vertices < index

    def evaluate(jobs: list[tuple[int, int, int]]) -> list:
        out: list = [None] * len(jobs)
        rows, runs, ends = [], [], []
        for r, (p, s, e) in enumerate(jobs):
            i, j = bounds[p][s], bounds[p][e]
            if kinks[p][j] - kinks[p][i + 1] > 0:
                continue
            rows.append(r)
            runs.append(polylines[p][i:j + 1])
            ends.append((tangents[p][i], tangents[p][j]))
        if rows:
            flags = np.array([vertical[jobs[r][0]] for r in rows], bool)
            ta, tb = (np.array(col) for col in zip(*ends))
            for r, fit in zip(rows, _fit_biarcs(runs, ta, tb, tolerance, flags)):
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


def _arc(start: FloatArray, end: FloatArray, centre: FloatArray, radius: float,
         plane: int) -> Arc:
    a1, a2, _ = PLANE_AXES[plane]
    s = start - centre
    e = end - centre
    cross = s[a1] * e[a2] - s[a2] * e[a1]
    kind = "ccw" if cross > 0 else "cw"
    return Arc(kind, float(end[0]), float(end[1]), float(end[2]), float(centre[0]),
               float(centre[1]), float(centre[2]), float(radius), plane)


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


def counts(moves: Sequence[AnyMove]) -> dict:
    """Numbers of rapid, line and arc moves (for reports)."""
    arcs = sum(isinstance(m, Arc) for m in moves)
    rapids = sum(m.kind == "rapid" for m in moves)
    return {"moves": len(moves), "arcs": arcs, "lines": len(moves) - arcs - rapids,
            "rapids": rapids}


def feed_length(moves: Sequence[AnyMove]) -> float:
    """Length (mm) of the feed moves (lines and arcs) of ``moves``, each from the end of the
    move before it (a feed with none before it has no length): the cutting length a program
    made of them has, as :mod:`BSplineCAM.core.program.gcode` measures its text.  An arc sweeps from
    its start to its end round its centre in its plane, the way its kind turns seen from the
    plane's normal axis (an end on its start: no sweep), and a helix adds its travel along
    that axis.  Lines are summed at once."""
    n = len(moves)
    if n < 2:
        return 0.0
    xyz = np.array([(m.x, m.y, m.z) for m in moves], dtype=float)
    line = np.array([m.kind == "feed" for m in moves[1:]], dtype=bool)
    seg = np.diff(xyz, axis=0)
    total = float(np.sqrt((seg[line] ** 2).sum(axis=1)).sum())
    for i in range(1, n):
        arc = moves[i]
        if not isinstance(arc, Arc):
            continue
        a1, a2, normal = PLANE_AXES[arc.plane]
        centre = (arc.cx, arc.cy, arc.cz)
        start, end = xyz[i - 1], xyz[i]
        t0 = math.atan2(start[a2] - centre[a2], start[a1] - centre[a1])
        t1 = math.atan2(end[a2] - centre[a2], end[a1] - centre[a1])
        sweep = (t1 - t0 if arc.kind == "ccw" else t0 - t1) % (2.0 * math.pi)
        total += math.hypot(arc.radius * sweep, end[normal] - start[normal])
    return total


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


__all__ = ["MAX_RADIUS", "MAX_SWEEP_DEG", "Arc", "contour_side", "counts", "feed_length",
           "fit_arcs", "fit_polyline", "gcode_words", "plain_gcode"]
