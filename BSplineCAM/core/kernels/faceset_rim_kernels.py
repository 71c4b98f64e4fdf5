# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the drop-cutter's rim bound (``faceset_bounds._rim_bound`` with
``faceset_bezier._material_reach``): the deep pairs far out in xy that a level's bounds leave
open are bounded by their material's own z and xy distance, one pair at a time where the
numpy engine makes two dozen array operations per call.

The arithmetic is the numpy engine's, operation by operation and in its order (``np.max``,
``np.min``, ``np.maximum`` and ``np.minimum`` with their NaN rule, ``np.argmin``'s first of
equals or first NaN, ``np.hypot``), and so are the vertex sets: a straddling pair whose trim
segments are listed takes its corners and the ends of as many segments as the most any such
pair of the call has (at least one), the others the sub-patch's corners.  The same bits.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper
from .scalars import nan_max, nan_min


@helper
def row_max(a):
    """``np.max`` of a 1-D array (NaN if any element is)."""
    out = a[0]
    for k in range(1, a.shape[0]):
        out = nan_max(out, a[k])
    return out


@helper
def abs_max(a):
    """``np.abs(a).max()`` of a 1-D array (NaN if any element is)."""
    out = abs(a[0])
    for k in range(1, a.shape[0]):
        out = nan_max(out, abs(a[k]))
    return out


@helper
def drift(w, c1, c2):
    """``faceset_bezier._rational_drift`` of one net's weights ``w`` (K,) and affine
    coefficients (c1, c2)."""
    wmin = w[0]
    wmax = w[0]
    for k in range(1, w.shape[0]):
        wmin = nan_min(wmin, w[k])
        wmax = nan_max(wmax, w[k])
    eps = (wmax - wmin) / wmin
    return math.sqrt(2.0) * eps * math.hypot(c1, c2)


@helper
def material_reach(vs, vt, ok, nv, kk, j, qx, qy, CX, CY, CZ, C, RS, rational, W, rounding,
                   ax, ay, nx, ny, usable):
    """``faceset_bezier._material_reach`` of one pair: sub-patch ``j`` of the table, query
    (qx, qy), the first ``nv`` material vertices (``vs``, ``vt``, ``ok``: the corners, then
    the first and the second ends of ``kk`` trim segments): (z_top, r).  ``ax`` ... ``usable``
    are scratch."""
    cx = CX[j]
    cy = CY[j]
    cz = CZ[j]
    x0 = C[1, j, 0]
    x1 = C[1, j, 1]
    x2 = C[1, j, 2]
    y0 = C[2, j, 0]
    y1 = C[2, j, 1]
    y2 = C[2, j, 2]
    z0 = C[0, j, 0]
    z1 = C[0, j, 1]
    z2 = C[0, j, 2]
    rx = abs_max(RS[1, j])
    ry = abs_max(RS[2, j])
    rz = abs_max(RS[0, j])
    if rational:
        rx = rx + drift(W[j], x1, x2)
        ry = ry + drift(W[j], y1, y2)
        rz = rz + drift(W[j], z1, z2)
    top = -np.inf
    best = np.inf
    jv = 0
    for v in range(nv):
        s = vs[v]
        t = vt[v]
        ax[v] = (cx + x0) + x1 * s + x2 * t - qx
        ay[v] = (cy + y0) + y1 * s + y2 * t - qy
        az = (cz + z0) + z1 * s + z2 * t
        top = nan_max(top, az if ok[v] else -np.inf)
        d2 = ax[v] * ax[v] + ay[v] * ay[v] if ok[v] else np.inf
        # np.argmin: the first NaN, else the first of the least
        if best == best and (d2 != d2 or d2 < best):
            best = d2
            jv = v
    z_top = top + rz
    # the candidate normals: the images of the box's sides, of the trim segments, and the
    # direction of the nearest vertex
    nc = 3 + kk
    nx[0] = -y1
    ny[0] = x1
    nx[1] = -y2
    ny[1] = x2
    for i in range(kk):
        ds = vs[4 + kk + i] - vs[4 + i]
        dt = vt[4 + kk + i] - vt[4 + i]
        nx[2 + i] = -(y1 * ds + y2 * dt)
        ny[2 + i] = x1 * ds + x2 * dt
    nx[nc - 1] = ax[jv]
    ny[nc - 1] = ay[jv]
    for c in range(nc):
        length = math.hypot(nx[c], ny[c])
        usable[c] = length > 0
        scale = length if usable[c] else 1.0
        nx[c] = nx[c] / scale
        ny[c] = ny[c] / scale
    gap = 0.0
    for c in range(nc):
        lo = np.inf
        hi = -np.inf
        for v in range(nv):
            proj = nx[c] * ax[v] + ny[c] * ay[v]
            lo = nan_min(lo, proj if ok[v] else np.inf)
            hi = nan_max(hi, proj if ok[v] else -np.inf)
        gap = nan_max(gap, nan_max(lo, -hi) if usable[c] else 0.0)
    r = nan_max(gap - math.hypot(rx, ry) - rounding, 0.0)
    return z_top, r


