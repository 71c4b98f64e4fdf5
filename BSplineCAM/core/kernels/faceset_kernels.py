# SPDX-License-Identifier: LGPL-2.1-or-later
"""Loop-style twins of the drop-cutter's per-level computations on sub-patches' nets
(:mod:`..toolpath.faceset_bounds`, :mod:`..toolpath.faceset_subdivide`): their coordinate
planes and boxes, the halving and the splits; compiled by
:class:`BSplineCAM.core.kernels.Kernel`, and :func:`~BSplineCAM.core.kernels.helper` functions
of :mod:`.faceset_round_kernels`' fused level.

Each function computes what its numpy twin computes, element by element in the same order of
operations, so both engines give the same bits: sums over a control net follow numpy's
pairwise summation (:func:`net_coords`), ``np.maximum``/``np.minimum`` keep their NaN rule
(a NaN operand gives NaN), and nothing is contracted into fused multiply-adds.  They take and
return contiguous float64, int64 and bool arrays only.
"""

from __future__ import annotations

import numpy as np

from . import helper

#: Most control points of a net whose centroid :func:`net_coords` sums (numpy's pairwise sum
#: of up to 128 terms is one 8-way block; larger nets take the numpy engine).
MAX_NET = 128


@helper
def net_coords(flat, rational):
    """The control points' coordinate planes PX, PY, PZ (N, K) of homogeneous nets ``flat``
    (N, 4, K) (divided by the weights if ``rational``), their centroids (N, 3) (numpy's
    ``mean``: pairwise sum, then divided by K), the deviations G (3, N, K) of (z, x, y) from
    the centroid and the net boxes (N, 5): x min, x max, y min, y max, z max."""
    N = flat.shape[0]
    K = flat.shape[2]
    PX = np.empty((N, K))
    PY = np.empty((N, K))
    PZ = np.empty((N, K))
    cen = np.empty((N, 3))
    G = np.empty((3, N, K))
    box = np.empty((N, 5))
    for n in range(N):
        for k in range(K):
            if rational:
                w = flat[n, 3, k]
                PX[n, k] = flat[n, 0, k] / w
                PY[n, k] = flat[n, 1, k] / w
                PZ[n, k] = flat[n, 2, k] / w
            else:
                PX[n, k] = flat[n, 0, k]
                PY[n, k] = flat[n, 1, k]
                PZ[n, k] = flat[n, 2, k]
        for c in range(3):
            if c == 0:
                a = PX[n]
            elif c == 1:
                a = PY[n]
            else:
                a = PZ[n]
            # numpy's pairwise sum (reduction started at 0)
            if K < 8:
                s = -0.0
                for i in range(K):
                    s += a[i]
            else:
                r0 = a[0]
                r1 = a[1]
                r2 = a[2]
                r3 = a[3]
                r4 = a[4]
                r5 = a[5]
                r6 = a[6]
                r7 = a[7]
                i = 8
                top = K - K % 8
                while i < top:
                    r0 += a[i]
                    r1 += a[i + 1]
                    r2 += a[i + 2]
                    r3 += a[i + 3]
                    r4 += a[i + 4]
                    r5 += a[i + 5]
                    r6 += a[i + 6]
                    r7 += a[i + 7]
                    i += 8
                s = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
                while i < K:
                    s += a[i]
                    i += 1
            cen[n, c] = (0.0 + s) / K
        xlo = PX[n, 0]
        xhi = PX[n, 0]
        ylo = PY[n, 0]
        yhi = PY[n, 0]
        zhi = PZ[n, 0]
        for k in range(K):
            x = PX[n, k]
            y = PY[n, k]
            z = PZ[n, k]
            G[0, n, k] = z - cen[n, 2]
            G[1, n, k] = x - cen[n, 0]
            G[2, n, k] = y - cen[n, 1]
            if x < xlo or x != x:
                xlo = x
            if x > xhi or x != x:
                xhi = x
            if y < ylo or y != y:
                ylo = y
            if y > yhi or y != y:
                yhi = y
            if z > zhi or z != z:
                zhi = z
        box[n, 0] = xlo
        box[n, 1] = xhi
        box[n, 2] = ylo
        box[n, 3] = yhi
        box[n, 4] = zhi
    return PX, PY, PZ, cen, G, box


