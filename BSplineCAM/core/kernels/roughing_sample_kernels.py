# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the Z-level roughing's samples of its grids
(:mod:`~BSplineCAM.core.toolpath.roughing`): the bilinear value of a field at fractional
cell indices, and whether straight feeds stay in the region {T <= z}, sampled half a cell
apart along each, in one call where the numpy engine makes a dozen small array operations
(clips, floors, gathers, repeats) per query.

The arithmetic is the numpy engine's, operation by operation: the indices clipped and
floored alike, the four weights multiplied and summed in the same order, a feed's pieces
``ceil(hypot / step)`` (at least one) with the point of piece k at ``A + ((k + 1) / n) D``,
and the cell indices ``(x - x0) / cell - 0.5``; so both engines take the same decisions.
A NaN index, which the numpy engine cannot take either (it indexes out of the grid), raises.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper


@helper
def _sample(field, x, y):
    """Bilinear value of ``field`` (ny, nx) at fractional cell indices (column x, row y),
    clamped to the grid."""
    ny, nx = field.shape
    if x != x or y != y:
        raise ValueError("bilinear sample at a NaN cell index")
    x = min(max(x, 0.0), nx - 1.0)
    y = min(max(y, 0.0), ny - 1.0)
    j = min(int(math.floor(x)), max(nx - 2, 0))
    i = min(int(math.floor(y)), max(ny - 2, 0))
    u = x - j
    v = y - i
    j1 = min(j + 1, nx - 1)
    i1 = min(i + 1, ny - 1)
    return ((1 - u) * (1 - v) * field[i, j] + u * (1 - v) * field[i, j1]
            + (1 - u) * v * field[i1, j] + u * v * field[i1, j1])


def _bilinear_loops(field, fx, fy):
    """Bilinear values of ``field`` at the fractional cell indices (fx[k], fy[k])."""
    n = fx.shape[0]
    out = np.empty(n)
    for k in range(n):
        out[k] = _sample(field, fx[k], fy[k])
    return out


def _in_region_loops(T, A, B, x0, y0, cell, step, limit):
    """Whether each feed A[k] -> B[k] (xy mm) keeps the bilinear value of T at most
    ``limit`` at its start and at the ends of its ceil(length / step) equal pieces (cells
    of ``cell`` mm from (x0, y0))."""
    m = A.shape[0]
    out = np.ones(m, np.bool_)
    for k in range(m):
        ax = A[k, 0]
        ay = A[k, 1]
        dx = B[k, 0] - ax
        dy = B[k, 1] - ay
        if _sample(T, (ax - x0) / cell - 0.5, (ay - y0) / cell - 0.5) > limit:
            out[k] = False
        n = max(int(math.ceil(math.hypot(dx, dy) / step)), 1)
        for q in range(n):
            t = (q + 1) / n
            px = ax + t * dx
            py = ay + t * dy
            if _sample(T, (px - x0) / cell - 0.5, (py - y0) / cell - 0.5) > limit:
                out[k] = False
    return out


bilinear = Kernel(_bilinear_loops)
in_region = Kernel(_in_region_loops)
