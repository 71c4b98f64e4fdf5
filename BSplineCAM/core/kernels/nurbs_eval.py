# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of :class:`~BSplineCAM.core.geometry.nurbs.NurbsSurface`'s scattered
evaluation: every point's spans, local parameters, Bernstein rows and patch sums, for all the
derivative orders asked for, in one compiled call (:data:`scattered`); the quotient rule of
rational surfaces over all orders in one (:data:`rational`); the parameters' domain check and
clamping in one (:data:`check`).

The loop functions here take plain contiguous arrays (float64 and int64) and integers; the
surface passes its flat knots, the first and last non-empty span of each direction and its
scatter tables of all the orders asked for, concatenated into one flat array with one offset
per order (:func:`pack_tables`).  The arithmetic is that of the numpy engine
(:meth:`Direction.locate <BSplineCAM.core.geometry.nurbs_spans.Direction.locate>`,
:func:`~BSplineCAM.core.geometry.nurbs_spans.bernstein_rows` and the two sums of
``NurbsSurface._homogeneous_scattered``): the spans and local parameters are the same bit for
bit, the Bernstein rows come from the same de Casteljau triangle in the same operation order,
and the sums and quotients run over the same terms in the same order (``np.einsum`` may sum
in another order: the last bits may then differ).
"""

from __future__ import annotations

import numpy as np

from . import Kernel, helper


@helper
def _scattered_loops(knots_u, p, first_u, last_u, knots_v, q, first_v, last_v, spans_v,
                     orders, offsets, tables, d, u, w):
    """Homogeneous partial derivatives at the scattered points (u, w): (len(orders), m, d),
    with the spans (2, m) and local parameters (2, m) found along u and v.

    Locating, as ``Direction.locate``: k is the last knot index with ``knots[k] <= t``
    (numpy's ``searchsorted(side="right") - 1``), the span k - degree clamped to
    [first, last] (the non-empty spans, so the domain's last span is closed), the local
    parameter ``(t - t_k) / (t_{k+1} - t_k)`` clamped to [0, 1].  The Bernstein rows of every
    degree come from one de Casteljau triangle per direction, raised in place in the operation
    order of ``bernstein_rows`` (whose degree-n rows are this triangle after step n).  Order
    k = (a, b) reads its scatter table (spans_u * spans_v, q-b+1, (p-a+1) d) from
    ``tables[offsets[k]:]``; each point sums its patch row against the row of degree q - b in
    t, then of degree p - a in s.  Orders above the degrees (a > p or b > q) are zero."""
    m = u.shape[0]
    count = orders.shape[0]
    top = max(p, q)
    spans = np.empty((2, m), dtype=np.int64)
    local = np.empty((2, m), dtype=np.float64)
    for axis in range(2):
        if axis == 0:
            knots, degree, first, last, par = knots_u, p, first_u, last_u, u
        else:
            knots, degree, first, last, par = knots_v, q, first_v, last_v, w
        n = knots.shape[0]
        for j in range(m):
            x = par[j]
            lo = 0
            hi = n
            while lo < hi:  # the first index with knots[index] > x
                mid = (lo + hi) >> 1
                if knots[mid] <= x:
                    lo = mid + 1
                else:
                    hi = mid
            k = lo - 1 - degree
            k = max(k, first)
            k = min(k, last)
            left = knots[k + degree]
            s = (x - left) / (knots[k + degree + 1] - left)
            if not s > 0.0 and s == s:  # np.maximum(s, 0.0), then np.minimum(s, 1.0)
                s = 0.0
            if not s < 1.0 and s == s:
                s = 1.0
            spans[axis, j] = k
            local[axis, j] = s
    out = np.zeros((count, m, d))
    rows = np.empty(top + 1)
    tri = np.zeros((2, top + 1, top + 1))  # tri[axis, n, i] = B_{i,n}
    for j in range(m):
        for axis in range(2):
            degree = p if axis == 0 else q
            s = local[axis, j]
            t = 1.0 - s
            rows[0] = 1.0
            tri[axis, 0, 0] = 1.0
            for n in range(1, degree + 1):
                rows[n] = s * rows[n - 1]
                for i in range(n - 1, 0, -1):
                    rows[i] = rows[i] * t + s * rows[i - 1]
                rows[0] = rows[0] * t
                for i in range(n + 1):
                    tri[axis, n, i] = rows[i]
        row = spans[0, j] * spans_v + spans[1, j]
        for k in range(count):
            da = p - orders[k, 0]
            db = q - orders[k, 1]
            if da < 0 or db < 0:  # above the degree: zero
                continue
            width = (da + 1) * d
            base = offsets[k] + row * (db + 1) * width
            for c in range(d):  # over s of the sums over t: no stores in the loops
                total = 0.0
                for a in range(da + 1):
                    at = base + a * d + c
                    acc = 0.0
                    for b in range(db + 1):
                        acc += tri[1, db, b] * tables[at + b * width]
                    total += tri[0, da, a] * acc
                out[k, j, c] = total
    return out, spans, local


@helper
def _rational_loops(hom, orders, index):
    """Derivatives of S = A / w from the homogeneous ones ``hom`` (len(orders), m, 4) of
    (A, w): (len(orders), m, 3), by the quotient rule in the operation order of
    ``nurbs._rational`` ("The NURBS Book" A4.4, eq. 4.20).

    ``orders`` (k, 2) must hold every (i, j) <= each of its orders, each after those it
    needs (lexicographic order does); ``index[a, b]`` is the row of order (a, b)."""
    count = orders.shape[0]
    m = hom.shape[1]
    top = 0
    for k in range(count):
        top = max(top, orders[k, 0], orders[k, 1])
    binom = np.zeros((top + 1, top + 1))  # Pascal's triangle
    for n in range(top + 1):
        binom[n, 0] = 1.0
        for i in range(1, n + 1):
            binom[n, i] = binom[n - 1, i - 1] + binom[n - 1, i]
    out = np.empty((count, m, 3))
    i00 = index[0, 0]
    for j in range(m):
        w0 = hom[i00, j, 3]
        for k in range(count):
            a = orders[k, 0]
            b = orders[k, 1]
            for c in range(3):
                v = hom[k, j, c]
                for jj in range(1, b + 1):
                    v -= binom[b, jj] * hom[index[0, jj], j, 3] * out[index[a, b - jj], j, c]
                for i in range(1, a + 1):
                    v -= binom[a, i] * hom[index[i, 0], j, 3] * out[index[a - i, b], j, c]
                    for jj in range(1, b + 1):
                        v -= (binom[a, i] * binom[b, jj] * hom[index[i, jj], j, 3]
                              * out[index[a - i, b - jj], j, c])
                out[k, j, c] = v / w0
    return out


@helper
def _check_loops(u, w, lo_u, hi_u, tol_u, lo_v, hi_v, tol_v):
    """u and w clamped to their domains [lo, hi] (as ``numeric.clamp``), and whether every
    value is finite and within [lo - tol, hi + tol]."""
    ok = True
    clamped_u = np.empty(u.shape[0])
    clamped_w = np.empty(w.shape[0])
    for axis in range(2):
        if axis == 0:
            values, out, lo, hi, tol = u, clamped_u, lo_u, hi_u, tol_u
        else:
            values, out, lo, hi, tol = w, clamped_w, lo_v, hi_v, tol_v
        below = lo - tol
        above = hi + tol
        for i in range(values.shape[0]):
            x = values[i]
            if not (x >= below and x <= above):  # NaN and infinities fail too
                ok = False
            if not x > lo and x == x:  # np.maximum(x, lo), then np.minimum(x, hi)
                x = lo
            if not x < hi and x == x:
                x = hi
            out[i] = x
    return clamped_u, clamped_w, ok


def pack_tables(tables) -> tuple[np.ndarray, np.ndarray]:
    """One flat float64 array of the scatter ``tables`` (each C-contiguous) end to end, and
    the int64 offset of each in it."""
    sizes = [t.size for t in tables]
    offsets = np.zeros(len(tables), dtype=np.int64)
    if len(tables) > 1:
        offsets[1:] = np.cumsum(sizes[:-1])
    flat = np.concatenate([np.zeros(0)] + [np.ascontiguousarray(t, dtype=np.float64).ravel()
                                           for t in tables])
    return flat, offsets


#: the compiled twins (made at their first call under the numba engine)
scattered = Kernel(_scattered_loops)
rational = Kernel(_rational_loops)
check = Kernel(_check_loops)

__all__ = ["check", "pack_tables", "rational", "scattered"]
