# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the radius of a roughing level's fronts
(:func:`~BSplineCAM.core.toolpath.roughing.rings.front_radius`): from the squared distances
to the cleared centres and to the rest, the signed distance, its two box means, its
Laplacian and the radius, in a few passes over the grid where the numpy engine pads, sums
and slices a dozen whole-grid temporaries.

The arithmetic is the numpy engine's, operation by operation: the box mean's summed-area
table is the two running sums ``np.cumsum`` takes (down the columns, then along the rows,
each started with its first value, not from 0, which would turn a -0.0 into 0.0), its window
sums the same four terms in the same order, the Laplacian the same five; so both engines
return the same bits.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper


@helper
def _box_mean(a, h):
    """Mean of ``a`` over the (2h + 1)^2 window round each cell, edges replicated (the
    numpy engine's padded summed-area table)."""
    ny, nx = a.shape
    py, px = ny + 2 * h, nx + 2 * h
    c = np.zeros((py + 1, px + 1))
    col = np.empty(px)
    for i in range(py):
        si = min(max(i - h, 0), ny - 1)
        for j in range(px):
            v = a[si, min(max(j - h, 0), nx - 1)]
            col[j] = v if i == 0 else col[j] + v
        run = col[0]
        c[i + 1, 1] = run
        for j in range(1, px):
            run = run + col[j]
            c[i + 1, j + 1] = run
    n = 2 * h + 1
    nn = float(n * n)
    out = np.empty((ny, nx))
    for i in range(ny):
        for j in range(nx):
            out[i, j] = (c[i + n, j + n] - c[i, j + n] - c[i + n, j] + c[i, j]) / nn
    return out


def _front_radius_loops(dq, dnq, cell, h):
    """Radius (mm) of the front nearest each cell from ``dq``, the squared distances
    (cells^2) to the cleared centres, and ``dnq``, those to the rest: the signed distance
    smoothed by two box means of half-width h cells, 1 / its Laplacian less the distance to
    the cleared centres, at least two cells; inf where the Laplacian is at most 1e-9."""
    ny, nx = dq.shape
    out = np.empty((ny, nx))
    sd = np.empty((ny, nx))
    for i in range(ny):
        for j in range(nx):
            o = math.sqrt(dq[i, j]) * cell
            out[i, j] = o
            sd[i, j] = o - math.sqrt(dnq[i, j]) * cell
    sm = _box_mean(_box_mean(sd, h), h)
    cc = cell * cell
    floor = 2.0 * cell
    rho = np.full((ny, nx), math.inf)
    for i in range(1, ny - 1):
        for j in range(1, nx - 1):
            lap = (sm[i, j + 1] + sm[i, j - 1] + sm[i + 1, j] + sm[i - 1, j]
                   - 4.0 * sm[i, j]) / cc
            if lap > 1e-9:
                v = 1.0 / lap - out[i, j]
                rho[i, j] = v if (v >= floor or v != v) else floor
    return rho


front_radius = Kernel(_front_radius_loops)
