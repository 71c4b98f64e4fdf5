# SPDX-License-Identifier: LGPL-2.1-or-later
"""Round fronts: the rings round a helical entry or a floor already cut, and the step by which
a round front grows so that the tool meets the material over the arc a straight pass does."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import kernels
from ...kernels import roughing_front_kernels as _fk
from ...typing import FloatArray
from .constants import FRONT_SMOOTH_RADII, MIN_FRONT_STEP
from .gridops import squared_distance


@dataclass
class _Ring:
    """Fronts round a helical entry: its component, its centre (x, y mm), the radius of its
    last front (mm; None once it met a wall and grows by the stepover) and the component's
    cells within a stepover of the rim (where a front nears a wall)."""

    mask: np.ndarray
    centre: tuple
    radius: float | None
    near_rim: np.ndarray
    exact: bool = True  # a helix's circle; False: a floor already cut, round only roughly


def ring_step(rho: float, R: float, s: float) -> float:
    """Step (mm) from a round front of radius ``rho`` (tool centres, mm) cleared all round to
    the next one, so that a tool of radius R on it meets the material over the same arc as
    on a straight pass at stepover s.

    On a straight pass the tool's edge is in the material over the angle phi0 = acos(1 - s/R)
    from the normal to the pass; the simulation's width of cut, the extent of the engaged
    cells across the travel, is R (1 - cos phi0) = s.  Round a cleared disc of radius
    rho + R the edge of a tool at radius rho' = rho + ds is in the material where
    rho'^2 + 2 rho' R cos(phi) + R^2 >= (rho + R)^2: over a wider arc than phi0 if ds = s
    (a 10 mm mill 4 mm out of a 4 mm helix: 96 degrees instead of 78, a width of 5.5 mm).
    The ds that gives phi0 solves rho'^2 + 2 c R rho' - ((rho + R)^2 - R^2) = 0 with
    c = 1 - s/R; it tends to s as rho grows."""
    return float(min(max(float(_ring_growth(rho, R, s)), 0.0), s))


def _ring_growth(rho, R: float, s: float):
    """rho' - rho of :func:`ring_step` (unclipped), for a radius or an array of them."""
    c = 1.0 - s / R
    return -c * R + np.sqrt(c * c * R * R + (rho + R) ** 2 - R * R) - rho


def ring_steps(rho: FloatArray, R: float, s: float) -> FloatArray:
    """:func:`ring_step` of each radius (mm; inf: a straight front), at least
    MIN_FRONT_STEP of the stepover."""
    r = np.minimum(np.asarray(rho, dtype=float), 1e6)
    return np.clip(_ring_growth(r, R, s), MIN_FRONT_STEP * s, s)


def front_radius(Q: np.ndarray, cell: float, R: float) -> FloatArray:
    """Radius (mm) of the boundary of the cleared centres Q nearest each cell (inf where it
    is straight or bends away): 1 / (the Laplacian of Q's signed distance, smoothed by two
    box means reaching FRONT_SMOOTH_RADII tool radii to each side) less the cell's distance,
    at least two cells.  The signed distance is smooth across the boundary, and the Laplacian
    of a distance is the curvature of its level sets, 1 / (rho + d) at a distance d from a
    round boundary of radius rho."""
    h = max(2, int(round(FRONT_SMOOTH_RADII * R / cell)))
    if kernels.use_numba():
        try:
            return _fk.front_radius(squared_distance(Q), squared_distance(~Q), float(cell), h)
        except kernels.KernelUnavailable:
            pass
    out = np.sqrt(squared_distance(Q)) * cell
    sd = out - np.sqrt(squared_distance(~Q)) * cell
    sm = _box_mean(_box_mean(sd, h), h)
    lap = np.zeros_like(sm)
    lap[1:-1, 1:-1] = (sm[1:-1, 2:] + sm[1:-1, :-2] + sm[2:, 1:-1] + sm[:-2, 1:-1]
                       - 4.0 * sm[1:-1, 1:-1]) / (cell * cell)
    with np.errstate(divide="ignore"):
        return np.where(lap > 1e-9, np.maximum(1.0 / lap - out, 2.0 * cell), np.inf)


def _box_mean(a: FloatArray, h: int) -> FloatArray:
    """Mean of ``a`` over the (2h + 1)^2 window round each cell (edges replicated)."""
    p = np.pad(a, h, mode="edge")
    c = np.zeros((p.shape[0] + 1, p.shape[1] + 1))
    np.cumsum(np.cumsum(p, axis=0), axis=1, out=c[1:, 1:])
    n = 2 * h + 1
    return (c[n:, n:] - c[:-n, n:] - c[n:, :-n] + c[:-n, :-n]) / (n * n)
