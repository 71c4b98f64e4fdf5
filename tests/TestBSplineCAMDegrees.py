# SPDX-License-Identifier: LGPL-2.1-or-later
"""NurbsSurface at degrees 1 to 25 against Cox–de Boor in exact rational arithmetic.

The reference is independent of the code under test: the B-spline basis by its recursive
definition ("The NURBS Book", Piegl & Tiller, eq. 2.5, half-open spans, so at an interior knot
the span to its right, at the domain's upper end the last span) and its derivatives by eq. 2.9,
all in :class:`fractions.Fraction` from the exact values of the float knots, poles, weights and
parameters; rational surfaces by the quotient rule (eq. 4.20) on the exact homogeneous sums.
Periodic directions (OCCT's form) are evaluated by wrapping the basis: the knots of one period
are continued by the period in both directions and basis function j multiplies pole
(j + p + 1 - m) mod n.  Bezier patches are evaluated by de Casteljau's algorithm, exactly.

Criterion.  With size the diagonal of the poles' bounding box (mm) and R_ij the rational basis
functions (N_i N_j w_ij / sum N N w), a partial derivative of order (a, b), a + b <= 2, passes
where

    |S^(a,b)_code - S^(a,b)_exact| <= 1e-12 * size * sum_ij |R^(a,b)_ij(u, w)|.

For points the factor is 1, so 1e-12 of the size.  For a derivative it is the norm of the linear
map from the (centred) poles to that derivative at that parameter: the largest value the
derivative can take there for any net of that size.  It carries the parameter scaling (about
(p / L)^k for derivative order k, L the length of the knot span for a Bezier span and of the
basis functions' support when they cover several spans), the non-uniform spacing and the
weights, and bounds what an evaluator backward stable in the poles gets wrong, about 1e-16 of
it: the textbook floating-point evaluator (A2.3 DersBasisFuns, A4.4 RatSurfaceDerivs) stays
within 1e-14 of it on every case here.  Where a derivative vanishes for every net (a second
derivative along a direction of degree 1) its factor is the square of the first derivative's.
A bound of 1e-12 * size / h^k per span length h alone would leave the textbook evaluator no
room at degree 25 (it lacks the p^k) and allow losses of (support / h)^k on short spans.

Unit normals pass within 1e-12 of the exact Su x Sw normalised, at the points where that normal
is well-conditioned: (|Su| b_w + b_u |Sw|) / |Su x Sw| <= 1e3, with b_u, b_w the derivative
bounds above (the normal moves by at most that times the tangents' relative errors).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction
from math import comb, lcm, pi

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from BSplineCAM.core.errors import NetError
from BSplineCAM.core.geometry.nurbs import NurbsSurface

#: Bound on |error| in units of size * sum |R^(a,b)| (see the module docstring).
LIMIT = 1e-12

#: Normals are checked where their condition (|Su| b_w + b_u |Sw|) / |Su x Sw| is at most this,
#: b_u and b_w the bounds of Su and Sw (size * sum |R^(1,0)|, size * sum |R^(0,1)|): nearly
#: every point of the cases here.
NORMAL_CONDITION = 1e3

ORDERS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
FIELDS = ("point", "su", "sw", "suu", "suw", "sww")


# --- the exact reference -------------------------------------------------------------------------
def _as_integers(values) -> tuple[list[int], int]:
    """Fractions as integer numerators over one common denominator."""
    den = 1
    for v in values:
        den = lcm(den, v.denominator)
    return [v.numerator * (den // v.denominator) for v in values], den


class ExactDirection:
    """One parameter direction: flat knots (for a periodic one, the knots of one period in OCCT's
    form, continued by the period), degree and pole count; basis values cached per parameter."""

    def __init__(self, knots, degree: int, count: int, periodic: bool):
        self.knots = [Fraction(float(t)) for t in knots]
        self.degree, self.count, self.periodic = degree, count, periodic
        self.period = self.knots[-1] - self.knots[0]
        self.first, self.stop = (0, count) if periodic else (degree, count)
        # OCCT numbers periodic poles so that pole 0 goes with the basis function that starts
        # p + 1 - m knots before the first (m its multiplicity): with m = p the surface starts
        # at pole 0, as a clamped one does.
        first_mult = sum(1 for t in self.knots if t == self.knots[0])
        self.shift = degree + 1 - first_mult if periodic else 0
        self.domain = (self.knot(self.first), self.knot(self.stop))
        self._cache: dict = {}

    def knot(self, j: int) -> Fraction:
        if not self.periodic:
            return self.knots[j]
        turns, r = divmod(j, self.count)
        return self.knots[r] + turns * self.period

    def pole(self, j: int) -> int:
        return (j + self.shift) % self.count if self.periodic else j

    def spans(self) -> list[int]:
        """Indices k of the non-empty spans [t_k, t_k+1) of the domain."""
        return [k for k in range(self.first, self.stop) if self.knot(k + 1) > self.knot(k)]

    def span(self, u: Fraction) -> int:
        """The span of eq. 2.5's half-open intervals holding u; the last one at the upper end."""
        inside = [k for k in self.spans() if self.knot(k) <= u]
        assert inside and self.domain[0] <= u <= self.domain[1], (u, self.domain)
        return inside[-1]

    def basis(self, u: Fraction):
        """(k, ders): ders[r][l] is d^r/du^r N_{k-p+l, p}(u), r = 0, 1, 2, exact."""
        if u not in self._cache:
            self._cache[u] = self._basis(u)
        return self._cache[u]

    def basis_integers(self, u: Fraction):
        """(k, ders, den): the exact basis of :meth:`basis` as integers over den."""
        key = ("int", u)
        if key not in self._cache:
            k, ders = self.basis(u)
            ints, den = _as_integers([x for d in ders for x in d])
            p1 = self.degree + 1
            self._cache[key] = (k, [ints[r * p1:(r + 1) * p1] for r in range(3)], den)
        return self._cache[key]

    def _basis(self, u: Fraction):
        p = self.degree
        k = self.span(u)
        t = {j: self.knot(j) for j in range(k - p, k + p + 2)}
        # eq. 2.5 level by level; level d holds N_{k-d .. k, d}, the others vanish on the span
        levels = [[Fraction(1)]]
        for d in range(1, p + 1):
            prev, cur = levels[-1], []
            for j in range(d + 1):
                i = k - d + j
                value = Fraction(0)
                if j >= 1 and t[i + d] > t[i]:
                    value += (u - t[i]) / (t[i + d] - t[i]) * prev[j - 1]
                if j < d and t[i + d + 1] > t[i + 1]:
                    value += (t[i + d + 1] - u) / (t[i + d + 1] - t[i + 1]) * prev[j]
                cur.append(value)
            levels.append(cur)

        def differentiate(prev, d):
            """eq. 2.9: N^(r)_{i,d} = d (N^(r-1)_{i,d-1} / (t_{i+d} - t_i)
            - N^(r-1)_{i+1,d-1} / (t_{i+d+1} - t_{i+1})), 0/0 = 0."""
            out = []
            for j in range(d + 1):
                i = k - d + j
                value = Fraction(0)
                if j >= 1 and t[i + d] > t[i]:
                    value += prev[j - 1] / (t[i + d] - t[i])
                if j < d and t[i + d + 1] > t[i + 1]:
                    value -= prev[j] / (t[i + d + 1] - t[i + 1])
                out.append(d * value)
            return out

        ders = []
        for r in range(3):
            if r > p:
                ders.append([Fraction(0)] * (p + 1))
                continue
            values = levels[p - r]
            for d in range(p - r + 1, p + 1):
                values = differentiate(values, d)
            ders.append(values)
        return k, ders


