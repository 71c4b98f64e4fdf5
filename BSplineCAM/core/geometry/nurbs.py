# SPDX-License-Identifier: LGPL-2.1-or-later
"""NURBS surfaces of any degree by the paper's matrix method, one matrix per knot span.

The paper (appendix A, eq. A.2) writes a uniform cubic patch as ``[U][MB][P][MB]^T[W]^T``: a row
of basis polynomials times a basis matrix times the patch's poles.  Here every knot span
``[t_k, t_{k+1})`` of any degree ``p`` and any knot vector has its own (p+1)x(p+1) matrix, and
the row holds the span's **Bernstein** polynomials ``B_{i,p}(s)`` of the local parameter
``s = (u - t_k) / h_k`` in [0, 1] (``h_k = t_{k+1} - t_k``)::

    [B_{0,p}(s) ... B_{p,p}(s)] @ E_k = [N_{k-p,p}(u) ... N_{k,p}(u)]

``E_k`` is the span's Bezier extraction matrix: ``E_k @ P_{k-p..k}`` are the Bezier control
points of the span ("The NURBS Book", Piegl & Tiller, 2nd ed., A5.6 DecomposeCurve).  Its
column l is the Bezier form of ``N_{k-p+l,p}`` on the span, computed by blossoming: Bezier
point i is the blossom ``N(t_k^(p-i), t_{k+1}^i)``, evaluated by de Boor's triangle with one
argument per level, whose weights all lie in [0, 1] (:func:`bernstein_span_matrices`).

Why Bernstein and not the paper's power basis ``[1 s ... s^p]`` (whose matrices are the Taylor
coefficients of the basis functions, :func:`span_matrices`; for uniform cubic knots they are
the paper's MB): the power basis on [0, 1] has a condition number that grows like ``3^p``, so
a degree-14 rational blend lost about 1e-9 of its size in the power coefficients and in their
conversion to Bezier points, and degree 25 about 1e-7.  Bernstein values come from de
Casteljau's triangle (sums of non-negative terms: A1.3 AllBernstein).  A derivative is the
B-spline of the derivative poles ("The NURBS Book" eq. 3.16 / A3.3:
``p (P_{i+1} - P_i) / (t_{i+p+1} - t_{i+1})``, knots without the end ones, degree p - 1),
extracted and evaluated the same way: its differences are taken over the basis functions'
support, not over one span, so a short span between long ones loses no digits.  Points and
derivatives hold about 1e-15 of what the net can produce at every degree OCCT writes (1 to 25).

A patch is ``[B(s)] E_i P_ij E_j^T [B(t)]^T``; the products ``C_ij = E_i P_ij E_j^T`` (the
patch's Bezier control points) are computed once per surface, and once per derivative order
asked for, for x, y, z and (rational surfaces) the weight, i.e. in homogeneous coordinates
``(w x, w y, w z, w)``.  Rational values
and derivatives follow from the homogeneous ones by the quotient rule ("The NURBS Book" eq.
4.20, algorithm A4.4).  Grids are evaluated in two banded stages like :func:`matrix.grid_planes`.

Periodic surfaces arrive in OCCT's (and FreeCAD's) form -- ``n`` distinct poles, the knots of one
period with the first and last multiplicity equal (``len(knots) = n + mult_last``) -- and are
converted to the equivalent non-periodic (unclamped) form: the flat knots are extended by the
period on both sides and the first poles repeated at the end, exactly as OCCT's
``Geom_BSplineSurface::SetUNotPeriodic`` does (see :func:`unperiodize`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from math import comb

import numpy as np

from .. import kernels
from ..errors import NetError, ParameterError
from ..kernels import nurbs_eval
from ..numeric import clamp
from ..typing import ArrayLike, FloatArray
from .matrix import DEGENERATE_NORMAL
from .nurbs_spans import (  # noqa: F401  (re-exported: the knot and span functions' home)
    Direction,
    _validate_knots,
    bernstein_rows,
    bernstein_span_matrices,
    derivative_poles,
    ders_basis_funs,
    expand_knots,
    span_matrices,
    unperiodize,
)
from .surface import Derivatives, unit_normals

#: Degrees accepted in each direction: every degree OCCT allows (Geom_BSplineSurface's
#: MaxDegree() is 25; a sphere's fillet is 10, a corner blend or a loft 14).
MIN_DEGREE, MAX_DEGREE = 1, 25

#: Bytes of patch coefficients gathered at once by scattered evaluation: the chunk of points
#: is sized so that the gathered (m, q+1, (p+1) d) block stays in cache.
SCATTER_BYTES = 1 << 21

#: Rows of w per block in grid normals: a block's tangents stay in cache.
NORMAL_BLOCK_ROWS = 16

#: Partial derivatives (du, dw) in the order of the fields of ``surface.Derivatives``.
SECOND_ORDER = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))


@dataclass(frozen=True)
class PatchBounds:
    """Axis-aligned boxes of the Bezier control points of every non-empty span pair (mm).

    ``u[i]`` and ``v[j]`` are the parameter intervals of span row i / column j; ``lower[i, j]``
    and ``upper[i, j]`` (shape (3,)) bound the surface over that patch (convex hull property;
    for rational patches the projected control points, valid since all weights are > 0).
    """

    u: FloatArray
    v: FloatArray
    lower: FloatArray
    upper: FloatArray


@dataclass(frozen=True)
class BezierPatches:
    """Bezier form of every non-empty span pair.

    ``points[i, j]`` (p+1, q+1, 3) are the projected control points (mm), ``weights[i, j]``
    (p+1, q+1) their weights (all 1 for a non-rational surface); the patch over
    ``u[i] x v[j]`` is the rational Bezier patch of those, in local parameters s, t in [0, 1].
    """

    u: FloatArray
    v: FloatArray
    points: FloatArray
    weights: FloatArray


class NurbsSurface:
    """A tensor-product NURBS surface of degrees 1..25 in u and v, evaluated per span by
    the paper's matrix form in the Bernstein basis, ``[B(s)] E_i P_ij E_j^T [B(t)]^T``.

    ``poles`` (n, m, 3) mm, ``knots_u``/``knots_v`` full flat knot vectors (multiplicities
    expanded, :func:`expand_knots`), ``weights`` (n, m) > 0 or None.  Periodic directions take
    OCCT's form (see the module docstring).  Parameters are those of the knot vectors
    (``domain``), not normalised.  The second parameter is called ``w`` in the methods, as in
    :class:`~BSplineCAM.core.geometry.surface.Surface`.
    """

    def __init__(
        self,
        poles: ArrayLike,
        knots_u: ArrayLike,
        knots_v: ArrayLike,
        degree_u: int,
        degree_v: int,
        weights: ArrayLike | None = None,
        periodic_u: bool = False,
        periodic_v: bool = False,
        name: str = "face",
    ):
        label = f"surface {name!r}"
        self.name = name
        try:
            poles = np.array(poles, dtype=float)
        except (TypeError, ValueError):
            raise NetError(f"{label}: poles must be numbers (mm)") from None
        if poles.ndim != 3 or poles.shape[2] != 3:
            raise NetError(f"{label}: poles must have shape (n, m, 3), got {poles.shape}")
        bad = np.argwhere(~np.isfinite(poles))
        if bad.size:
            i, j, c = bad[0]
            raise NetError(f"{label}: pole ({i}, {j}) coordinate {'xyz'[c]} is "
                           f"{poles[i, j, c]} mm; poles must be finite")
        degrees = []
        for axis, d in (("u", degree_u), ("v", degree_v)):
            valid = not isinstance(d, bool) and float(d).is_integer()
            if not valid or not MIN_DEGREE <= d <= MAX_DEGREE:
                raise NetError(f"{label}: degree_{axis} is {d!r}, expected an integer "
                               f"from {MIN_DEGREE} to {MAX_DEGREE}")
            degrees.append(int(d))
        n, m = poles.shape[:2]
        for axis, count, d, periodic in (("u", n, degrees[0], periodic_u),
                                         ("v", m, degrees[1], periodic_v)):
            least = 2 if periodic else d + 1
            if count < least:
                kind = " (periodic)" if periodic else ""
                raise NetError(f"{label}: {count} poles along {axis}: degree {d}{kind} needs "
                               f"at least {least}")
        if weights is not None:
            try:
                weights = np.array(weights, dtype=float)
            except (TypeError, ValueError):
                raise NetError(f"{label}: weights must be numbers") from None
            if weights.shape != (n, m):
                raise NetError(f"{label}: weights must have shape {(n, m)} like the poles, got "
                               f"{weights.shape}")
            bad = np.argwhere(~(np.isfinite(weights) & (weights > 0)))
            if bad.size:
                i, j = bad[0]
                raise NetError(f"{label}: weight ({i}, {j}) is {weights[i, j]}; weights must "
                               "be finite and > 0")
        ku = _validate_knots(knots_u, degrees[0], n, bool(periodic_u), f"{label} u")
        kv = _validate_knots(knots_v, degrees[1], m, bool(periodic_v), f"{label} v")
        self.periodic_u, self.periodic_v = bool(periodic_u), bool(periodic_v)
        if self.periodic_u:
            ku, rows = unperiodize(ku, degrees[0], n)
            poles = poles[rows]
            weights = None if weights is None else weights[rows]
        if self.periodic_v:
            kv, cols = unperiodize(kv, degrees[1], m)
            poles = poles[:, cols]
            weights = None if weights is None else weights[:, cols]
        self.degree_u, self.degree_v = degrees
        self.poles = poles
        self.weights = weights
        self.rational = weights is not None and not np.all(weights == weights.flat[0])
        self.knots_u, self.knots_v = ku, kv
        for a in (self.poles, self.knots_u, self.knots_v):
            a.setflags(write=False)
        if self.weights is not None:
            self.weights.setflags(write=False)
        self._u = Direction(ku, degrees[0])
        self._v = Direction(kv, degrees[1])
        self._nets: dict[tuple[int, int], FloatArray] = {}
        self._tables: dict[tuple[int, int], FloatArray] = {}
        self._packs: dict[tuple, tuple | FloatArray] = {}  # the compiled kernels' arguments

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def from_surface(cls, surface) -> NurbsSurface:
        """The same surface as a cubic :class:`~BSplineCAM.core.geometry.surface.Surface` (its uniform
        or clamped layout as full knot vectors over the normalised domain [0, 1])."""
        ku, kw = surface.knot_vectors()
        return cls(np.array(surface.control_points), ku, kw, surface.degree, surface.degree,
                   name=surface.name)

    def __repr__(self) -> str:
        n, m = self.poles.shape[:2]
        kind = "rational" if self.rational else "non-rational"
        return (f"NurbsSurface({self.name!r}, {n}x{m} poles, degrees {self.degree_u}x"
                f"{self.degree_v}, {kind})")

    # -- description -------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        """Poles along u and v of the non-periodic form."""
        return int(self.poles.shape[0]), int(self.poles.shape[1])

    @property
    def domain(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """((u0, u1), (v0, v1)): the parameter domain."""
        return self._u.domain, self._v.domain

    def span_matrices(self) -> tuple[FloatArray, FloatArray]:
        """The per-span matrices E_i along u and E_j along v that the evaluator uses
        (:func:`bernstein_span_matrices`)."""
        return self._u.matrices, self._v.matrices

    def size(self) -> float:
        """Diagonal of the poles' bounding box (mm): the scale for relative tolerances."""
        pts = self.poles.reshape(-1, 3)
        return float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))

    @cached_property
    def homogeneous(self) -> FloatArray:
        """Poles as (w x, w y, w z, w) if rational, else (x, y, z): shape (n, m, d)."""
        if not self.rational:
            return self.poles
        w = self.weights[..., None]
        return np.concatenate([self.poles * w, w], axis=-1)

    def _net(self, a: int, b: int) -> FloatArray:
        """The homogeneous poles differentiated a times along u and b times along v."""
        if (a, b) not in self._nets:
            net = self._v.differentiate(self._u.differentiate(self.homogeneous, a, 0), b, 1)
            net.setflags(write=False)
            self._nets[(a, b)] = net
        return self._nets[(a, b)]

    def _coefficients(self, a: int, b: int) -> FloatArray:
        """E_i Q_ij E_j^T of the (a, b) derivative's B-spline for every span pair:
        (spans_u, spans_v, p-a+1, q-b+1, d)."""
        p, q = self.degree_u - a, self.degree_v - b
        blocks = np.lib.stride_tricks.sliding_window_view(
            self._net(a, b), (p + 1, q + 1), axis=(0, 1))  # (su, sv, d, k, l)
        coef = np.einsum("iak,ijckl,jbl->ijabc", self._u.matrices_for(a), blocks,
                         self._v.matrices_for(b), optimize=True)
        coef = np.ascontiguousarray(coef)
        coef.setflags(write=False)
        return coef

    @cached_property
    def patch_coefficients(self) -> FloatArray:
        """C_ij = E_i P_ij E_j^T for every span pair: shape (spans_u, spans_v, p+1, q+1, d).

        ``C[i, j, a, b]`` is the Bezier control point of Bernstein indices (a, b) of patch
        (i, j) in homogeneous coordinates (the coefficient of B_{a,p}(s) B_{b,q}(t)).
        """
        return self._coefficients(0, 0)

    # -- parameters --------------------------------------------------------------------------
    @cached_property
    def _tolerances(self) -> tuple[float, ...]:
        """(lo, hi, tol) of u then v: the domains and the round-off ``_check`` lets pass."""
        out: tuple[float, ...] = ()
        for lo, hi in (self._u.domain, self._v.domain):
            out += (lo, hi, 1e-10 * max(hi - lo, abs(lo), abs(hi)))
        return out

    def _check(self, u: ArrayLike, w: ArrayLike) -> tuple[FloatArray, FloatArray]:
        try:
            u = np.asarray(u, dtype=float)
            w = np.asarray(w, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError(f"surface {self.name!r}: parameters u and w must be numbers") \
                from None
        if kernels.use_numba():
            try:
                cu, cw, ok = nurbs_eval.check(_plain(u), _plain(w), *self._tolerances)
                if ok:
                    return (cu if u.ndim == 1 else cu.reshape(u.shape),
                            cw if w.ndim == 1 else cw.reshape(w.shape))
            except kernels.KernelUnavailable:
                pass
        out = []
        for axis, values, (lo, hi) in (("u", u, self._u.domain), ("w", w, self._v.domain)):
            tol = 1e-10 * max(hi - lo, abs(lo), abs(hi))  # round-off of trimmed-face bounds
            if values.size and (not np.all(np.isfinite(values)) or values.min() < lo - tol
                                or values.max() > hi + tol):
                raise ParameterError(
                    f"surface {self.name!r}: parameter {axis} must lie in its knot domain "
                    f"[{lo!r}, {hi!r}], got {float(values.min())!r}..{float(values.max())!r}")
            out.append(clamp(values, lo, hi))
        return out[0], out[1]

    # -- scattered evaluation ----------------------------------------------------------------
    def _scatter_table(self, a: int, b: int) -> FloatArray:
        """The (a, b) derivative's patch coefficients laid out for gathering:
        (spans_u * spans_v, q-b+1, (p-a+1) * d), row (i * spans_v + j), then the t index, then
        (s index, coordinate)."""
        if (a, b) not in self._tables:
            coef = self.patch_coefficients if (a, b) == (0, 0) else self._coefficients(a, b)
            su, sv, p1, q1, d = coef.shape
            table = np.ascontiguousarray(coef.transpose(0, 1, 3, 2, 4)).reshape(
                su * sv, q1, p1 * d)
            table.setflags(write=False)
            self._tables[(a, b)] = table
        return self._tables[(a, b)]

    def _homogeneous_scattered(self, u: FloatArray, w: FloatArray,
                               orders: list[tuple[int, int]]) -> dict:
        """Homogeneous partial derivatives at scattered points (flat u, w), per order: each
        point gathers its patch's coefficients of that derivative and sums them against the
        Bernstein rows in t, then in s (under the numba engine, all orders in one call of
        :mod:`~BSplineCAM.core.kernels.nurbs_eval`'s kernel, the same arithmetic)."""
        if kernels.use_numba():
            try:
                return self._scattered_compiled(u, w, orders)
            except kernels.KernelUnavailable:
                pass
        d = self.homogeneous.shape[-1]
        p, q = self.degree_u, self.degree_v
        spans_v = len(self._v.matrices)
        outs = {o: np.zeros((len(u), d)) for o in orders}
        live = [(a, b) for a, b in orders if a <= p and b <= q]
        if not live:
            return outs
        chunk = max(256, SCATTER_BYTES // (8 * (p + 1) * (q + 1) * d))
        for start in range(0, len(u), chunk):
            sl = slice(start, start + chunk)
            iu, su = self._u.locate(u[sl])
            iv, sv = self._v.locate(w[sl])
            row = iu * spans_v + iv
            rows_s = {k: bernstein_rows(su, k) for k in {p - a for a, _ in live}}
            rows_t = {k: bernstein_rows(sv, k) for k in {q - b for _, b in live}}
            for a, b in live:
                coef = self._scatter_table(a, b)[row]  # (m, q-b+1, (p-a+1) d)
                planes = np.einsum("bm,mbn->mn", rows_t[q - b], coef)
                planes = planes.reshape(len(row), p - a + 1, d)
                outs[(a, b)][sl] = np.einsum("am,mac->mc", rows_s[p - a], planes)
        return outs

    def _pack(self, orders: tuple[tuple[int, int], ...]) -> tuple:
        """The compiled kernel's arguments but u and w for ``orders``: each direction's knots,
        degree and first and last non-empty span, the number of spans along v, the orders and
        their offsets (int64) in their scatter tables laid end to end
        (:func:`~BSplineCAM.core.kernels.nurbs_eval.pack_tables`; orders above the degrees
        have none), and the coordinates d."""
        pack = self._packs.get(orders)
        if pack is None:
            p, q = self.degree_u, self.degree_v
            live = [o for o in orders if o[0] <= p and o[1] <= q]
            flat, packed = nurbs_eval.pack_tables([self._scatter_table(a, b) for a, b in live])
            offsets = np.zeros(len(orders), dtype=np.int64)
            for k, o in enumerate(orders):
                if o in live:
                    offsets[k] = packed[live.index(o)]
            spans = []
            for direction in (self._u, self._v):
                spans += [np.array(direction.knots, dtype=np.float64),  # contiguous, writable
                          direction.degree, int(direction.nonempty[0]),
                          int(direction.nonempty[-1])]
            pack = (*spans, len(self._v.matrices), np.array(orders, dtype=np.int64).reshape(-1, 2),
                    offsets, flat, self.homogeneous.shape[-1])
            self._packs[orders] = pack
        return pack

    def _scattered_compiled(self, u: FloatArray, w: FloatArray,
                            orders: list[tuple[int, int]]) -> dict:
        """``_homogeneous_scattered`` by the compiled kernel (all orders in one call)."""
        orders = tuple(orders)
        out, _, _ = nurbs_eval.scattered(*self._pack(orders), _plain(u), _plain(w))
        return {o: out[k] for k, o in enumerate(orders)}

    def _evaluate_compiled(self, u: FloatArray, w: FloatArray,
                           orders: tuple[tuple[int, int], ...]) -> list[FloatArray]:
        """``_evaluate_orders`` of checked (u, w) by the compiled kernels: the scattered sums
        of every order needed in one call, then (rational) the quotient rule in one."""
        shape = u.shape
        if u.ndim != 1 or w.shape != shape:
            u, w = np.broadcast_arrays(u, w)
            shape = u.shape
            u, w = u.ravel(), w.ravel()
        needed = tuple(_closure(orders)) if self.rational else tuple(dict.fromkeys(orders))
        pack = self._pack(needed)
        out, _, _ = nurbs_eval.scattered(*pack, _plain(u), _plain(w))
        if self.rational:
            index = self._packs.get(("index", needed))
            if index is None:  # the row of each order (a, b) in ``needed``
                top = max(max(a, b) for a, b in needed)
                index = np.zeros((top + 1, top + 1), dtype=np.int64)
                for k, (a, b) in enumerate(needed):
                    index[a, b] = k
                self._packs[("index", needed)] = index
            out = nurbs_eval.rational(out, pack[9], index)  # pack[9]: the orders (int64)
        if len(shape) == 1:
            return [out[needed.index(o)] for o in orders]
        return [out[needed.index(o)].reshape(shape + (3,)) for o in orders]

    def _evaluate_orders(self, u: ArrayLike, w: ArrayLike,
                         orders: tuple[tuple[int, int], ...]) -> list[FloatArray]:
        u, w = self._check(u, w)
        if kernels.use_numba():
            try:
                return self._evaluate_compiled(u, w, orders)
            except kernels.KernelUnavailable:
                pass
        u, w = np.broadcast_arrays(u, w)
        shape = u.shape
        needed = _closure(orders) if self.rational else list(orders)
        ders = self._homogeneous_scattered(u.ravel(), w.ravel(), needed)
        if self.rational:
            ders = _rational(ders, orders)
        return [ders[o].reshape(shape + (3,)) for o in orders]

    def evaluate(self, u: ArrayLike, w: ArrayLike, du: int = 0, dw: int = 0) -> FloatArray:
        """Points (or the (du, dw) partial derivative, mm per parameter unit) at scattered
        parameters u, w (broadcast): shape broadcast(u, w) + (3,)."""
        return self._evaluate_orders(u, w, ((_order(du, "du"), _order(dw, "dw")),))[0]

    def derivatives(self, u: ArrayLike, w: ArrayLike, grid: bool = False):
        """Point, Su, Sw, Suu, Suw, Sww as a :class:`~BSplineCAM.core.geometry.surface.Derivatives`."""
        if grid:
            return Derivatives(*self._grid_orders(u, w, SECOND_ORDER))
        return Derivatives(*self._evaluate_orders(u, w, SECOND_ORDER))

    # -- grids -------------------------------------------------------------------------------
    def _stage1(self, u: FloatArray, a: int, b: int) -> FloatArray:
        """[B(s)] E_i applied along u to the (a, b) derivative's poles (p-a+1 pole rows per
        sample): (n_v - b, d * len(u)), laid out coordinate-major within a row (planes of
        len(u) values)."""
        net = self._net(a, b)
        n_v, d = net.shape[1], net.shape[2]
        iu, bu = self._u.weights(u, a)
        acc = bu[:, 0, None, None] * net[iu]
        for k in range(1, self.degree_u - a + 1):
            acc += bu[:, k, None, None] * net[iu + k]
        return np.ascontiguousarray(acc.transpose(1, 2, 0)).reshape(n_v, d * len(u))

    def _stage2_blocks(self, w: FloatArray, rows: int | None = None):
        """Sorted order of w, and per block of w-rows within one v-span: (lo, hi, span)."""
        order = np.argsort(w, kind="stable")
        iv, _ = self._v.locate(w[order])
        blocks = []
        start = 0
        while start < len(w):
            stop = int(np.searchsorted(iv, iv[start], side="right"))
            if rows is not None:
                stop = min(stop, start + rows)
            blocks.append((start, stop, int(iv[start])))
            start = stop
        return order, blocks

    def _homogeneous_grid(self, u: FloatArray, w: FloatArray,
                          orders: list[tuple[int, int]]) -> dict:
        """Homogeneous partial derivatives on the grid u x w as planes (len(w), d, len(u)).

        Stage 1 applies [B(s)] E_i along u to the derivative's poles (p-a+1 pole rows per
        sample), stage 2 ([B(t)] E_j)^T along v span by span: the samples of v-span j need
        only pole columns j .. j+q-b, so each span is one small BLAS product writing a
        contiguous block of output rows (as :func:`matrix.grid_planes` does for the cubic
        case).
        """
        d = self.homogeneous.shape[-1]
        p, q, nu = self.degree_u, self.degree_v, len(u)
        live = [(a, b) for a, b in orders if a <= p and b <= q]
        stage1 = {(a, b): self._stage1(u, a, b) for a, b in live}
        order, blocks = self._stage2_blocks(w)
        ws = w[order]
        basis_v = {b: self._v.weights(ws, b)[1] for b in sorted({b for _, b in live})}
        outs = {}
        for a, b in orders:
            if (a, b) not in stage1:
                outs[(a, b)] = np.zeros((len(w), d, nu))
                continue
            out = np.empty((len(w), d * nu))
            for lo, hi, j in blocks:
                np.matmul(basis_v[b][lo:hi], stage1[(a, b)][j : j + q - b + 1], out=out[lo:hi])
            if not np.array_equal(order, np.arange(len(w))):
                out[order] = out.copy()
            outs[(a, b)] = out.reshape(len(w), d, nu)  # planes: coordinate on axis 1
        return outs

    def _grid_orders(self, u: ArrayLike, w: ArrayLike,
                     orders: tuple[tuple[int, int], ...]) -> list[FloatArray]:
        u, w = self._check(np.atleast_1d(u).ravel(), np.atleast_1d(w).ravel())
        needed = _closure(orders) if self.rational else list(orders)
        ders = self._homogeneous_grid(u, w, needed)
        if self.rational:
            ders = _rational(ders, orders, axis=1)
        return [ders[o].transpose(2, 0, 1) for o in orders]  # (len(u), len(w), 3) views

    def evaluate_grid(self, u: ArrayLike, w: ArrayLike, du: int = 0, dw: int = 0) -> FloatArray:
        """Points (or a partial derivative) on the tensor grid u x w: (len(u), len(w), 3)."""
        return self._grid_orders(u, w, ((_order(du, "du"), _order(dw, "dw")),))[0]

    def grid(self, nu: int, nw: int) -> FloatArray:
        """Points sampled uniformly over the parameter domain: (nu, nw, 3)."""
        if int(nu) < 2 or int(nw) < 2:
            raise ParameterError(f"grid needs at least 2 samples each way, got {nu}x{nw}")
        (u0, u1), (v0, v1) = self.domain
        return self.evaluate_grid(np.linspace(u0, u1, int(nu)), np.linspace(v0, v1, int(nw)))

    # -- normals -----------------------------------------------------------------------------
    def _tangent_pair(self, u: FloatArray, w: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Vectors parallel to Su and Sw at scattered (u, w) (same directions, the positive
        factor 1/w^2 dropped for rational surfaces: w A_u - w_u A and w A_w - w_w A)."""
        orders = [(0, 0), (1, 0), (0, 1)] if self.rational else [(1, 0), (0, 1)]
        h = self._homogeneous_scattered(u, w, orders)
        if not self.rational:
            return h[(1, 0)], h[(0, 1)]
        a, au, aw = h[(0, 0)], h[(1, 0)], h[(0, 1)]
        wgt = a[..., 3:]
        su = wgt * au[..., :3] - au[..., 3:] * a[..., :3]
        sw = wgt * aw[..., :3] - aw[..., 3:] * a[..., :3]
        return su, sw

    def normals(self, u: ArrayLike, w: ArrayLike, grid: bool = False) -> FloatArray:
        """Unit normals Su x Sw / |Su x Sw| (grid: shape (len(u), len(w), 3)).

        Where that cross product vanishes (a collapsed edge, a pole of a sphere), the normal
        is taken from a parameter nudged 1e-6 of the domain towards its middle, so no NaN
        reaches a toolpath.
        """
        if grid:
            u, w = self._check(np.atleast_1d(u).ravel(), np.atleast_1d(w).ravel())
            return self._grid_normals(u, w)
        u, w = self._check(u, w)
        u, w = np.broadcast_arrays(u, w)
        shape = u.shape
        u, w = u.ravel(), w.ravel()
        return self._scattered_normals(u, w).reshape(shape + (3,))

    def _scattered_normals(self, u: FloatArray, w: FloatArray) -> FloatArray:
        (u0, u1), (w0, w1) = self._u.domain, self._v.domain
        scale = self.size() ** 2 / ((u1 - u0) * (w1 - w0))  # |Su x Sw| of a surface this size
        return unit_normals(*self._tangent_pair(u, w), lambda: self._nudged_normals(u, w),
                            scale)

    def _nudged_normals(self, u: FloatArray, w: FloatArray) -> FloatArray:
        moved = []
        for t, (lo, hi) in ((u, self._u.domain), (w, self._v.domain)):
            shift = 1e-6 * (hi - lo)
            moved.append(np.where(t > 0.5 * (lo + hi), t - shift, t + shift))
        return unit_normals(*self._tangent_pair(*moved), None)

    def _grid_normals(self, u: FloatArray, w: FloatArray) -> FloatArray:
        """Normals on the grid from the banded stages: stage 1 for [S] and d[S]/du once,
        then per block of a few w-rows Su, Sw (and the point, if rational) by small BLAS
        products, crossed and normalised while in cache."""
        d = self.homogeneous.shape[-1]
        q, nu = self.degree_v, len(u)
        s00, s10, s01 = self._stage1(u, 0, 0), self._stage1(u, 1, 0), self._stage1(u, 0, 1)
        order, blocks = self._stage2_blocks(w, NORMAL_BLOCK_ROWS)
        ws = w[order]
        w0 = self._v.weights(ws, 0)[1]
        w1 = self._v.weights(ws, 1)[1]
        out = np.empty((len(w), 3, nu))
        length = np.empty((len(w), nu))
        scratch = np.empty((NORMAL_BLOCK_ROWS, nu))
        for lo, hi, j in blocks:
            su = (w0[lo:hi] @ s10[j : j + q + 1]).reshape(-1, d, nu)
            sw = (w1[lo:hi] @ s01[j : j + q]).reshape(-1, d, nu)
            if self.rational:
                a = (w0[lo:hi] @ s00[j : j + q + 1]).reshape(-1, d, nu)
                su = a[:, 3:] * su[:, :3] - su[:, 3:] * a[:, :3]
                sw = a[:, 3:] * sw[:, :3] - sw[:, 3:] * a[:, :3]
            block = out[lo:hi]
            tmp = scratch[: hi - lo]
            for c, (i, k) in enumerate(((1, 2), (2, 0), (0, 1))):
                np.multiply(su[:, i], sw[:, k], out=block[:, c])
                np.multiply(su[:, k], sw[:, i], out=tmp)
                block[:, c] -= tmp
            lengths = length[lo:hi]
            np.einsum("mcn,mcn->mn", block, block, out=lengths)
            np.sqrt(lengths, out=lengths)
            np.divide(1.0, lengths, out=tmp, where=lengths > 0)
            tmp[lengths == 0] = 0.0
            block *= tmp[:, None, :]
        if not np.array_equal(order, np.arange(len(w))):
            out[order] = out.copy()
            length[order] = length.copy()
        degenerate = length <= DEGENERATE_NORMAL * max(1.0, float(length.max(initial=0.0)))
        normals = out.transpose(2, 0, 1)
        if np.any(degenerate):
            jw, iu = np.nonzero(degenerate)
            normals[iu, jw] = self._nudged_normals(u[iu], w[jw])
        return normals

    def grid_with_normals(self, nu: int, nw: int) -> tuple[FloatArray, FloatArray]:
        """Points and unit normals on a uniform nu x nw parameter grid."""
        (u0, u1), (v0, v1) = self.domain
        u, w = np.linspace(u0, u1, int(nu)), np.linspace(v0, v1, int(nw))
        return self.evaluate_grid(u, w), self.normals(u, w, grid=True)

    # -- Bezier form and bounds --------------------------------------------------------------
    def bezier_patches(self) -> BezierPatches:
        """Bezier control points of every non-empty span pair: the patch coefficients
        E_i P_ij E_j^T ("The NURBS Book" A5.7's decomposition, by blossoming)."""
        iu, iv = self._u.nonempty, self._v.nonempty
        hom = self.patch_coefficients[np.ix_(iu, iv)]
        if self.rational:
            weights = hom[..., 3]
            points = hom[..., :3] / weights[..., None]
        else:
            weights = np.ones(hom.shape[:-1])
            points = hom
        ku, kv = self.knots_u, self.knots_v
        p, q = self.degree_u, self.degree_v
        u = np.stack([ku[iu + p], ku[iu + p + 1]], axis=-1)
        v = np.stack([kv[iv + q], kv[iv + q + 1]], axis=-1)
        return BezierPatches(u, v, points, weights)

    def patch_bounds(self) -> PatchBounds:
        """Axis-aligned box of each Bezier patch's control points (see :class:`PatchBounds`)."""
        bez = self.bezier_patches()
        return PatchBounds(bez.u, bez.v, bez.points.min(axis=(2, 3)),
                           bez.points.max(axis=(2, 3)))


def patch_bounds(surface: NurbsSurface) -> PatchBounds:
    """Per-span boxes of ``surface`` (:meth:`NurbsSurface.patch_bounds`)."""
    return surface.patch_bounds()


def _plain(values: FloatArray) -> FloatArray:
    """``values`` as a flat, C-contiguous, writable float64 array that owns its data (the
    kernels' one array type): views are copied, since numba reads their writable flag, which
    warns under numpy 1.x for the views ``np.broadcast_arrays`` returns."""
    values = np.ascontiguousarray(values, dtype=np.float64)
    if values.ndim != 1:
        values = values.reshape(-1)
    return values if values.base is None and values.flags.writeable else values.copy()


def _order(value: int, label: str) -> int:
    if isinstance(value, bool) or not float(value).is_integer() or value < 0:
        raise ParameterError(f"derivative order {label} must be an integer >= 0, got {value!r}")
    return int(value)


def _closure(orders) -> list[tuple[int, int]]:
    """Every (k, l) <= some requested (du, dw): what the quotient rule needs."""
    return sorted({(a, b) for du, dw in orders for a in range(du + 1) for b in range(dw + 1)})


def _rational(hom: dict, orders, axis: int = -1) -> dict:
    """Derivatives of S = A / w from those of (A, w): "The NURBS Book" A4.4 (eq. 4.20).

    S^(k,l) = (A^(k,l) - sum_{j=1..l} C(l,j) w^(0,j) S^(k,l-j)
               - sum_{i=1..k} C(k,i) w^(i,0) S^(k-i,l)
               - sum_{i=1..k} C(k,i) sum_{j=1..l} C(l,j) w^(i,j) S^(k-i,l-j)) / w.
    The homogeneous coordinates (w x, w y, w z, w) run along ``axis`` of every array.
    """
    ndim = hom[(0, 0)].ndim
    xyz = [slice(None)] * ndim
    wt = [slice(None)] * ndim
    xyz[axis], wt[axis] = slice(0, 3), slice(3, 4)
    xyz, wt = tuple(xyz), tuple(wt)
    w0 = hom[(0, 0)][wt]
    out: dict = {}
    for k, el in _closure(orders):
        v = hom[(k, el)][xyz].copy()
        for j in range(1, el + 1):
            v -= comb(el, j) * hom[(0, j)][wt] * out[(k, el - j)]
        for i in range(1, k + 1):
            v -= comb(k, i) * hom[(i, 0)][wt] * out[(k - i, el)]
            for j in range(1, el + 1):
                v -= comb(k, i) * comb(el, j) * hom[(i, j)][wt] * out[(k - i, el - j)]
        v /= w0
        out[(k, el)] = v
    return out