def _rim_bound_loops(ub, dd, floor, depth, rim_d2, rim_depth, R2, nd, qq, strad, listed, st,
                     okst, segs, CX, CY, CZ, C, RS, rational, W, rounding):
    """``faceset_bounds._rim_bound``: ``ub`` (n,) of the pairs (sub-patch ``nd``, query
    ``qq``) above ``floor`` (n,), at least ``rim_depth`` deep and whose net's box lies at
    least sqrt(``rim_d2``) away (``dd``) lowered to the material's reach, in place.  The
    straddling pairs ``strad`` (s,) with their segments ``listed`` take their material's
    vertices ``st`` (s, 4 + 2 MS, 2), ``okst``; ``segs`` (n, MS) are the pairs' trim
    segments, ``W`` (N, K) the nets' weights (read if ``rational``).  Returns the number of
    pairs bounded."""
    n = ub.shape[0]
    MS = segs.shape[1]
    in_strad = np.full(n, -1, np.int64)
    for r in range(strad.shape[0]):
        if listed[r]:
            in_strad[strad[r]] = r
    rim = np.zeros(n, np.bool_)
    kk = 0
    count = 0
    for i in range(n):
        if ub[i] > floor[i] and dd[i] >= rim_d2 and depth[i] >= rim_depth:
            rim[i] = True
            count += 1
            if in_strad[i] >= 0:
                c = 0
                for e in range(MS):
                    if segs[i, e] >= 0:
                        c += 1
                kk = max(kk, c)
    kk = max(kk, 1)
    V = 4 + 2 * kk
    vs = np.empty(V)
    vt = np.empty(V)
    ok = np.empty(V, np.bool_)
    ax = np.empty(V)
    ay = np.empty(V)
    nx = np.empty(3 + kk)
    ny = np.empty(3 + kk)
    usable = np.empty(3 + kk, np.bool_)
    for i in range(n):
        if not rim[i]:
            continue
        r = in_strad[i]
        if r >= 0:
            for v in range(V):
                col = v if v < 4 + kk else 4 + MS + (v - 4 - kk)
                vs[v] = st[r, col, 0]
                vt[v] = st[r, col, 1]
                ok[v] = okst[r, col]
            nv = V
            k = kk
        else:
            vs[0] = 0.0
            vt[0] = 0.0
            vs[1] = 1.0
            vt[1] = 0.0
            vs[2] = 0.0
            vt[2] = 1.0
            vs[3] = 1.0
            vt[3] = 1.0
            for v in range(4):
                ok[v] = True
            nv = 4
            k = 0
        zb, rb = material_reach(vs, vt, ok, nv, k, nd[i], qq[i, 0], qq[i, 1], CX, CY, CZ, C,
                                RS, rational, W, rounding, ax, ay, nx, ny, usable)
        if rb * rb > R2:
            ub[i] = -np.inf
        else:
            ub[i] = nan_min(ub[i], zb + math.sqrt(nan_max(R2 - rb * rb, 0.0)))
    return count


rim_bound = Kernel(_rim_bound_loops)
