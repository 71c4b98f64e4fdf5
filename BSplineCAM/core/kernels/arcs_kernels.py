# SPDX-License-Identifier: LGPL-2.1-or-later
"""The one-sided arc fit of a batch of runs (:func:`..toolpath.arcs_fit._fit_runs`) run by
run: the same arithmetic as its numpy engine, in the same order, so that the fits agree to
the bit.

* :func:`_fit_runs_loops` takes what the numpy engine computes once per batch (the padded
  runs, their chord frames, the sagitta bounds from the end chords: numpy's ``arctan2`` and
  ``tan`` do not round as the C library's do) and does the rest per run: the sagitta bounds
  from the interior vertices, the straight-line test, the arc at the lowest admissible
  sagitta, the bisection where a chord's interior pokes above it, and the exact gap checks
  (:func:`_gaps_loop`, ``arcs_fit._gaps`` of one run);
* :func:`_biarc_checks_loops` is :func:`..toolpath.arcs_fit._fit_biarcs`'s acceptance of the
  biarcs whose geometry (joint, centres, radii) the numpy engine has built.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper
from .scalars import least, most

#: The limits of :mod:`..toolpath.arcs_fit` (its module imports them from here would make a
#: cycle; the tests check that they agree).
MIN_RADIUS = 0.01
MARGIN = 1e-7
ROUNDING = 1e-10
BISECTIONS = 16


@helper
def _sagitta(c, u, v):
    """``arcs_fit._circle_sagitta`` of one point."""
    sign = -1.0 if v < 0 else 1.0
    if abs(v) < 1e-300:
        v = sign * 1e-300
    q = (u * u + v * v - c * c) / (2.0 * v)
    r = math.hypot(c, q)
    if q * sign >= 0:
        return q + sign * r
    return -c * c / (q - sign * r)


@helper
def _gaps_loop(pts, cnt, cx, cy, radius, upper, t0, t1, n0, n1, u, v):
    """``arcs_fit._gaps`` of one run (points ``pts`` (L, 2) padded, ``cnt`` real ones) under
    the arc of centre (cx, cy) and ``radius``: (lo, hi), NaN where the run is no graph over
    t inside the circle's span.  ``u``, ``v`` (L,) are work space."""
    for j in range(cnt):
        u[j] = pts[j, 0] * t0 + pts[j, 1] * t1
        v[j] = pts[j, 0] * n0 + pts[j, 1] * n1
    cu = cx * t0 + cy * t1
    cv = cx * n0 + cy * n1
    r = radius
    b = 1.0 if upper else -1.0
    rising = True
    falling = True
    span = True
    lo = np.inf
    hi = -np.inf
    for j in range(cnt):
        w = u[j] - cu
        if not abs(w) <= r * (1.0 + 1e-12):
            span = False
        if 1 <= j < cnt - 1:
            g = cv + b * math.sqrt(max(r * r - w * w, 0.0)) - v[j]
            if g < lo or g != g:
                lo = g
            if g > hi or g != g:
                hi = g
    for j in range(cnt - 1):
        du = u[j + 1] - u[j]
        if not du > 0:
            rising = False
        if not du < 0:
            falling = False
        safe = du if du != 0 else 1.0
        slope = (v[j + 1] - v[j]) / safe
        wc = -b * slope * r / math.sqrt(1.0 + slope * slope)
        uc = cu + wc
        if (uc - u[j]) * (uc - u[j + 1]) < 0:
            g = cv + b * math.sqrt(max(r * r - wc * wc, 0.0)) - (v[j] + slope * (uc - u[j]))
            if g < lo or g != g:
                lo = g
            if g > hi or g != g:
                hi = g
    if not ((rising or falling) and span):
        return np.nan, np.nan
    return lo, hi


