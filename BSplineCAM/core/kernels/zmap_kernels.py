# SPDX-License-Identifier: LGPL-2.1-or-later
"""The Z-map's stamping as loops: each segment's envelope lowered straight into the height map.

:func:`stamp_loops` is the numba twin of ``simulate._envelope`` followed by the ``fmin`` merge
(and, for a rapid, the collision depth): cell by cell, the same float32 operations in the same
order, every intermediate rounded to float32 where the numpy engine's arrays are float32, so
the height map is bit-identical.  The per-segment constants (direction, slope, the float32
casts of the numpy engine's per-segment terms) and the ``wide`` choice of each segment (made
per batch by the numpy engine) are computed by the caller with numpy and passed in.

A call stamps the rows ``part``, ``part + parts``, ... of every 4-row block
(``(row >> 2) % parts == part``): threads given different ``part`` never write the same cell.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper

#: Shapes, as ``simulate.ToolShape`` in the order ball, flat, bull-nose.
BALL, FLAT, BULLNOSE = 0, 1, 2


def stamp_loops(height, x0, y0, cell, ix0, iy0, hb, wb, p0x, p0y, ux, uy, wide, L, Lf, mf,
                slopef, zf, bisect, shape, consts, collision, part, parts, depth_out):
    """Lower ``height`` (float32, (ny, nx)) by the envelopes of the segments, each over its
    window of hb[k] x wb[k] cells from (iy0[k], ix0[k]).

    Per segment k (float64): start (p0x, p0y), XY direction (ux, uy), length L; float32:
    Lf = f32(L), mf = f32(m), slopef = f32(tau* / rho) (ball m / sqrt(1 + m^2), flat sign(m),
    bull-nose sign(m)), zf = f32(z0 + R) (ball), f32(z0) (flat), f32(z0 + rc) (bull-nose);
    wide[k] the float64-then-round path.  ``consts`` (float32, :func:`constants`) holds the
    tool's float32 constants as the numpy engine casts them.  ``bisect[k]`` is f32(|m|) for the bull-nose
    bisection (0: level, tau = 0).  With ``collision`` (one segment) the deepest
    height - envelope before the merge goes to depth_out = (depth, row, column), first in row
    order; NaN envelopes count as -inf.
    """
    f32 = np.float32
    R2, rim2, flat_cut, rcf, rc2, rc_top, twice_rc, af, Rf = (
        consts[0], consts[1], consts[2], consts[3], consts[4], consts[5], consts[6], consts[7],
        consts[8])
    zero = f32(0.0)
    nan = f32(np.nan)
    best = -np.inf
    best_i = -1
    best_j = -1
    most = 1
    for k in range(len(wb)):
        most = max(most, wb[k])
    b_qa = np.empty(most, np.float32)
    b_qa1 = np.empty(most, np.float32)
    b_qp2 = np.empty(most, np.float32)
    b_beyond = np.empty(most, np.float32)
    b_rho = np.empty(most, np.float32)
    b_tau = np.empty(most, np.float32)
    b_lo = np.empty(most, np.float32)
    for k in range(len(ix0)):
        H = hb[k]
        W = wb[k]
        for i in range(iy0[k], iy0[k] + H):
            if (i >> 2) % parts != part:
                continue
            dy = y0 + (float(i) + 0.5) * cell - p0y[k]
            # the row's cells: offsets along and across the segment, reach
            for c in range(W):
                dx = x0 + (float(ix0[k] + c) + 0.5) * cell - p0x[k]
                if wide[k]:
                    qa = f32(dy * uy[k] + dx * ux[k])
                    qa1 = f32(dy * uy[k] + (dx * ux[k] - L[k]))
                    qp = f32(dy * ux[k] - dx * uy[k])
                else:
                    qa = f32(f32(dy * uy[k]) + f32(dx * ux[k]))
                    qa1 = f32(qa - Lf[k])
                    qp = f32(f32(dy * ux[k]) - f32(dx * uy[k]))
                qp2 = f32(qp * qp)
                beyond = -qa
                if qa1 > beyond:
                    beyond = qa1
                if beyond < zero:
                    beyond = zero
                b_qa[c] = qa
                b_qa1[c] = qa1
                b_qp2[c] = qp2
                b_beyond[c] = f32(f32(beyond * beyond) + qp2)
                b_rho[c] = f32(math.sqrt(f32(R2 - qp2)))  # NaN beyond reach
            if shape == BULLNOSE:
                if bisect[k] > zero:
                    _bullnose_tau_row(b_qp2, b_rho, bisect[k], af, rc2, rc_top, W, b_lo,
                                      b_tau)
                else:
                    for c in range(W):
                        b_tau[c] = f32(b_rho[c] * zero)
                for c in range(W):
                    b_tau[c] = f32(b_tau[c] * slopef[k])
            else:
                for c in range(W):
                    b_tau[c] = f32(b_rho[c] * slopef[k])
            for c in range(W):
                if not b_beyond[c] <= rim2:
                    env = nan  # beyond the tool's reach, or its rim band
                else:
                    qa = b_qa[c]
                    rho = b_rho[c]
                    tau = b_tau[c]
                    if tau > qa:
                        tau = qa
                    t = f32(qa - tau)
                    if b_qa1[c] > tau:
                        tau = b_qa1[c]
                    if t > Lf[k]:
                        t = Lf[k]
                    t = f32(t * mf[k])
                    gap = f32(f32(rho - tau) * f32(rho + tau))
                    if shape == BALL:
                        env = nan
                        if gap >= zero:
                            env = f32(f32(t + zf[k]) - f32(math.sqrt(gap)))
                    elif shape == FLAT:
                        env = nan
                        if not gap < flat_cut:
                            env = f32(t + zf[k])
                    else:
                        r = f32(R2 - gap)
                        g = nan
                        if r >= zero:
                            g = f32(gap / f32(f32(math.sqrt(r)) + Rf))
                        if g > rcf:
                            g = rcf
                        g = f32(g * f32(twice_rc - g))
                        env = nan
                        if g >= zero:
                            env = f32(f32(t + zf[k]) - f32(math.sqrt(g)))
                j = ix0[k] + c
                h = height[i, j]
                if collision:
                    d = f32(h - env)
                    if d > best:  # NaN is never deeper
                        best = d
                        best_i = i
                        best_j = j
                if env < h:
                    height[i, j] = env
    depth_out[0] = best
    depth_out[1] = best_i
    depth_out[2] = best_j


@helper
def _bullnose_tau_row(qp2, rho, m, a, rc2, rc_top, W, lo, tau):
    """tau >= 0 solving f'(r) tau / r = m on [0, rho] for the first W cells of a row, by the
    numpy engine's 24 float32 bisection steps (``simulate._bullnose_tau``), into ``tau``
    (``lo`` is work space).  Branch-free over the row, so that the compiler vectorises it."""
    f32 = np.float32
    zero = f32(0.0)
    half = f32(0.5)
    for c in range(W):
        lo[c] = zero
        tau[c] = rho[c]  # hi
    for _ in range(24):
        for c in range(W):
            mid = f32(half * f32(lo[c] + tau[c]))
            r = f32(math.sqrt(f32(qp2[c] + f32(mid * mid))))
            e = f32(r - a)
            e = e if e > zero else zero
            e = e if e < rc_top else rc_top
            slope = f32(e / f32(math.sqrt(f32(rc2 - f32(e * e)))))  # e / 0 = inf, as numpy
            w = f32(mid / r) if r > zero else zero
            grow = f32(slope * w) < m
            lo[c] = mid if grow else lo[c]
            tau[c] = tau[c] if grow else mid
    for c in range(W):
        tau[c] = f32(half * f32(lo[c] + tau[c]))


def constants(R: float, rc: float, rim: float) -> np.ndarray:
    """The float32 constants of :func:`stamp_loops` for a tool of radius R, corner radius rc
    (bull-nose) and a rim band ``rim`` (mm), cast as ``simulate._envelope`` casts them."""
    f32 = np.float32
    return np.array([f32(R * R), f32((R - rim) ** 2), f32(-1e-6 * R * R), f32(rc),
                     f32(rc * rc), f32(rc * (1 - 1e-12)), f32(2 * rc), f32(R - rc), f32(R)],
                    dtype=np.float32)


stamp = Kernel(stamp_loops)

__all__ = ["BALL", "BULLNOSE", "FLAT", "constants", "stamp", "stamp_loops"]


@helper
def envelope_window(out, o, x0, y0, cell, ix0, iy0, H, W, p0x, p0y, ux, uy, wide, L, Lf, mf,
                    slopef, zf, bisect, shape, consts, work):
    """The envelope of one segment over its window of H x W cells from (iy0, ix0), row by row
    into ``out[o:o + H * W]`` (float32, NaN beyond the tool's reach): the cell values
    :func:`stamp_loops` merges, by the same float32 operations (the arguments are one
    segment's entries of its arrays).  ``work`` (float32, (7, >= W)) is work space."""
    f32 = np.float32
    R2, rim2, flat_cut, rcf, rc2, rc_top, twice_rc, af, Rf = (
        consts[0], consts[1], consts[2], consts[3], consts[4], consts[5], consts[6], consts[7],
        consts[8])
    zero = f32(0.0)
    nan = f32(np.nan)
    b_qa = work[0]
    b_qa1 = work[1]
    b_qp2 = work[2]
    b_beyond = work[3]
    b_rho = work[4]
    b_tau = work[5]
    b_lo = work[6]
    for r in range(H):
        dy = y0 + (float(iy0 + r) + 0.5) * cell - p0y
        for c in range(W):
            dx = x0 + (float(ix0 + c) + 0.5) * cell - p0x
            if wide:
                qa = f32(dy * uy + dx * ux)
                qa1 = f32(dy * uy + (dx * ux - L))
                qp = f32(dy * ux - dx * uy)
            else:
                qa = f32(f32(dy * uy) + f32(dx * ux))
                qa1 = f32(qa - Lf)
                qp = f32(f32(dy * ux) - f32(dx * uy))
            qp2 = f32(qp * qp)
            beyond = -qa
            if qa1 > beyond:
                beyond = qa1
            if beyond < zero:
                beyond = zero
            b_qa[c] = qa
            b_qa1[c] = qa1
            b_qp2[c] = qp2
            b_beyond[c] = f32(f32(beyond * beyond) + qp2)
            b_rho[c] = f32(math.sqrt(f32(R2 - qp2)))  # NaN beyond reach
        if shape == BULLNOSE:
            if bisect > zero:
                _bullnose_tau_row(b_qp2, b_rho, bisect, af, rc2, rc_top, W, b_lo, b_tau)
            else:
                for c in range(W):
                    b_tau[c] = f32(b_rho[c] * zero)
            for c in range(W):
                b_tau[c] = f32(b_tau[c] * slopef)
        else:
            for c in range(W):
                b_tau[c] = f32(b_rho[c] * slopef)
        row = o + r * W
        for c in range(W):
            if not b_beyond[c] <= rim2:
                env = nan  # beyond the tool's reach, or its rim band
            else:
                qa = b_qa[c]
                rho = b_rho[c]
                tau = b_tau[c]
                if tau > qa:
                    tau = qa
                t = f32(qa - tau)
                if b_qa1[c] > tau:
                    tau = b_qa1[c]
                if t > Lf:
                    t = Lf
                t = f32(t * mf)
                gap = f32(f32(rho - tau) * f32(rho + tau))
                if shape == BALL:
                    env = nan
                    if gap >= zero:
                        env = f32(f32(t + zf) - f32(math.sqrt(gap)))
                elif shape == FLAT:
                    env = nan
                    if not gap < flat_cut:
                        env = f32(t + zf)
                else:
                    rr = f32(R2 - gap)
                    g = nan
                    if rr >= zero:
                        g = f32(gap / f32(f32(math.sqrt(rr)) + Rf))
                    if g > rcf:
                        g = rcf
                    g = f32(g * f32(twice_rc - g))
                    env = nan
                    if g >= zero:
                        env = f32(f32(t + zf) - f32(math.sqrt(g)))
            out[row + c] = env


__all__ += ["envelope_window"]
