# SPDX-License-Identifier: LGPL-2.1-or-later
"""Knot vectors and the per-span matrices of a NURBS direction (:mod:`.nurbs` builds surfaces
on them).

* knot vectors: OCCT's knots and multiplicities expanded, validated, periodic ones unrolled
  to the equivalent non-periodic form (:func:`unperiodize`, as OCCT's SetUNotPeriodic);
* the span matrices: the paper's power-basis form (:func:`span_matrices`, Taylor coefficients
  from "The NURBS Book" A2.3) and the Bezier extraction matrices the evaluator uses
  (:func:`bernstein_span_matrices`, by blossoming), the Bernstein rows (A1.3) and the
  derivative poles (A3.3);
* :class:`Direction`: one parameter direction's knots, spans, location and basis weights.
"""

from __future__ import annotations

from functools import cached_property
from math import factorial

import numpy as np

from ..errors import NetError
from ..numeric import clamp
from ..typing import ArrayLike, FloatArray, IntArray


# -- knot vectors -----------------------------------------------------------------------------
def expand_knots(knots: ArrayLike, mults: ArrayLike) -> FloatArray:
    """Flat knot vector from distinct knots and multiplicities (OCCT's/FreeCAD's
    ``getUKnots()`` + ``getUMultiplicities()``): each knot repeated ``mult`` times."""
    knots = np.asarray(knots, dtype=float).ravel()
    mults = np.asarray(mults).ravel()
    if len(knots) != len(mults):
        raise NetError(f"{len(knots)} knots but {len(mults)} multiplicities: they must pair up")
    for i, m in enumerate(mults):
        if not float(m).is_integer() or m < 1:
            raise NetError(f"multiplicity {i} is {m}: multiplicities are integers >= 1")
    return np.repeat(knots, np.asarray(mults, dtype=int))


def _multiplicity_runs(knots: FloatArray) -> list[tuple[int, int]]:
    """(first index, multiplicity) of each run of equal values in a flat knot vector."""
    runs: list[tuple[int, int]] = []
    for i, t in enumerate(knots):
        if runs and t == knots[runs[-1][0]]:
            runs[-1] = (runs[-1][0], runs[-1][1] + 1)
        else:
            runs.append((i, 1))
    return runs


def _validate_knots(knots: ArrayLike, degree: int, count: int, periodic: bool,
                    label: str) -> FloatArray:
    try:
        knots = np.asarray(knots, dtype=float).ravel()
    except (TypeError, ValueError):
        raise NetError(f"{label}: knots must be numbers") from None
    bad = np.flatnonzero(~np.isfinite(knots))
    if bad.size:
        raise NetError(f"{label}: knot {bad[0]} is {knots[bad[0]]}, knots must be finite")
    down = np.flatnonzero(np.diff(knots) < 0)
    if down.size:
        i = int(down[0])
        raise NetError(f"{label}: knots must be non-decreasing, knot {i + 1} ({knots[i + 1]:g}) "
                       f"< knot {i} ({knots[i]:g})")
    runs = _multiplicity_runs(knots)
    if len(runs) < 2:
        raise NetError(f"{label}: the knots span no interval (all equal to {knots[0]:g})")
    for r, (start, mult) in enumerate(runs):
        end = r in (0, len(runs) - 1)
        limit = degree if periodic or not end else degree + 1
        if mult > limit:
            where = "end" if end else "interior"
            raise NetError(f"{label}: knot {start} ({knots[start]:g}) has multiplicity {mult}, "
                           f"more than {limit} allowed for an {where} knot of degree {degree}"
                           + (" (periodic)" if periodic else ""))
    if periodic:
        first, last = runs[0][1], runs[-1][1]
        if first != last:
            raise NetError(f"{label}: periodic knots need equal first and last multiplicities, "
                           f"got {first} and {last}")
        if len(knots) != count + last:
            raise NetError(f"{label}: periodic (OCCT form) needs len(knots) = poles + last "
                           f"multiplicity = {count} + {last} = {count + last}, got {len(knots)}")
        if count < degree + 1 - first:
            # the unclamped form borrows degree + 1 - m knots from one previous period
            raise NetError(f"{label}: periodic with {count} poles: degree {degree} with end "
                           f"multiplicity {first} needs at least {degree + 1 - first} poles")
    elif len(knots) != count + degree + 1:
        raise NetError(f"{label}: len(knots) must be poles + degree + 1 = {count} + {degree} + 1 "
                       f"= {count + degree + 1}, got {len(knots)}")
    return knots