class ExactSurface:
    """Points, first and second partial derivatives, normals and basis norms, exactly: each
    value is an integer vector over an integer denominator (to float by Python's correctly
    rounded integer division)."""

    def __init__(self, poles, knots_u, knots_v, degree_u, degree_v, weights=None,
                 periodic_u=False, periodic_v=False, **_):
        poles = np.asarray(poles, dtype=float)
        n, m = poles.shape[:2]
        self.u = ExactDirection(knots_u, degree_u, n, periodic_u)
        self.v = ExactDirection(knots_v, degree_v, m, periodic_v)
        self.rational = weights is not None
        self.weights = np.ones((n, m)) if weights is None else np.asarray(weights, dtype=float)
        extent = poles.reshape(-1, 3).max(axis=0) - poles.reshape(-1, 3).min(axis=0)
        self.size = float(np.linalg.norm(extent))
        coords = []  # homogeneous poles (w x, w y, w z, w)
        for i in range(n):
            for j in range(m):
                w = Fraction(float(self.weights[i, j]))
                coords += [Fraction(float(c)) * w for c in poles[i, j]] + [w]
        ints, self.den = _as_integers(coords)
        self.hom = [[ints[(i * m + j) * 4:(i * m + j + 1) * 4] for j in range(m)]
                    for i in range(n)]
        self._rows: dict = {}

    def _row_sums(self, w: Fraction):
        """rows[b][i] = sum_j N^(b)_j(w) H_ij for every pole row i, over the returned
        denominator (times self.den)."""
        if w not in self._rows:
            k, ders, den = self.v.basis_integers(w)
            q = self.v.degree
            cols = [self.v.pole(k - q + e) for e in range(q + 1)]
            rows = [[[sum(c * row[col][x] for c, col in zip(ders[b], cols)) for x in range(4)]
                     for row in self.hom] for b in range(3)]
            self._rows[w] = (rows, den)
        return self._rows[w]

    def homogeneous(self, u: Fraction, w: Fraction, orders) -> dict:
        """{(a, b): [X, Y, Z, W]}: sum_ij N^(a)_i(u) N^(b)_j(w) (w x, w y, w z, w)_ij as integers
        over one common denominator (which cancels in every quotient below)."""
        k, ders, _ = self.u.basis_integers(u)
        rows, _ = self._row_sums(w)
        p = self.u.degree
        lines = [self.u.pole(k - p + e) for e in range(p + 1)]
        return {(a, b): [sum(c * rows[b][i][x] for c, i in zip(ders[a], lines))
                         for x in range(4)] for a, b in orders}

    def denominator(self, u: Fraction, w: Fraction) -> int:
        return self.u.basis_integers(u)[2] * self.v.basis_integers(w)[2] * self.den

    def evaluate(self, u: Fraction, w: Fraction, orders=ORDERS) -> dict:
        """{(a, b): (numerators of x, y, z, denominator)} of S = A / W and its partial
        derivatives by the quotient rule (eq. 4.20) written over powers of W:
        S_i = N_i / W^2 with N_i = A_i W - W_i A, and
        S_ij = (A_ij W^2 - W_ij A W - W_i N_j - W_j N_i) / W^3."""
        needed = sorted({(a, b) for da, db in orders for a in range(da + 1)
                         for b in range(db + 1)})
        h = self.homogeneous(u, w, needed)
        wt = {o: v[3] for o, v in h.items()}
        a, w0 = h[0, 0][:3], wt[0, 0]
        first = {o: [x * w0 - wt[o] * y for x, y in zip(h[o][:3], a)]
                 for o in ((1, 0), (0, 1)) if o in h}
        out = {}
        for o in orders:
            if o == (0, 0):
                out[o] = (a, w0)
            elif o in first:
                out[o] = (first[o], w0**2)
            else:
                i, j = {(2, 0): ((1, 0), (1, 0)), (1, 1): ((1, 0), (0, 1)),
                        (0, 2): ((0, 1), (0, 1))}[o]
                out[o] = ([x * w0**2 - wt[o] * y * w0 - wt[i] * nj - wt[j] * ni
                           for x, y, ni, nj in zip(h[o][:3], a, first[i], first[j])], w0**3)
        return out

    def normal(self, u: Fraction, w: Fraction) -> np.ndarray:
        """Su x Sw exactly (N_u x N_w / W^4), then as floats (not normalised)."""
        values = self.evaluate(u, w, ((1, 0), (0, 1)))
        (nu, den), (nw, _) = values[1, 0], values[0, 1]
        cross = (nu[1] * nw[2] - nu[2] * nw[1], nu[2] * nw[0] - nu[0] * nw[2],
                 nu[0] * nw[1] - nu[1] * nw[0])
        return np.array([c / den**2 for c in cross])

    def basis_norms(self, u: Fraction, w: Fraction) -> dict:
        """{(a, b): sum_ij |R^(a,b)_ij(u, w)|} (a tolerance factor, so in floats from the exact
        basis)."""
        ku, du, den_u = self.u.basis_integers(u)
        kv, dv, den_v = self.v.basis_integers(w)
        nu = [np.array([x / den_u for x in d]) for d in du]
        nv = [np.array([x / den_v for x in d]) for d in dv]
        if not self.rational:
            norms = {(a, b): float(np.abs(nu[a]).sum() * np.abs(nv[b]).sum()) for a, b in ORDERS}
            # a second derivative along a direction of degree 1 vanishes for every net: its
            # bound is then the square of the first derivative's (its unit)
            for second, first in (((2, 0), (1, 0)), ((0, 2), (0, 1))):
                norms[second] = norms[second] or norms[first] ** 2
            return norms
        p, q = self.u.degree, self.v.degree
        rows = [self.u.pole(ku - p + e) for e in range(p + 1)]
        cols = [self.v.pole(kv - q + e) for e in range(q + 1)]
        wts = self.weights[np.ix_(rows, cols)]
        h = {(a, b): nu[a][:, None] * nv[b][None, :] * wts for a, b in ORDERS}
        den = self.denominator(u, w)
        total = {o: v[3] / den for o, v in self.homogeneous(u, w, ORDERS).items()}
        r: dict = {}
        for a, b in ORDERS:  # the quotient rule again, per basis function
            value = h[a, b].copy()
            for i in range(a + 1):
                for j in range(b + 1):
                    if i or j:
                        value -= comb(a, i) * comb(b, j) * total[i, j] * r[a - i, b - j]
            r[a, b] = value / total[0, 0]
        return {o: float(np.abs(v).sum()) for o, v in r.items()}