@helper
def halve(nets, rational):
    """de Casteljau halving of nets (U, 4, p+1, q+1) along the longer side (the sum of the
    corners' xy distances, u on ties): (along u (U,), left halves, right halves)
    (``faceset_subdivide._longer_u`` and ``faceset_bezier._split_into``)."""
    U = nets.shape[0]
    D = nets.shape[1]
    P1 = nets.shape[2]
    Q1 = nets.shape[3]
    along = np.empty(U, np.bool_)
    left = np.empty_like(nets)
    right = np.empty_like(nets)
    cx = np.empty((2, 2, 2))
    wk = np.empty(max(P1, Q1))
    for m in range(U):
        for i in range(2):
            for j in range(2):
                ii = i * (P1 - 1)
                jj = j * (Q1 - 1)
                for c in range(2):
                    if rational:
                        cx[c, i, j] = nets[m, c, ii, jj] / nets[m, 3, ii, jj]
                    else:
                        cx[c, i, j] = nets[m, c, ii, jj]
        len_u = -0.0
        len_v = -0.0
        for c in range(2):
            for j in range(2):
                len_u += abs(cx[c, 1, j] - cx[c, 0, j])
        for c in range(2):
            for i in range(2):
                len_v += abs(cx[c, i, 1] - cx[c, i, 0])
        au = len_u >= len_v
        along[m] = au
        if au:
            k = P1
            other = Q1
        else:
            k = Q1
            other = P1
        for d in range(D):
            for o in range(other):
                for r in range(k):
                    wk[r] = nets[m, d, r, o] if au else nets[m, d, o, r]
                if au:
                    left[m, d, 0, o] = wk[0]
                    right[m, d, k - 1, o] = wk[k - 1]
                else:
                    left[m, d, o, 0] = wk[0]
                    right[m, d, o, k - 1] = wk[k - 1]
                for r in range(1, k):
                    for i in range(k - r):
                        wk[i] = (wk[i] + wk[i + 1]) * 0.5
                    if au:
                        left[m, d, r, o] = wk[0]
                        right[m, d, k - 1 - r, o] = wk[k - 1 - r]
                    else:
                        left[m, d, o, r] = wk[0]
                        right[m, d, o, k - 1 - r] = wk[k - 1 - r]
    return along, left, right


@helper
def split_at(nets, along_u, t):
    """Both sides of de Casteljau's split of nets (n, 4, p+1, q+1) at local parameters t (n,)
    along u (``along_u``) or v (``faceset_bezier._split_at``, kept left and right)."""
    n = nets.shape[0]
    D = nets.shape[1]
    P1 = nets.shape[2]
    Q1 = nets.shape[3]
    left = np.empty_like(nets)
    right = np.empty_like(nets)
    wk = np.empty(max(P1, Q1))
    for m in range(n):
        au = along_u[m]
        tt = t[m]
        if au:
            k = P1
            other = Q1
        else:
            k = Q1
            other = P1
        for d in range(D):
            for o in range(other):
                for r in range(k):
                    wk[r] = nets[m, d, r, o] if au else nets[m, d, o, r]
                if au:
                    left[m, d, 0, o] = wk[0]
                    right[m, d, k - 1, o] = wk[k - 1]
                else:
                    left[m, d, o, 0] = wk[0]
                    right[m, d, o, k - 1] = wk[k - 1]
                for r in range(1, k):
                    for i in range(k - r):
                        wk[i] = wk[i] + tt * (wk[i + 1] - wk[i])
                    if au:
                        left[m, d, r, o] = wk[0]
                        right[m, d, k - 1 - r, o] = wk[k - 1 - r]
                    else:
                        left[m, d, o, r] = wk[0]
                        right[m, d, o, k - 1 - r] = wk[k - 1 - r]
    return left, right
