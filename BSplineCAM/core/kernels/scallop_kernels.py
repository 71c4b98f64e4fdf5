# SPDX-License-Identifier: LGPL-2.1-or-later
"""The constant-scallop strategy's grid loops (:mod:`..toolpath.scallop_field`,
:mod:`..toolpath.scallop_metric`): the same arithmetic as their numpy engine, in the same
order, so that the answers agree to the bit.

* :func:`_near_vector_loops` is ``scallop_field.near_vector``'s search over the nodes near
  each piece of the polylines, offset by offset: first the least distance of each node over
  all pieces, then the vector of the pieces that reach it, the last one winning (numpy's
  fancy assignment);
* :func:`_propagate_loops` is ``scallop_field.propagate``'s sweeps, row by row, with the
  segmented running minimum along each row by the same prefix sums and offsets;
* :func:`_band_loops` is one direction of ``scallop_metric.band_costs``;
* :func:`_tent_loops` raises E to the tents between neighbours
  (``scallop_gaps.SurfaceGrid.distance``);
* :func:`_interpolated_cost_loops` is ``scallop_metric.directional_cost`` without ``bound``
  at the nodes of a mask, the costs read in place from the (axes, nx, ny) grids; the angles
  come from numpy's ``arctan2`` (its SIMD loops do not round as the C library's does).
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper
from .scalars import least


def _near_vector_loops(xs, ys, ax, ay, abx, aby, den, ci, cj, reach, out, vec, won_at):
    """Per offset (oi, oj) in [1 - reach, reach]^2, row-major: for each piece k (start
    (ax, ay), direction (abx, aby), den = |ab|^2, cell (ci, cj)) the distance from node
    (ci + oi, cj + oj), inside the grid, to the piece; ``out`` (nx, ny) lowered to it, then
    ``vec`` (nx, ny, 2) set to the node's vector from the piece where that distance is the
    node's least, pieces in order (the last write wins), and ``won_at`` (nx, ny) to the
    offset's row-major index."""
    nx, ny = out.shape
    m = len(ax)
    dist = np.empty(m)
    rx = np.empty(m)
    ry = np.empty(m)
    o = -1
    for oi in range(-reach + 1, reach + 1):
        for oj in range(-reach + 1, reach + 1):
            o += 1
            for k in range(m):
                i = ci[k] + oi
                j = cj[k] + oj
                if i < 0 or i >= nx or j < 0 or j >= ny:
                    continue
                px = xs[i] - ax[k]
                py = ys[j] - ay[k]
                t = (px * abx[k] + py * aby[k]) / den[k]
                if t < 0.0:
                    t = 0.0
                elif t > 1.0:
                    t = 1.0
                x = xs[i] - (ax[k] + t * abx[k])
                y = ys[j] - (ay[k] + t * aby[k])
                d = math.hypot(x, y)
                dist[k] = d
                rx[k] = x
                ry[k] = y
                cur = out[i, j]
                if d < cur or d != d:  # np.minimum: NaN wins
                    out[i, j] = d
            for k in range(m):
                i = ci[k] + oi
                j = cj[k] + oj
                if i < 0 or i >= nx or j < 0 or j >= ny:
                    continue
                if dist[k] == out[i, j]:
                    vec[i, j, 0] = rx[k]
                    vec[i, j, 1] = ry[k]
                    won_at[i, j] = o