@helper
def _arc_loop(sag, k, pts, cnt, c, mid, t, n, s_hi, s_max, s_min_radius, u, v, out):
    """The arc of sagitta ``sag`` on run ``k`` below the upper bound ``s_hi`` (``arc_of`` of
    ``arcs_fit._fit_runs``): out = (cx, cy, radius, lo, hi); returns whether it is good."""
    good = (sag <= s_hi) & (abs(sag) <= s_max[k]) & (abs(sag) >= s_min_radius[k])
    safe = sag if good and sag != 0 else 1.0
    ck = c[k]
    r = (ck * ck + safe * safe) / (2.0 * abs(safe))
    good = good and r >= MIN_RADIUS
    sign = 1.0 if safe > 0 else (-1.0 if safe < 0 else 0.0)
    off = sign * (r - abs(safe))
    cx = mid[k, 0] - off * n[k, 0]
    cy = mid[k, 1] - off * n[k, 1]
    lo, hi = _gaps_loop(pts[k], cnt, cx, cy, r, safe > 0, t[k, 0], t[k, 1], n[k, 0], n[k, 1],
                        u, v)
    out[0] = cx
    out[1] = cy
    out[2] = r
    out[3] = lo
    out[4] = hi
    return good and math.isfinite(lo)


def _fit_runs_loops(pts, count, u, v, ok, c, s_end, s_max, s_min_radius, lift, vertical, a,
                    b, chord, mid, t, n, tolerance, line, good, centre, radius):
    """Per run k with ``ok`` (numpy engine's arrays: padded points, chord-frame u, v, the end
    chords' sagitta bound ``s_end``, ...): ``line``, ``good``, ``centre`` and ``radius`` as
    ``arcs_fit._fit_runs`` decides them."""
    K, width = u.shape
    wu = np.empty(width)
    wv = np.empty(width)
    arc = np.empty(5)
    keep = np.empty(5)
    for k in range(K):
        line[k] = False
        good[k] = False
        if not ok[k]:
            continue
        cnt = count[k]
        ck = c[k]
        s_lo = -np.inf
        s_hi_k = np.inf
        for j in range(1, cnt - 1):
            s = _sagitta(ck, u[k, j], v[k, j])
            if s > s_lo or s != s:
                s_lo = s
            s = _sagitta(ck, u[k, j], v[k, j] + lift[k])
            if s < s_hi_k or s != s:
                s_hi_k = s
        s_lo = most(s_lo, s_end[k])
        straight = s_lo <= 0.0 and s_hi_k >= 0.0
        if straight:
            ratio = chord[k, 1] / (chord[k, 0] if chord[k, 0] > 0 else 1.0)
            for j in range(cnt):
                if vertical[k]:
                    gap = a[k, 1] + (pts[k, j, 0] - a[k, 0]) * ratio - pts[k, j, 1]
                else:
                    gap = -v[k, j]
                if not (gap >= -1e-12 and gap <= tolerance):
                    straight = False
                    break
            if vertical[k] and not chord[k, 0] > 0:
                straight = False
        if straight:
            line[k] = True
            continue
        s_k = s_lo + MARGIN
        if s_k > 0 and s_k < s_min_radius[k]:
            s_k = s_min_radius[k]
        g = _arc_loop(s_k, k, pts, cnt, c, mid, t, n, s_hi_k, s_max, s_min_radius,
                      wu, wv, arc)
        for i in range(5):
            keep[i] = arc[i]
        fit = g
        if g and arc[3] < -ROUNDING:
            top = least(s_hi_k, s_max[k])
            g_t = _arc_loop(top, k, pts, cnt, c, mid, t, n, s_hi_k, s_max,
                            s_min_radius, wu, wv, arc)
            if not (g_t and arc[3] >= -ROUNDING):
                fit = False
            else:
                for i in range(5):
                    keep[i] = arc[i]
                lo_s = s_k
                hi_s = top
                for _ in range(BISECTIONS):
                    m = 0.5 * (lo_s + hi_s)
                    g_m = _arc_loop(m, k, pts, cnt, c, mid, t, n, s_hi_k, s_max,
                                    s_min_radius, wu, wv, arc)
                    if g_m and arc[3] >= 0.5 * MARGIN:
                        hi_s = m
                        for i in range(5):
                            keep[i] = arc[i]
                    else:
                        lo_s = m
        cx, cy, r, lo, hi = keep[0], keep[1], keep[2], keep[3], keep[4]
        centre[k, 0] = cx
        centre[k, 1] = cy
        radius[k] = r
        if not fit or lo < -ROUNDING:
            continue
        upper = (mid[k, 0] - cx) * n[k, 0] + (mid[k, 1] - cy) * n[k, 1] > 0
        if vertical[k]:
            lo_v, hi_v = _gaps_loop(pts[k], cnt, cx, cy, r, upper, 1.0, 0.0, 0.0, 1.0, wu, wv)
            wa = a[k, 1] - cy
            wb = b[k, 1] - cy
            halves = ((wa > 0) == upper) and ((wb > 0) == upper) and abs(wa) > 1e-12 \
                and abs(wb) > 1e-12
            good[k] = lo_v >= -ROUNDING and hi_v <= tolerance and halves
        else:
            good[k] = hi <= tolerance



