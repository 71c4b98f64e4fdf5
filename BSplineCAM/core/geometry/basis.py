# SPDX-License-Identifier: LGPL-2.1-or-later
"""Knot vectors and the Cox–de Boor recursion (the paper's equations 2 and 3).

This is the *reference* definition of the B-spline basis: a direct, vectorised transcription
of the recursion for any degree and knot vector, with derivatives from the standard formula
N'_{i,p} = p/(t_{i+p}-t_i) N_{i,p-1} - p/(t_{i+p+1}-t_{i+1}) N_{i+1,p-1}
(The NURBS Book, eq. 2.7).  The fast evaluator in :mod:`matrix` is checked against it.
"""

from __future__ import annotations

from enum import Enum

import numpy as np

from ..errors import NetError
from ..typing import ArrayLike, FloatArray
from ..validation import parse_enum

DEGREE = 3


class KnotLayout(str, Enum):
    """How the knots of a cubic net are laid out.

    UNIFORM is the paper's unclamped uniform vector t_i = i - (k - 1) (appendix A): the surface
    spans the central patches and does not reach the outer control points.  CLAMPED is the open
    uniform vector (end knots of multiplicity 4): the surface interpolates the corner points.
    """

    UNIFORM = "uniform"
    CLAMPED = "clamped"

    @classmethod
    def parse(cls, value: str | KnotLayout) -> KnotLayout:
        """Accept an enum or its string; raise a NetError naming the valid layouts."""
        return parse_enum(cls, value, "knot layout", NetError)


def knot_vector(count: int, layout: str | KnotLayout, degree: int = DEGREE) -> FloatArray:
    """Flat knot vector for ``count`` control points, scaled so the domain is [0, 1].

    Both layouts put the interior breakpoints at k / (count - degree), so patch ``j`` of either
    layout spans [j, j + 1] / (count - degree) and uses control points j .. j + degree.
    """
    layout = KnotLayout.parse(layout)
    if count < degree + 1:
        raise NetError(f"{count} control points: a degree-{degree} B-spline needs at least {degree + 1}")
    spans = count - degree
    if layout is KnotLayout.UNIFORM:
        return (np.arange(count + degree + 1, dtype=float) - degree) / spans
    interior = np.arange(1, spans, dtype=float) / spans
    return np.concatenate([np.zeros(degree + 1), interior, np.ones(degree + 1)])


def unique_knots(flat: FloatArray, tol: float = 1e-12) -> tuple[FloatArray, np.ndarray]:
    """Distinct knot values and their multiplicities (the form OCCT and FreeCAD take)."""
    values: list[float] = []
    mults: list[int] = []
    for t in np.asarray(flat, dtype=float):
        if values and abs(t - values[-1]) <= tol:
            mults[-1] += 1
        else:
            values.append(float(t))
            mults.append(1)
    return np.array(values), np.array(mults, dtype=int)


def cox_de_boor(knots: ArrayLike, degree: int, u: ArrayLike, derivative: int = 0) -> FloatArray:
    """All basis functions N_{i,degree}(u) (or a derivative) by equations (2)–(3).

    Returns an array of shape (len(u), n) with n = len(knots) - degree - 1.  Equation (2) uses
    half-open intervals [t_i, t_{i+1}); the last non-empty interval of the domain
    [t_degree, t_n] is closed so the basis is a partition of unity at its right end too.
    0/0 terms of equation (3) are 0.  Derivatives follow The NURBS Book, eq. 2.7.
    """
    knots = np.asarray(knots, dtype=float)
    u = np.atleast_1d(np.asarray(u, dtype=float))
    count = len(knots) - degree - 1
    if derivative > degree:
        return np.zeros((len(u), count))
    order = degree - derivative
    # degree 0: indicator functions of the knot intervals
    n0 = len(knots) - 1
    table = np.zeros((len(u), n0))
    for i in range(n0):
        table[:, i] = (u >= knots[i]) & (u < knots[i + 1])
    end = knots[count]
    last = max(i for i in range(n0) if knots[i] < knots[i + 1] and knots[i + 1] <= end)
    table[u == end, :] = 0.0
    table[u == end, last] = 1.0
    for p in range(1, order + 1):
        nxt = np.zeros((len(u), n0 - p))
        for i in range(n0 - p):
            d1 = knots[i + p] - knots[i]
            d2 = knots[i + p + 1] - knots[i + 1]
            if d1 > 0:
                nxt[:, i] += (u - knots[i]) / d1 * table[:, i]
            if d2 > 0:
                nxt[:, i] += (knots[i + p + 1] - u) / d2 * table[:, i + 1]
        table = nxt
    for p in range(order + 1, degree + 1):
        nxt = np.zeros((len(u), n0 - p))
        for i in range(n0 - p):
            d1 = knots[i + p] - knots[i]
            d2 = knots[i + p + 1] - knots[i + 1]
            if d1 > 0:
                nxt[:, i] += p / d1 * table[:, i]
            if d2 > 0:
                nxt[:, i] -= p / d2 * table[:, i + 1]
        table = nxt
    return table


def cox_de_boor_surface(
    control_points: FloatArray,
    knots_u: ArrayLike,
    knots_w: ArrayLike,
    u: ArrayLike,
    w: ArrayLike,
    degree: int = DEGREE,
) -> FloatArray:
    """Equation (4) summed directly with Cox–de Boor bases at scattered (u, w): shape (m, 3)."""
    nu = cox_de_boor(knots_u, degree, u)
    nw = cox_de_boor(knots_w, degree, w)
    return np.einsum("mi,ijc,mj->mc", nu, np.asarray(control_points, dtype=float), nw)