def _interpolated_cost_loops(cost, against, source, ang, ii, jj, theta, vx, vy):
    """At nodes (ii[m], jj[m]): the cost per mm in the direction at angle theta[m] (rad, in
    [0, 2 pi)), interpolated linearly in the angle between the two of the directions at
    sorted angles ``ang`` that bracket it, times |(vx[m], vy[m])|.  Direction s reads row
    source[s] of the costs (axes, nx, ny) stacked on those ``against`` them."""
    count = len(ang)
    axes = cost.shape[0]
    out = np.empty(len(ii))
    for m in range(len(ii)):
        th = theta[m]
        # np.searchsorted(ang, th, side="right") - 1, NaN after every angle
        if th != th:
            lo = count - 1
        else:
            a, b = 0, count
            while a < b:
                mid = (a + b) // 2
                if ang[mid] <= th:
                    a = mid + 1
                else:
                    b = mid
            lo = a - 1
        hi = (lo + 1) % count
        span = (2.0 * math.pi if hi == 0 else ang[hi]) - ang[lo]
        w = (th - ang[lo]) / span
        i, j = ii[m], jj[m]
        r = source[lo]
        c_lo = float(cost[r, i, j]) if r < axes else float(against[r - axes, i, j])
        r = source[hi]
        c_hi = float(cost[r, i, j]) if r < axes else float(against[r - axes, i, j])
        out[m] = ((1.0 - w) * c_lo + w * c_hi) * math.hypot(vx[m], vy[m])
    return out


@helper
def _scan_loops(d, w, free, out):
    """``scallop_field._scan`` of one row (d, the edge costs w between its nodes, free) into
    out: the segmented running minimum by the same prefix sums, keys and offsets."""
    n = len(d)
    c = np.empty(n)
    brk = np.empty(n)
    c[0] = 0.0
    brk[0] = 0.0
    count = 0
    for t in range(1, n):
        wt = w[t - 1]
        finite = math.isfinite(wt)
        c[t] = c[t - 1] + (wt if finite else 0.0)
        if not free[t] or not free[t - 1] or not finite:
            count += 1
        brk[t] = float(count)
    most = 0.0
    for t in range(n):
        if math.isfinite(d[t]):
            most = max(most, abs(d[t]))
    big = 4.0 * (most + c[n - 1] + 1.0)
    acc = 0.0
    for t in range(n):
        key = (d[t] - c[t] if free[t] else math.inf) - brk[t] * big
        acc = key if t == 0 else least(acc, key)
        best = acc + brk[t] * big + c[t]
        out[t] = least(d[t], best) if free[t] else d[t]


def _propagate_loops(d, cost, against, free, length, bdi, bdj, bk, mstart, ma, mb, row_axis,
                     max_rounds):
    """``scallop_field.propagate``'s sweeps over d (nx, ny; the start values, inf off the
    free nodes), in place: per round a forward sweep over the rows along the axes
    (``cost``) and a backward one against them (``against``), each row taking its
    candidates from the rows before it along the axes (bdi[b], bdj[b]) = AXES[bk[b]], the
    nodes the step passes (ma, mb)[mstart[b]:mstart[b + 1]], then the scans along the row;
    until no value moves by more than 1e-9 or ``max_rounds`` rounds."""
    nx, ny = d.shape
    row = np.empty(ny)
    scanned = np.empty(ny)
    w = np.empty(max(ny - 1, 0))
    rd = np.empty(ny)
    rw = np.empty(max(ny - 1, 0))
    rf = np.empty(ny, np.bool_)
    before = np.empty((nx, ny))
    half_row = 0.5 * length[row_axis]
    for _ in range(max_rounds):
        before[:, :] = d
        for sweep in (1, -1):
            c_in = cost if sweep == 1 else against
            for step in range(nx):
                i = step if sweep == 1 else nx - 1 - step
                for j in range(ny):
                    row[j] = d[i, j]
                for b in range(len(bk)):
                    di, dj, k = bdi[b], bdj[b], bk[b]
                    src_i = i - sweep * di
                    if src_i < 0 or src_i >= nx:
                        continue
                    sj = sweep * dj
                    nm = mstart[b + 1] - mstart[b]
                    for j in range(ny):
                        jj = j - sj
                        if 0 <= jj < ny:
                            src = d[src_i, jj]
                            c_src = c_in[k, src_i, jj]
                        else:
                            src = math.inf
                            c_src = math.inf
                        total = 0.5 * (c_src + c_in[k, i, j])
                        for q in range(mstart[b], mstart[b + 1]):
                            row_m = i - sweep * (di - ma[q])
                            jm = j - sweep * (dj - mb[q])
                            if 0 <= jm < ny and free[row_m, jm]:
                                total = total + c_in[k, row_m, jm]
                            else:
                                total = math.inf
                        cand = src + length[k] * total / (nm + 1)
                        if free[i, j]:
                            row[j] = least(row[j], cand)
                for j in range(ny - 1):
                    w[j] = half_row * (cost[row_axis, i, j + 1] + cost[row_axis, i, j])
                _scan_loops(row, w, free[i], scanned)
                for j in range(ny):
                    rd[j] = scanned[ny - 1 - j]
                    rf[j] = free[i, ny - 1 - j]
                for j in range(ny - 1):
                    rw[ny - 2 - j] = half_row * (against[row_axis, i, j + 1]
                                                 + against[row_axis, i, j])
                _scan_loops(rd, rw, rf, row)
                for j in range(ny):
                    d[i, j] = row[ny - 1 - j]
        most = 0.0
        same = True
        for i in range(nx):
            for j in range(ny):
                a, b = d[i, j], before[i, j]
                fa, fb = math.isfinite(a), math.isfinite(b)
                if fa != fb:
                    same = False
                most = max(most, abs((a if fa else 0.0) - (b if fb else 0.0)))
        if most <= 1e-9 and same:
            break


