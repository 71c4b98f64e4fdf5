# SPDX-License-Identifier: LGPL-2.1-or-later
"""One-sided fits of batches of runs: circular arcs, biarcs and helical arcs.

Each fitter takes runs (2-D, or 3-D for helices) padded to one length (or a batch already
padded, :func:`_gather`) and fits each from its first to its last point at once in numpy,
returning a fit or None per run; :mod:`.arcs` grows the runs and turns the fits into moves.
Under the numba engine the per-run work of the single arc (after the batch's chord frames)
and of the biarcs' tests (after their geometry) runs in :mod:`..kernels.arcs_kernels`, the
same arithmetic in the same order.

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
Arcs are kept numerically sane: radius in [MIN_RADIUS, MAX_RADIUS] mm, sweep at most
MAX_SWEEP_DEG, chord at least MIN_CHORD mm; a run whose straight chord fits one-sidedly
becomes one line.

Biarcs (:func:`_fit_biarcs`): two arcs tangent at a joint that need not be a vertex, given
the polyline's tangents at the run's ends (turned onto the end chord where they point below
it) and the joint of the equal-distance construction (Bolton; Meek & Walton).  A biarc is
accepted under the single arc's tests (each arc on the free side by [0, ``tolerance``],
measured on the part of the polyline it spans, and the same limits).

Helices (:func:`_fit_helices`): a 3-D run is fitted by a helical G17 arc: XY on a circle
through the run's end points, Z linear in the angle (the end Z is the run's).  The helix must
lie within ``tolerance`` of every chord of the polyline in 3-D (bounded by its sagitta over
the chord plus the larger end-vertex error) and the vertices must lie on it: in 3-D within
``tolerance`` / 10 for an unsided run; for a sided one, the XY projection is fitted
one-sidedly like a contour's and each vertex's Z lies within ``tolerance`` / 10 of the helix.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from .. import kernels
from ..kernels import arcs_kernels
from ..typing import FloatArray

#: Largest arc radius (mm): flatter arcs are near-straight and stay lines.
MAX_RADIUS = 1000.0
#: Smallest arc radius (mm).
MIN_RADIUS = 0.01
#: Largest sweep of one arc (degrees); below 180 so that the R form (G2/G3 R) is unambiguous
#: and well conditioned.
MAX_SWEEP_DEG = 150.0
#: Shortest arc chord (mm): posts round coordinates to 0.001 mm.
MIN_CHORD = 0.02
#: Arcs clear the polyline by at least this (mm): rounding of the closed forms.
MARGIN = 1e-7
#: Gaps above -ROUNDING (mm) count as on the free side: floating-point rounding.
ROUNDING = 1e-10
#: Bisection steps on the sagitta where a chord's interior bounds it.
BISECTIONS = 16


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


def _pad(runs: Sequence[FloatArray] | _Batch) -> _Batch:
    """The runs padded to one length (a batch is kept as it is)."""
    if isinstance(runs, _Batch):
        return runs
    count = np.array([len(r) for r in runs])
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    return _gather(np.concatenate(runs), first, count)


def _gather(flat: FloatArray, first: np.ndarray, count: np.ndarray) -> _Batch:
    """The runs flat[first[k]:first[k] + count[k]] padded to one length: each row gathered
    from ``flat``, the padding repeating the run's end point."""
    width = int(count.max())
    col = np.minimum(np.arange(width)[None, :], count[:, None] - 1)
    pts = flat[first[:, None] + col]
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


def _fit_runs(runs: Sequence[FloatArray] | _Batch, tolerance: float, vertical: np.ndarray
              ) -> list[_Fit | None]:
    """One arc (or line) per run from its first to its last point, lying left of travel by
    [0, tolerance] (2-D points, or a padded batch of them); None where none exists.  Where ``vertical``, the plane is
    vertical with the second coordinate up and the gaps are measured vertically."""
    batch = _pad(runs)
    pts, mask, count = batch
    K = len(count)
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
    lift = np.where(vertical, n[:, 1], 1.0)[:, None] * tolerance
    # the arc leaves A above the first chord and reaches B above the last one: its tangent
    # makes the angle 2 atan(s / c) with the chord at both ends
    first = np.arctan2(v[:, 1] - v[:, 0], u[:, 1] - u[:, 0])
    last = np.arctan2(v[idx, count - 1] - v[idx, count - 2], u[idx, count - 1] - u[idx, count - 2])
    s_end = np.maximum(c * np.tan(first / 2.0), -c * np.tan(last / 2.0))
    s_max = c * math.tan(math.radians(MAX_SWEEP_DEG) / 4.0)
    s_min_radius = MAX_RADIUS - np.sqrt(np.maximum(MAX_RADIUS ** 2 - c * c, 0.0))
    if kernels.use_numba():
        line = np.zeros(K, bool)
        good = np.zeros(K, bool)
        centre = np.zeros((K, 2))
        radius = np.full(K, np.nan)
        try:
            arcs_kernels.fit_runs(pts, count, u, v, ok, c, s_end, s_max, s_min_radius,
                                  lift[:, 0], vertical, a, b, chord, mid, t, n,
                                  float(tolerance), line, good, centre, radius)
            return _fits(line, good, mid, centre, radius)
        except kernels.KernelUnavailable:
            pass  # numba failed: the numpy engine from now on
    cc = np.where(ok, c, 1.0)[:, None]
    s_lo = np.where(interior, _circle_sagitta(cc, u, v), -np.inf).max(axis=1)
    s_hi = np.where(interior, _circle_sagitta(cc, u, v + lift), np.inf).min(axis=1)
    s_lo = np.maximum(s_lo, s_end)
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
    return _fits(line, good, mid, centre, radius)


def _fits(line: np.ndarray, good: np.ndarray, mid: FloatArray, centre: FloatArray,
          radius: FloatArray) -> list[_Fit | None]:
    """Per run the line (through ``mid``), the arc or None."""
    out: list[_Fit | None] = []
    for k in range(len(line)):
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


def _fit_biarcs(runs: Sequence[FloatArray] | _Batch, ta: FloatArray, tb: FloatArray,
                tolerance: float, vertical: np.ndarray) -> list[_Biarc | None]:
    """An equal-distance biarc per 2-D run (:func:`_biarc_geometry`, end tangents ``ta``,
    ``tb`` (K, 2)), accepted under the single arc's tests: each arc on the free (left) side of
    the part of the polyline it spans by [0, ``tolerance``] (mm), measured vertically where
    ``vertical`` (the arc a graph over the horizontal axis, no vertical tangent inside) and
    along the normal of the arc's own chord otherwise.  The run must be a graph over each
    arc's frame; it is cut where its abscissa reaches the joint's, and the gap at the cut is
    checked with the others (:func:`_gaps`)."""
    pts, mask, count = _pad(runs)
    K = len(count)
    idx = np.arange(K)
    a = pts[:, 0]
    b = pts[idx, count - 1]
    ok, joint, centres, radii = _biarc_geometry(a, b, pts[:, 1] - a,
                                                b - pts[idx, count - 2], ta, tb)
    good = ok.copy()
    if kernels.use_numba():
        try:
            arcs_kernels.biarc_checks(pts, count, vertical, joint, centres, radii, a, b,
                                      float(tolerance), good)
            return [_Biarc(joint[k], centres[k], radii[k]) if good[k] else None
                    for k in range(K)]
        except kernels.KernelUnavailable:
            good = ok.copy()  # numba failed: the numpy engine from now on
    pair = mask[:, 1:]
    width = pts.shape[1]
    cols = np.arange(width + 1)[None, :]
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