def de_casteljau(points, weights, s: Fraction, t: Fraction) -> tuple[list[int], int]:
    """Exact point of the rational Bezier patch (points (p+1, q+1, 3), weights (p+1, q+1)) at
    local (s, t): de Casteljau ("The NURBS Book" A1.5) on the homogeneous net, in integers.
    Returns the numerators of x, y, z and their denominator."""
    p1, q1 = weights.shape
    hom = []
    for a in range(p1):
        for b in range(q1):
            w = Fraction(float(weights[a, b]))
            hom += [Fraction(float(c)) * w for c in points[a, b]] + [w]
    ints, _ = _as_integers(hom)
    net = [[ints[(a * q1 + b) * 4:(a * q1 + b + 1) * 4] for b in range(q1)] for a in range(p1)]

    def reduce(column, x: Fraction):
        num, d = x.numerator, x.denominator
        level = column
        while len(level) > 1:  # b_i <- (1 - x) b_i + x b_{i+1}, times d at every level
            level = [[(d - num) * lo + num * hi for lo, hi in zip(level[i], level[i + 1])]
                     for i in range(len(level) - 1)]
        return level[0]

    point = reduce([reduce(net[a], t) for a in range(p1)], s)
    return point[:3], point[3]


# --- the surfaces ------------------------------------------------------------------------------
KINDS = ("clamped", "nonuniform", "multiple", "unclamped", "periodic")
PLACEMENTS = ((0.0, 1.0), (-3.0, 7.5), (12.25, 0.2), (-40.0, 100.0))


