# SPDX-License-Identifier: LGPL-2.1-or-later
"""The job simulation's cut as loops: a chunk of moves cut into the Z-map and measured.

:func:`cut_chunk_loops` is the numba twin of ``job_simulation._Cutter.cut_chunk`` (envelopes
by :func:`.zmap_kernels.envelope_window`, then, move by move, ``cut_segment`` with its
``_inner_depth`` and ``_radial``): the same float32 and float64 operations in the same order,
so that heights, drops, engagements and volumes are bit-identical.  Sums of float32 cells in
float64 follow numpy's (:func:`pairwise_sum`).  The per-piece constants of the envelope and
the ``wide`` choice of each piece (made per window shape by the numpy engine) are computed by
the caller with numpy and passed in.
"""

from __future__ import annotations

import numpy as np

from ..simulation.simulate import segment_frame, window_reach
from . import Kernel, helper
from .zmap_kernels import BALL, FLAT, envelope_window

#: numpy's pairwise summation: blocks of at most this many values are summed with 8
#: accumulators.
_PW_BLOCKSIZE = 128
#: numpy's buffer (elements) when a float32 array is summed in float64: the pairwise sums of
#: successive buffers are added one after the other.
_BUFSIZE = 8192


@helper
def _pairwise(a, lo, n):
    """numpy's pairwise sum (float64) of ``a[lo:lo + n]`` (float32 or float64 values)."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += np.float64(a[lo + i])
        return res
    if n <= _PW_BLOCKSIZE:
        r0 = np.float64(a[lo])
        r1 = np.float64(a[lo + 1])
        r2 = np.float64(a[lo + 2])
        r3 = np.float64(a[lo + 3])
        r4 = np.float64(a[lo + 4])
        r5 = np.float64(a[lo + 5])
        r6 = np.float64(a[lo + 6])
        r7 = np.float64(a[lo + 7])
        i = 8
        stop = n - n % 8
        while i < stop:
            r0 += np.float64(a[lo + i])
            r1 += np.float64(a[lo + i + 1])
            r2 += np.float64(a[lo + i + 2])
            r3 += np.float64(a[lo + i + 3])
            r4 += np.float64(a[lo + i + 4])
            r5 += np.float64(a[lo + i + 5])
            r6 += np.float64(a[lo + i + 6])
            r7 += np.float64(a[lo + i + 7])
            i += 8
        res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        while i < n:
            res += np.float64(a[lo + i])
            i += 1
        return res
    n2 = n // 2
    n2 -= n2 % 8
    return _pairwise(a, lo, n2) + _pairwise(a, lo + n2, n - n2)


@helper
def pairwise_sum(a, lo, n):
    """``a[lo:lo + n].sum(dtype=np.float64)`` as numpy computes it for a float32 array: the
    pairwise sums of successive buffers of _BUFSIZE values, added in order."""
    total = 0.0
    start = 0
    while start < n:
        size = min(_BUFSIZE, n - start)
        total += _pairwise(a, lo + start, size)
        start += size
    return total


def cut_chunk_loops(height, x0, y0, cell, z0, has_z0, thr, ix0, iy0, hb, wb, p0x, p0y, ux, uy,
                    wide, L, Lf, mf, slopef, zf, bisect, shape, consts, first, count, start,
                    end, length, rapid, reach2, corner, diameter, area, weak, drop_out,
                    axial_out, radial_out, xy_out, piece_volume, volume_out):
    """Cut the moves of a chunk into ``height`` (float32, (ny, nx)), one after the other.

    Pieces (numbered in the chunk, a move's pieces consecutive): window (iy0, ix0, hb, wb) and
    envelope constants as :func:`.zmap_kernels.envelope_window` takes them.  Move k: pieces
    first[k] .. first[k] + count[k] - 1 (count >= 1), ends ``start[k]``, ``end[k]`` (x, y, z),
    XY length ``length[k]`` (math.hypot), ``rapid[k]``.  ``z0`` (float32) is the floor when
    ``has_z0``, ``thr`` (float32) the engagement threshold, ``reach2`` the squared radius of
    the axial measure, ``corner`` the tool's corner height (``corner_height`` before its
    halving), ``area`` a cell's area, ``weak`` whether a Python float added to a float32
    scalar stays float32 (numpy 2).  Out, per move: ``drop_out`` (the deepest drop),
    ``axial_out``, ``radial_out`` (written for cutting feed moves only), ``xy_out`` (the
    deepest cell's centre), ``volume_out``; per piece ``piece_volume`` (zeros on entry).
    """
    f32 = np.float32
    npieces = len(ix0)
    most_w = 1
    most_cells = 1
    for p in range(npieces):
        most_w = max(most_w, wb[p])
    for k in range(len(first)):
        cells = 0
        for p in range(first[k], first[k] + count[k]):
            cells += hb[p] * wb[p]
        most_cells = max(most_cells, cells)
    work = np.empty((7, most_w), np.float32)
    new = np.empty(most_cells, np.float32)  # the move's pieces' heights after it
    drop = np.empty(most_cells, np.float32)  # their drops, then what each piece removed
    # the engaged cells (drop > thr): centre from the move's start, drop, height before
    eqx = np.empty(most_cells)
    eqy = np.empty(most_cells)
    edrop = np.empty(most_cells, np.float32)
    ebefore = np.empty(most_cells, np.float32)
    offset = np.empty(npieces, np.int64)
    for k in range(len(first)):
        # each piece: its envelope, the heights after it, its deepest drop (numpy's argmax:
        # the first of the largest, or the first NaN)
        o = 0
        best_k = -1
        best_d = f32(0.0)
        best_at = 0
        engaged = 0
        ax = start[k, 0]
        ay = start[k, 1]
        for p in range(first[k], first[k] + count[k]):
            H = hb[p]
            W = wb[p]
            offset[p] = o
            envelope_window(new, o, x0, y0, cell, ix0[p], iy0[p], H, W, p0x[p], p0y[p],
                            ux[p], uy[p], wide[p], L[p], Lf[p], mf[p], slopef[p], zf[p],
                            bisect[p], shape, consts, work)
            pd = f32(0.0)
            pat = 0
            nan_at = -1
            nan_d = f32(0.0)
            for r in range(H):
                row = o + r * W
                for c in range(W):
                    h = height[iy0[p] + r, ix0[p] + c]
                    e = new[row + c]
                    v = e if e < h else h
                    if has_z0 and v < z0:
                        v = z0
                    new[row + c] = v
                    d = f32(h - v)
                    drop[row + c] = d
                    if r == 0 and c == 0:
                        pd = d
                    elif d > pd:
                        pd = d
                        pat = r * W + c
                    if d > thr:
                        eqx[engaged] = x0 + (float(ix0[p] + c) + 0.5) * cell - ax
                        eqy[engaged] = y0 + (float(iy0[p] + r) + 0.5) * cell - ay
                        edrop[engaged] = d
                        ebefore[engaged] = h
                        engaged += 1
                    elif d != d and nan_at < 0:
                        nan_at = r * W + c
                        nan_d = d  # that NaN, its sign bit as the subtraction gave it
            if nan_at >= 0:
                pd = nan_d
                pat = nan_at
            if best_k < 0 or pd > best_d:  # Python's max over the pieces' drops
                best_k = p
                best_d = pd
                best_at = pat
            o += H * W
        deepest = np.float64(best_d)
        W = wb[best_k]
        cy = best_at // W
        cx = best_at - cy * W
        drop_out[k] = deepest
        axial_out[k] = deepest
        xy_out[k, 0] = x0 + (float(ix0[best_k] + cx) + 0.5) * cell
        xy_out[k, 1] = y0 + (float(iy0[best_k] + cy) + 0.5) * cell
        if deepest > thr and not rapid[k]:
            axial_out[k] = _inner_depth(eqx, eqy, edrop, engaged, end[k, 0] - ax,
                                        end[k, 1] - ay, reach2)
            radial_out[k] = _radial(eqx, eqy, ebefore, engaged, start[k], end[k],
                                    length[k], corner, diameter, cell, thr, deepest, weak)
        # the cut, and the volume each piece removed beyond the pieces before it
        if count[k] == 1:
            p = first[k]
            if deepest > 0:
                for r in range(hb[p]):
                    for c in range(wb[p]):
                        height[iy0[p] + r, ix0[p] + c] = new[r * wb[p] + c]
                piece_volume[p] = pairwise_sum(drop, 0, hb[p] * wb[p]) * area
        else:
            for p in range(first[k], first[k] + count[k]):
                o = offset[p]
                for r in range(hb[p]):
                    row = o + r * wb[p]
                    for c in range(wb[p]):
                        h = height[iy0[p] + r, ix0[p] + c]
                        e = new[row + c]
                        v = e if e < h else h
                        drop[row + c] = f32(h - v)
                        height[iy0[p] + r, ix0[p] + c] = v
                piece_volume[p] = pairwise_sum(drop, o, hb[p] * wb[p]) * area
        volume_out[k] = pairwise_sum(piece_volume, first[k], count[k])


@helper
def _inner_depth(qx, qy, drop, n, dx, dy, reach2):
    """``_Cutter._inner_depth``: the largest drop at the ``n`` engaged cells (centres qx, qy
    from the move's start, which moves by dx, dy in XY) within sqrt(reach2) of its XY path."""
    dd = dx * dx + dy * dy
    best = 0.0
    for i in range(n):
        t = 0.0
        if dd > 0:
            t = (qx[i] * dx + qy[i] * dy) / dd
            t = min(max(t, 0.0), 1.0)
        gx = qx[i] - t * dx
        gy = qy[i] - t * dy
        if gx * gx + gy * gy <= reach2 and np.float64(drop[i]) > best:
            best = np.float64(drop[i])
    return best


@helper
def _radial(qx, qy, before, n, p0, p1, L, corner, diameter, cell, thr, deepest, weak):
    """``_Cutter._radial``: the extent of the ``n`` engaged cells (centres qx, qy from the
    move's start, heights ``before`` it) across the move, those whose material stood above
    the corner height if any, plus a cell, at most ``diameter``."""
    f32 = np.float32
    dx = p1[0] - p0[0]
    dy = p1[1] - p0[1]
    low = min(p0[2], p1[2]) + min(corner, 0.5 * deepest)
    above = f32(f32(low) + thr) if weak else f32(low + np.float64(thr))
    for upper in (True, False):
        lo = np.inf
        hi = -np.inf
        lo2 = np.inf
        hi2 = -np.inf
        for i in range(n):
            if upper and not before[i] > above:
                continue
            if L > 1e-9:
                q = (qy[i] * dx - qx[i] * dy) / L
                lo = min(lo, q)
                hi = max(hi, q)
            else:
                lo = min(lo, qx[i])
                hi = max(hi, qx[i])
                lo2 = min(lo2, qy[i])
                hi2 = max(hi2, qy[i])
        if hi >= lo:
            extent = hi - lo if L > 1e-9 else max(hi - lo, hi2 - lo2)
            return min(diameter, extent + cell)
    return 0.0


def envelope_arrays(p0, p1, ix0, iy0, hb, wb, key, radius, corner_radius, shape, x0, y0, cell):
    """The per-piece arguments of :func:`.zmap_kernels.envelope_window` for the pieces from
    ``p0`` to ``p1`` (n, 3) over windows (iy0, ix0, hb, wb), as ``simulate._envelope`` computes
    them for a batch, its ``wide`` choice made over the pieces of equal ``key`` (one batch
    each): (p0x, p0y, ux, uy, wide, L, Lf, mf, slopef, zf, bisect)."""
    L, ux, uy, m, z0 = segment_frame(p0, p1)
    reach = window_reach(p0, ix0, iy0, hb, wb, x0, y0, cell)
    _, batch = np.unique(key, return_inverse=True)
    batch = batch.reshape(-1)
    most = np.full(int(batch.max()) + 1 if len(batch) else 0, -np.inf)
    np.maximum.at(most, batch, reach)
    wide = most[batch] > 2 * radius
    f32 = np.float32
    bisect = np.zeros(len(L), f32)
    if shape == BALL:
        slope, zf = m / np.sqrt(1.0 + m * m), z0 + radius
    elif shape == FLAT:
        slope, zf = np.sign(m), z0
    else:
        slope, zf = np.sign(m), z0 + corner_radius
        bisect = np.abs(m).astype(f32)
    return (*(np.ascontiguousarray(v, dtype=float) for v in (p0[:, 0], p0[:, 1], ux, uy)),
            np.ascontiguousarray(wide), np.ascontiguousarray(L, dtype=float),
            *(np.ascontiguousarray(v).astype(f32) for v in (L, m, slope, zf)), bisect)


cut_chunk = Kernel(cut_chunk_loops)
sum_float32 = Kernel(pairwise_sum)

__all__ = ["cut_chunk", "cut_chunk_loops", "envelope_arrays", "pairwise_sum", "sum_float32"]