def _biarc_checks_loops(pts, count, vertical, joint, centres, radii, a, b, tolerance, good):
    """``arcs_fit._fit_biarcs``'s tests of each run's two arcs (``good`` in: the geometry's
    ok; out: accepted): the run a graph over each arc's frame, cut at the joint's abscissa,
    each part's gaps and the gap at the cut within [0, tolerance]."""
    K, width = count.shape[0], pts.shape[1]
    u = np.empty(width)
    sub = np.empty((width + 1, 2))
    wu = np.empty(width + 1)
    wv = np.empty(width + 1)
    for k in range(K):
        if not good[k]:
            continue
        cnt = count[k]
        for arc in range(2):
            if arc == 0:
                px, py, qx, qy = a[k, 0], a[k, 1], joint[k, 0], joint[k, 1]
            else:
                px, py, qx, qy = joint[k, 0], joint[k, 1], b[k, 0], b[k, 1]
            if vertical[k]:
                t0, t1 = 1.0, 0.0
            else:
                dx, dy = qx - px, qy - py
                length = math.hypot(dx, dy)
                if not length > 0:
                    length = 1.0
                t0, t1 = dx / length, dy / length
            n0, n1 = -t1, t0
            for j in range(cnt):
                u[j] = pts[k, j, 0] * t0 + pts[k, j, 1] * t1
            uj = joint[k, 0] * t0 + joint[k, 1] * t1
            ok = u[0] < uj and uj < u[cnt - 1]
            for j in range(cnt - 1):
                if not u[j + 1] - u[j] > 0:
                    ok = False
            m = 0
            for j in range(cnt):
                if (u[j] < uj) if arc == 0 else (u[j] <= uj):
                    m += 1
            m = min(max(m, 1), cnt - 1)
            u0, u1 = u[m - 1], u[m]
            f = (uj - u0) / (u1 - u0 if u1 > u0 else 1.0)
            cutx = pts[k, m - 1, 0] + f * (pts[k, m, 0] - pts[k, m - 1, 0])
            cuty = pts[k, m - 1, 1] + f * (pts[k, m, 1] - pts[k, m - 1, 1])
            if arc == 0:  # A, vertices before the cut, the cut
                for j in range(m):
                    sub[j, 0] = pts[k, j, 0]
                    sub[j, 1] = pts[k, j, 1]
                sub[m, 0] = cutx
                sub[m, 1] = cuty
                sub_count = m + 1
            else:  # the cut, vertices after it, B
                sub[0, 0] = cutx
                sub[0, 1] = cuty
                sub_count = cnt - m + 1
                for j in range(1, sub_count):
                    sub[j, 0] = pts[k, m + j - 1, 0]
                    sub[j, 1] = pts[k, m + j - 1, 1]
            cx, cy = centres[k, arc, 0], centres[k, arc, 1]
            upper = (0.5 * (px + qx) - cx) * n0 + (0.5 * (py + qy) - cy) * n1 > 0
            if vertical[k]:
                wa, wb = py - cy, qy - cy
                if not (((wa > 0) == upper) and ((wb > 0) == upper) and abs(wa) > 1e-12
                        and abs(wb) > 1e-12):
                    ok = False
            lo, hi = _gaps_loop(sub, sub_count, cx, cy, radii[k, arc], upper, t0, t1, n0, n1,
                                wu, wv)
            gap = (joint[k, 0] - cutx) * n0 + (joint[k, 1] - cuty) * n1
            if not (ok and lo >= -ROUNDING and hi <= tolerance and gap >= -ROUNDING
                    and gap <= tolerance):
                good[k] = False
                break


fit_runs = Kernel(_fit_runs_loops)
biarc_checks = Kernel(_biarc_checks_loops)