def direction_knots(kind: str, p: int, rng: np.random.Generator) -> tuple[np.ndarray, int]:
    """(flat knots, pole count) of one direction: clamped (1 or 2 uniform spans), non-uniform
    clamped (spans 30x apart in length), interior knots of multiplicity p and 1..p, unclamped
    (simple and double end knots) or periodic in OCCT's form (end multiplicity 1, p/2 or p); on
    a random offset and scale of the parameter."""
    offset, scale = PLACEMENTS[rng.integers(len(PLACEMENTS))]

    def place(values):
        return offset + scale * np.asarray(values, dtype=float)

    def spread(count):
        gaps = 10.0 ** rng.uniform(-1.5, 0.0, count)
        return np.concatenate([[0.0], np.cumsum(gaps)]) / gaps.sum()

    if kind == "clamped":
        spans = int(rng.integers(1, 3))
        values, mults = np.linspace(0, 1, spans + 1), [p + 1] + [1] * (spans - 1) + [p + 1]
    elif kind == "nonuniform":
        values, mults = spread(3), [p + 1, 1, 1, p + 1]
    elif kind == "multiple":
        values, mults = spread(3), [p + 1, p, int(rng.integers(1, p + 1)), p + 1]
    elif kind == "unclamped":
        count = p + 1 + int(rng.integers(1, 3))
        flat = place(spread(count + p))
        if p >= 2:
            flat[1] = flat[0]  # a double end knot, still unclamped
        return flat, count
    else:
        end = int(rng.choice(sorted({1, max(1, p // 2), p})))
        spans = max(2, 3 - end, p + 2 - 2 * end)
        values, mults = spread(spans), [end] + [1] * (spans - 1) + [end]
        flat = place(np.repeat(values, mults))
        return flat, len(flat) - end
    flat = place(np.repeat(values, mults))
    return flat, len(flat) - p - 1


def make_poles(n: int, m: int, periodic_u: bool, periodic_v: bool,
               rng: np.random.Generator) -> np.ndarray:
    """A smooth net with 0.8 mm of noise: a height field, a cylinder about the periodic
    direction, or a torus when both are periodic (about 60 mm across)."""
    a = 2 * pi * np.arange(n) / n if periodic_u else np.linspace(0.0, 1.0, n)
    b = 2 * pi * np.arange(m) / m if periodic_v else np.linspace(0.0, 1.0, m)
    a, b = np.meshgrid(a, b, indexing="ij")
    if periodic_u and periodic_v:
        ring = 30.0 + 10.0 * np.cos(b)
        net = np.stack([ring * np.cos(a), ring * np.sin(a), 10.0 * np.sin(b)], axis=-1)
    elif periodic_u:
        net = np.stack([25.0 * np.cos(a), 25.0 * np.sin(a), 40.0 * b], axis=-1)
    elif periodic_v:
        net = np.stack([40.0 * a, 25.0 * np.cos(b), 25.0 * np.sin(b)], axis=-1)
    else:
        net = np.stack([60.0 * a, 40.0 * b, 8.0 * np.sin(3 * a) * np.cos(2 * b)], axis=-1)
    return net + rng.normal(scale=0.8, size=net.shape)


@dataclass(frozen=True)
class Case:
    degree_u: int
    degree_v: int
    kind_u: str
    kind_v: str
    rational: bool
    seed: int = 0

    def __str__(self) -> str:
        kind = "rational" if self.rational else "polynomial"
        return f"{self.degree_u}x{self.degree_v}-{self.kind_u}-{self.kind_v}-{kind}"

    def arguments(self) -> dict:
        rng = np.random.default_rng([self.degree_u, self.degree_v, self.seed,
                                     KINDS.index(self.kind_u), KINDS.index(self.kind_v)])
        ku, n = direction_knots(self.kind_u, self.degree_u, rng)
        kv, m = direction_knots(self.kind_v, self.degree_v, rng)
        pu, pv = self.kind_u == "periodic", self.kind_v == "periodic"
        poles = make_poles(n, m, pu, pv, rng)
        weights = 10.0 ** rng.uniform(-1.0, 1.0, (n, m)) if self.rational else None
        return dict(poles=poles, knots_u=ku, knots_v=kv, degree_u=self.degree_u,
                    degree_v=self.degree_v, weights=weights, periodic_u=pu, periodic_v=pv,
                    name=str(self))


def corner_blend() -> dict:
    """A degree 2 x 14 rational blend like OCCT's rolling-ball fillets: quarter circles of
    radius about 3 mm (weights 1, cos 45 deg, 1) swept along a curved 8 mm spine, 3 x 41
    poles, interior knots non-uniform with two double ones, placed away from the origin."""
    q, m = 14, 41
    interior = np.sort(np.random.default_rng(41).uniform(0.0, 8.3, m - q - 1 - 2))
    interior = np.sort(np.r_[interior, interior[5], interior[17]])
    kv = np.r_[np.zeros(q + 1), interior, np.full(q + 1, 8.3)]
    ku = np.r_[np.zeros(3), np.full(3, pi / 2)]
    v = np.linspace(0.0, 1.0, m)
    spine = np.stack([8.0 * v, 1.5 * np.sin(pi * v), 0.5 * v**2], axis=-1)
    radius = (3.0 + 0.4 * np.sin(2 * pi * v))[:, None]
    e1, e2 = np.array([0.0, 0.0, 1.0]), np.array([0.0, -1.0, 0.0])
    poles = np.stack([spine + radius * e1, spine + radius * (e1 + e2), spine + radius * e2])
    poles += np.array([120.0, -35.0, 40.0])
    weights = np.ones((3, m))
    weights[1] = np.cos(pi / 4)
    return dict(poles=poles, knots_u=ku, knots_v=kv, degree_u=2, degree_v=q, weights=weights,
                name="corner blend")


# --- the checks --------------------------------------------------------------------------------
def parameters(direction: ExactDirection, rng: np.random.Generator, knots: int = 1,
               inside: int = 2) -> np.ndarray:
    """Both ends of the domain, ``knots`` interior knots and ``inside`` random parameters."""
    lo, hi = (float(x) for x in direction.domain)
    interior = sorted({float(direction.knot(k)) for k in direction.spans()} - {lo, hi})
    chosen = list(rng.choice(interior, min(knots, len(interior)), replace=False)) \
        if interior else []
    return np.array([lo, hi, *chosen, *rng.uniform(lo, hi, inside)])


def assert_within(label: str, actual, expected, bound, us, ws) -> None:
    """|actual - expected| <= LIMIT * bound per point (bound: size * sum |R|, shape (nu, nw))."""
    error = np.linalg.norm(np.asarray(actual, dtype=float) - expected, axis=-1)
    ratio = error / bound
    worst = np.unravel_index(int(np.argmax(ratio)), ratio.shape)
    assert ratio[worst] <= LIMIT, (
        f"{label}: error {ratio[worst]:.2e} of size * sum|R| (limit {LIMIT:g}) at "
        f"u={us[worst[0]]!r}, w={ws[worst[1]]!r}")


def check_surface(args: dict, knots: int = 1, inside: int = 2, patches: int | None = 6) -> None:
    """Every evaluation of the public API on a grid of parameters against the exact reference;
    the Bezier patches (``patches`` of them, all if None) at two local parameters each."""
    surface = NurbsSurface(**args)
    ref = ExactSurface(**args)
    label = args["name"]
    rng = np.random.default_rng(len(args["knots_u"]) * 7919 + len(args["knots_v"]))
    us = parameters(ref.u, rng, knots, inside)
    ws = parameters(ref.v, rng, knots, inside)
    (u0, u1), (v0, v1) = surface.domain
    assert (u0, u1, v0, v1) == pytest.approx([float(x) for x in (*ref.u.domain, *ref.v.domain)],
                                             rel=1e-15, abs=1e-15)

    shape = (len(us), len(ws))
    expected = {o: np.empty(shape + (3,)) for o in ORDERS}
    bound = {o: np.empty(shape) for o in ORDERS}
    normal = np.full(shape + (3,), np.nan)
    for i, u in enumerate(us):
        for j, w in enumerate(ws):
            fu, fw = Fraction(float(u)), Fraction(float(w))
            exact = ref.evaluate(fu, fw)
            norms = ref.basis_norms(fu, fw)
            for o in ORDERS:
                numerators, den = exact[o]
                expected[o][i, j] = [x / den for x in numerators]
                bound[o][i, j] = ref.size * norms[o]
            n = ref.normal(fu, fw)
            length = np.linalg.norm(n)
            condition = (np.linalg.norm(expected[1, 0][i, j]) * bound[0, 1][i, j]
                         + bound[1, 0][i, j] * np.linalg.norm(expected[0, 1][i, j]))
            if condition <= NORMAL_CONDITION * length:
                normal[i, j] = n / length

    uu, ww = us[:, None], ws[None, :]
    scattered = surface.derivatives(uu, ww)
    grid = surface.derivatives(us, ws, grid=True)
    for o, field in zip(ORDERS, FIELDS):
        e, b = expected[o], bound[o]
        assert_within(f"{label} {field} derivatives()", getattr(scattered, field), e, b, us, ws)
        assert_within(f"{label} {field} derivatives(grid)", getattr(grid, field), e, b, us, ws)
        assert_within(f"{label} {field} evaluate()", surface.evaluate(uu, ww, *o), e, b, us, ws)
        assert_within(f"{label} {field} evaluate_grid()", surface.evaluate_grid(us, ws, *o), e,
                      b, us, ws)

    checked = ~np.isnan(normal[..., 0])
    assert checked.sum() >= checked.size // 2, f"{label}: too few well-conditioned normals"
    for how, got in (("normals()", surface.normals(uu, ww)),
                     ("normals(grid)", surface.normals(us, ws, grid=True))):
        error = np.where(checked, np.linalg.norm(got - np.nan_to_num(normal), axis=-1), 0.0)
        assert error.max() <= LIMIT, f"{label} {how}: error {error.max():.2e} (limit {LIMIT:g})"

    check_patches(surface, ref, label, expected[0, 0], us, ws, rng, patches)


def check_patches(surface: NurbsSurface, ref: ExactSurface, label: str, points, us, ws,
                  rng: np.random.Generator, patches: int | None) -> None:
    """bezier_patches(): one per pair of non-empty spans, over those spans, each patch equal to
    the surface (exact de Casteljau against Cox–de Boor); patch_bounds() holds the surface."""
    bez = surface.bezier_patches()
    p, q = ref.u.degree, ref.v.degree
    spans = []
    for direction, got in ((ref.u, bez.u), (ref.v, bez.v)):
        want = [(float(direction.knot(k)), float(direction.knot(k + 1)))
                for k in direction.spans()]
        extent = float(max(abs(direction.domain[0]), abs(direction.domain[1])))
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-15 * extent, err_msg=label)
        spans.append(len(want))
    assert bez.points.shape == (*spans, p + 1, q + 1, 3)
    assert bez.weights.shape == (*spans, p + 1, q + 1)
    pairs = [(i, j) for i in range(spans[0]) for j in range(spans[1])]
    if patches is not None and len(pairs) > patches:
        keep = rng.choice(np.arange(1, len(pairs) - 1), patches - 2, replace=False)
        pairs = [pairs[0], *(pairs[k] for k in sorted(keep)), pairs[-1]]
    for i, j in pairs:
        (a0, a1), (b0, b1) = (Fraction(float(x)) for x in bez.u[i]), \
            (Fraction(float(x)) for x in bez.v[j])
        for s, t in rng.uniform(0.0, 1.0, (2, 2)):
            s, t = Fraction(float(s)), Fraction(float(t))
            got, got_den = de_casteljau(bez.points[i, j], bez.weights[i, j], s, t)
            want, want_den = ref.evaluate(a0 + s * (a1 - a0), b0 + t * (b1 - b0),
                                          ((0, 0),))[0, 0]
            error = float(np.linalg.norm([(x * want_den - y * got_den) / (got_den * want_den)
                                          for x, y in zip(got, want)]))
            assert error <= LIMIT * ref.size, (
                f"{label}: Bezier patch ({i}, {j}) at s={float(s)!r}, t={float(t)!r} off by "
                f"{error / ref.size:.2e} of the size (limit {LIMIT:g})")

    bounds = surface.patch_bounds()
    slack = LIMIT * ref.size
    for i, u in enumerate(us):
        for j, w in enumerate(ws):
            rows = np.flatnonzero((bounds.u[:, 0] <= u) & (u <= bounds.u[:, 1]))
            cols = np.flatnonzero((bounds.v[:, 0] <= w) & (w <= bounds.v[:, 1]))
            inside = [np.all(bounds.lower[r, c] - slack <= points[i, j])
                      and np.all(points[i, j] <= bounds.upper[r, c] + slack)
                      for r in rows for c in cols]
            assert any(inside), f"{label}: point at u={u!r}, w={w!r} outside its patch's box"


# --- the tests ---------------------------------------------------------------------------------
DEGREES = [(1, 1), (3, 3), (6, 6), (9, 9), (2, 14), (14, 2), (3, 25), (25, 3), (7, 11), (16, 16),
           (20, 5), (25, 25)]
LAYOUTS = [("nonuniform", "multiple", False), ("unclamped", "clamped", True),
           ("periodic", "unclamped", True), ("multiple", "periodic", False)]
CASES = [Case(p, q, ku, kv, rational) for p, q in DEGREES for ku, kv, rational in LAYOUTS]


@pytest.mark.parametrize("case", CASES, ids=str)
def test_against_exact_cox_de_boor(case: Case):
    check_surface(case.arguments())


def test_corner_blend_degree_2_by_14():
    check_surface(corner_blend(), knots=3, inside=3, patches=None)


@st.composite
def cases(draw) -> Case:
    return Case(draw(st.integers(1, 25)), draw(st.integers(1, 25)), draw(st.sampled_from(KINDS)),
                draw(st.sampled_from(KINDS)), draw(st.booleans()), draw(st.integers(0, 2**16)))


# Exact arithmetic at degree 25 costs up to a second per example: few examples, no shrinking.
@settings(deadline=None, max_examples=25, derandomize=True, database=None,
          phases=(Phase.explicit, Phase.generate), suppress_health_check=[HealthCheck.too_slow])
@given(cases())
def test_random_degrees_and_knots(case: Case):
    check_surface(case.arguments(), knots=1, inside=1, patches=3)


@pytest.mark.parametrize("axis", ["u", "v"])
@pytest.mark.parametrize("degree", [0, 26])
def test_degree_outside_1_to_25_is_refused(axis: str, degree: int):
    other = 3
    counts = {"u": degree + 1 if degree else 2, "v": other + 1}
    if axis == "v":
        counts = {"u": other + 1, "v": degree + 1 if degree else 2}

    def knots(d: int, count: int) -> np.ndarray:
        return np.r_[np.zeros(d + 1), np.linspace(0, 1, count - d + 1)[1:-1], np.ones(d + 1)]

    degrees = {"u": degree if axis == "u" else other, "v": degree if axis == "v" else other}
    args = dict(poles=np.zeros((counts["u"], counts["v"], 3)),
                knots_u=knots(degrees["u"], counts["u"]), knots_v=knots(degrees["v"], counts["v"]),
                degree_u=degrees["u"], degree_v=degrees["v"])
    with pytest.raises(NetError) as raised:
        NurbsSurface(**args)
    message = str(raised.value)
    assert f"degree_{axis} is {degree}" in message, message
    assert re.search(r"\b1\b\D{1,8}\b25\b", message), message