def unperiodize(knots: FloatArray, degree: int, count: int) -> tuple[FloatArray, IntArray]:
    """Non-periodic flat knots and pole indices equivalent to a periodic (OCCT-form) direction.

    One period holds the flat knots tau_0 .. tau_{n-1} (``knots[:count]``, period
    ``T = knots[-1] - knots[0]``), extended as tau_{i+n} = tau_i + T.  With the first
    multiplicity m, the unclamped form has ``a = degree + 1 - m`` knots from the previous
    period before tau_0, poles P_0 .. P_{n-1}, P_0 .. P_{a-1} (n + a of them) and n + a +
    degree + 1 knots, so its domain [t_p, t_{n+a}] is the period [tau_0, tau_0 + T].  This is
    OCCT's ``SetNotPeriodic`` (checked in the tests); "The NURBS Book" sec. 12.3 wraps poles
    the same way.  Returns (flat knots, index of the periodic pole for each new pole).
    """
    mult = _multiplicity_runs(knots)[0][1]
    n = count
    period = knots[-1] - knots[0]
    a = degree + 1 - mult
    index = np.arange(-a, n + degree + 1)
    flat = knots[np.mod(index, n)] + np.floor_divide(index, n) * period
    return flat, np.mod(np.arange(n + a), n)


# -- the span matrices ------------------------------------------------------------------------
def ders_basis_funs(span: int, u: float, degree: int, n_ders: int,
                    knots: FloatArray) -> FloatArray:
    """"The NURBS Book" A2.3: the p+1 non-zero basis functions N_{span-p..span} and their
    derivatives up to ``n_ders`` at ``u`` in [t_span, t_{span+1}): shape (n_ders+1, p+1)."""
    p = degree
    ndu = np.zeros((p + 1, p + 1))
    left = np.zeros(p + 1)
    right = np.zeros(p + 1)
    ndu[0, 0] = 1.0
    for j in range(1, p + 1):
        left[j] = u - knots[span + 1 - j]
        right[j] = knots[span + j] - u
        saved = 0.0
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]  # lower triangle: knot differences
            temp = ndu[r, j - 1] / ndu[j, r]
            ndu[r, j] = saved + right[r + 1] * temp  # upper triangle: basis functions
            saved = left[j - r] * temp
        ndu[j, j] = saved
    ders = np.zeros((n_ders + 1, p + 1))
    ders[0] = ndu[:, p]
    a = np.zeros((2, p + 1))
    for r in range(p + 1):
        s1, s2 = 0, 1
        a[0, 0] = 1.0
        for k in range(1, n_ders + 1):
            d = 0.0
            rk, pk = r - k, p - k
            if r >= k:
                a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                d = a[s2, 0] * ndu[rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                d += a[s2, j] * ndu[rk + j, pk]
            if r <= pk:
                a[s2, k] = -a[s1, k - 1] / ndu[pk + 1, r]
                d += a[s2, k] * ndu[r, pk]
            ders[k, r] = d
            s1, s2 = s2, s1
    factor = p
    for k in range(1, n_ders + 1):
        ders[k] *= factor
        factor *= p - k
    return ders


def span_matrices(knots: ArrayLike, degree: int) -> FloatArray:
    """Power-basis matrices M_k of every span k = p .. n-1: shape (n - p, p+1, p+1): the
    paper's form (the evaluator takes the better-conditioned :func:`bernstein_span_matrices`).

    ``[1 s ... s^p] @ M[k - p]`` are the basis functions N_{k-p .. k} on span k at local
    parameter s = (u - t_k) / (t_{k+1} - t_k).  Row r is the s^r coefficient (the paper's MB
    lists s^3 first: for uniform cubic knots ``M[k] == MB[::-1]``).  Empty spans (repeated
    knots) get zero matrices; they are never located.
    """
    knots = np.asarray(knots, dtype=float)
    p = int(degree)
    count = len(knots) - p - 1
    out = np.zeros((count - p, p + 1, p + 1))
    scale = np.array([1.0 / factorial(r) for r in range(p + 1)])
    for k in range(p, count):
        h = knots[k + 1] - knots[k]
        if h > 0:
            ders = ders_basis_funs(k, knots[k], p, p, knots)
            out[k - p] = ders * (scale * h ** np.arange(p + 1))[:, None]
    return out


def bernstein_span_matrices(knots: ArrayLike, degree: int) -> FloatArray:
    """Bezier extraction matrices E_k of every span k = p .. n-1: shape (n - p, p+1, p+1).

    ``[B_{0,p}(s) ... B_{p,p}(s)] @ E[k - p]`` are the basis functions N_{k-p .. k} on span k
    at local parameter s = (u - t_k) / (t_{k+1} - t_k); ``E[k - p] @ P[k-p .. k]`` are the
    span's Bezier control points.  Row i is the blossom of the span's basis functions at
    (t_k repeated p - i times, t_{k+1} repeated i times), by de Boor's triangle with the i-th
    argument list: every weight ``(x - t_j) / (t_{j+p+1-r} - t_j)`` lies in [0, 1], so each
    entry is a convex combination and keeps full precision at any degree.  Empty spans
    (repeated knots) get zero matrices; they are never located.
    """
    knots = np.asarray(knots, dtype=float)
    p = int(degree)
    count = len(knots) - p - 1
    out = np.zeros((count - p, p + 1, p + 1))
    k = np.arange(p, count)
    k = k[knots[k + 1] > knots[k]]
    if not len(k):
        return out
    lo, hi = knots[k], knots[k + 1]
    j = np.arange(p + 1)
    for i in range(p + 1):
        d = np.broadcast_to(np.eye(p + 1), (len(k), p + 1, p + 1)).copy()  # (span, j, column)
        for r in range(1, p + 1):
            x = lo if r <= p - i else hi  # the blossom's r-th argument
            first = k[:, None] - p + j[None, r:]  # global index of the poles j = r .. p
            left = knots[first]
            alpha = (x[:, None] - left) / (knots[first + p + 1 - r] - left)
            d[:, r:] = (1.0 - alpha)[..., None] * d[:, r - 1 : -1] + alpha[..., None] * d[:, r:]
        out[k - p, i] = d[:, p]
    return out


def derivative_poles(poles: FloatArray, knots: FloatArray, degree: int,
                     axis: int = 0) -> FloatArray:
    """Poles of the first derivative of a B-spline along ``axis`` of ``poles``: degree p - 1 on
    ``knots[1:-1]``, ``Q_i = p (P_{i+1} - P_i) / (t_{i+p+1} - t_{i+1})`` ("The NURBS Book"
    eq. 3.16, A3.3); a zero-length support (a knot of multiplicity p + 1) gives 0."""
    p = int(degree)
    n = poles.shape[axis]
    support = knots[p + 1 : p + n] - knots[1:n]
    factor = np.where(support > 0, p / np.where(support > 0, support, 1.0), 0.0)
    shape = [1] * poles.ndim
    shape[axis] = n - 1
    return np.diff(poles, axis=axis) * factor.reshape(shape)


def bernstein_rows(s: FloatArray, degree: int) -> FloatArray:
    """The Bernstein polynomials B_{0..p,p}(s): shape (p+1, m), by de Casteljau's triangle
    ("The NURBS Book" A1.3, raised in place one degree at a time: sums of non-negative
    terms)."""
    s = np.asarray(s, dtype=float)
    t = 1.0 - s
    rows = np.zeros((degree + 1, len(s)))
    rows[0] = 1.0
    for n in range(1, degree + 1):  # rows[0 .. n-1] (degree n-1) to degree n
        rows[n] = s * rows[n - 1]
        for i in range(n - 1, 0, -1):
            rows[i] *= t
            rows[i] += s * rows[i - 1]
        rows[0] *= t
    return rows


# -- the direction: knots, spans and location -------------------------------------------------
class Direction:
    """One parameter direction: its non-periodic flat knots, degree, spans and the extraction
    matrices of its derivatives (``matrices_for(order)``: the B-spline of degree p - order on
    ``knots[order:-order]``, whose spans are the same intervals with the same indices)."""

    def __init__(self, knots: FloatArray, degree: int):
        self.knots = knots
        self.degree = degree
        self._matrices: dict[int, FloatArray] = {}

    def matrices_for(self, order: int) -> FloatArray:
        """(count - p, p-order+1, p-order+1) extraction matrices of the order-th derivative."""
        if order not in self._matrices:
            knots = self.knots[order : len(self.knots) - order]
            self._matrices[order] = bernstein_span_matrices(knots, self.degree - order)
        return self._matrices[order]

    @property
    def matrices(self) -> FloatArray:
        """(count - p, p+1, p+1): Bezier extraction matrices of the spans."""
        return self.matrices_for(0)

    def differentiate(self, net: FloatArray, order: int, axis: int) -> FloatArray:
        """The poles of ``net`` differentiated ``order`` times along ``axis`` (this direction)."""
        for k in range(order):
            net = derivative_poles(net, self.knots[k : len(self.knots) - k], self.degree - k,
                                   axis)
        return net

    @property
    def count(self) -> int:
        return len(self.knots) - self.degree - 1

    @cached_property
    def domain(self) -> tuple[float, float]:
        return float(self.knots[self.degree]), float(self.knots[self.count])

    @cached_property
    def nonempty(self) -> IntArray:
        """Span indices (k - p) of the spans of non-zero length."""
        k = np.arange(self.degree, self.count)
        return np.flatnonzero(self.knots[k + 1] > self.knots[k])

    def locate(self, t: FloatArray) -> tuple[IntArray, FloatArray]:
        """Span index (k - p, also the first pole of every derivative's net) and local
        parameter s per parameter."""
        p = self.degree
        k = np.searchsorted(self.knots, t, side="right") - 1
        span = clamp(k - p, self.nonempty[0], self.nonempty[-1])
        # a parameter inside an empty span (only possible by clipping) moves to a real one
        lo = self.knots[span + p]
        h = self.knots[span + p + 1] - lo
        return span, clamp((t - lo) / h, 0.0, 1.0)

    def weights(self, t: FloatArray, order: int) -> tuple[IntArray, FloatArray]:
        """First pole index and the p-order+1 basis values of the order-th derivative's
        B-spline per parameter (they weigh the poles of ``differentiate(net, order)``)."""
        span, s = self.locate(t)
        rows = bernstein_rows(s, self.degree - order).T
        return span, np.einsum("ma,mal->ml", rows, self.matrices_for(order)[span])