def _band_loops(src, reach, oi, oj, within, best):
    """``scallop_metric.band_costs`` of one direction: best (nx, ny) raised to src at each
    offset (oi[q], oj[q]) inside the grid whose distance ``within[q]`` (mm) the node's reach
    (mm) attains."""
    nx, ny = src.shape
    for i in range(nx):
        for j in range(ny):
            b = best[i, j]
            r = reach[i, j]
            for q in range(len(oi)):
                if r >= within[q]:
                    ii = i + oi[q]
                    jj = j + oj[q]
                    if 0 <= ii < nx and 0 <= jj < ny:
                        v = src[ii, jj]
                        if v > b or v != v:  # np.maximum: NaN wins
                            b = v
            best[i, j] = b


@helper
def _fmax(a, b):
    """np.fmax(a, b) of two floats (NaN loses)."""
    if b != b:
        return a
    if a != a or b > a:
        return b
    return a


def _tent_loops(e, rate, unit, on, dx, dy, out, top):
    """``scallop_gaps.SurfaceGrid.distance``'s tents: along x, then y, each edge's top
    (where E growing from both ends at rate times the unit vector's component meets, -inf
    where it does not lie on the edge) raises ``out`` at the edge's lower ends, then at its
    upper ones; ``top`` is scratch (nx, ny)."""
    nx, ny = e.shape
    for axis in range(2):
        step = dx if axis == 0 else dy
        di = 1 if axis == 0 else 0
        dj = 1 - di
        for i in range(nx - di):
            for j in range(ny - dj):
                i1, j1 = i + di, j + dj
                s1 = rate[i, j] * unit[i, j, axis]
                s2 = -rate[i1, j1] * unit[i1, j1, axis]
                t = (e[i1, j1] - e[i, j] + s2 * step) / (s1 + s2)
                if on[i, j] and on[i1, j1] and s1 > 0 and s2 > 0 and t > 0 and t < step:
                    top[i, j] = e[i, j] + s1 * t
                else:
                    top[i, j] = -math.inf
        for i in range(nx - di):
            for j in range(ny - dj):
                out[i, j] = _fmax(out[i, j], top[i, j])
        for i in range(nx - di):
            for j in range(ny - dj):
                out[i + di, j + dj] = _fmax(out[i + di, j + dj], top[i, j])


near_vector = Kernel(_near_vector_loops)
interpolated_cost = Kernel(_interpolated_cost_loops)
propagate = Kernel(_propagate_loops)
band = Kernel(_band_loops)
tent = Kernel(_tent_loops)

__all__ = ["band", "interpolated_cost", "near_vector", "propagate", "tent"]
