# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the Z-level roughing's record of a cut
(:meth:`~BSplineCAM.core.toolpath.roughing.state._GridState.mark`): the cells a tool's path
at the level takes out of the uncut grid, the lowest level cut at each, and the surface
estimate and its lower bound lowered to the level plus the tool's profile, in one pass over
the path's window where the numpy engine makes a dozen masked gathers and scatters.

The arithmetic is the numpy engine's, operation by operation: the distance of a cell centre
to a segment as :func:`~BSplineCAM.core.kernels.roughing_kernels._segment_distance_loops`
takes it, the tool's profile as :meth:`~BSplineCAM.core.simulation.simulate.Tool.profile`
(the same products, differences and square roots), and ``min`` where numpy takes
``np.minimum`` of numbers that are never NaN; so both engines leave the same bits.
"""

from __future__ import annotations

import math

from . import Kernel, helper

#: Tool shapes as the kernels take them (``Tool.shape.value`` -> code).
SHAPES = {"flat": 0, "ball": 1, "bullnose": 2}


@helper
def _profile(shape, R, corner, r):
    """Height (mm) of the tool's bottom above its tip at radial distance r >= 0 (mm), r at
    most R (``Tool.profile`` within the tool)."""
    if shape == 1:
        return R - math.sqrt(max(R * R - r * r, 0.0))
    if shape == 0:
        return 0.0
    a = R - corner
    e = max(r - a, 0.0)
    return corner - math.sqrt(max(corner * corner - e * e, 0.0))


@helper
def _mark_window(uncut, floor, surface, surface_lo, full, also, use_also, i0, i1, j0, j1,
                 segment, dist, dist_lo, x0, y0, cell, sx, sy, abx, aby, ab2, R, hd, z_lo,
                 z_hi, shape, corner):
    """Mark the cells of the window rows i0:i1, columns j0:j1 by their distance d (mm) from
    the path (``d_lo`` a lower bound of it): with ``segment`` d = d_lo from the segment
    (sx, sy) + [0, 1] (abx, aby) (``ab2`` its squared length, at least 1e-300) to the cell
    centre x0 + (j + 0.5) cell, y0 + (i + 0.5) cell, else ``dist`` and ``dist_lo`` at
    [i - i0, j - j0].  Within R a cell leaves ``uncut`` (and ``also`` with ``use_also``) and,
    with ``full``, its floor drops to z_lo; with ``full`` the estimate drops to z_hi plus the
    profile at d + hd where that lies within R, its lower bound to z_lo plus the profile at
    d_lo - hd where that does.  A cell farther than R + hd changes nothing: from a segment,
    one whose squared distance is beyond that (with a margin far above the rounding) is
    passed without its square root.  The cell's work is written out here, not called, for
    the compiled loop's speed."""
    reach = R + hd
    far_sq = reach * reach * (1.0 + 1e-9) + 1e-12
    for i in range(i0, i1):
        py = (y0 + (i + 0.5) * cell) - sy
        for j in range(j0, j1):
            if segment:
                px = (x0 + (j + 0.5) * cell) - sx
                t = (px * abx + py * aby) / ab2
                t = min(max(t, 0.0), 1.0)
                qx = px - t * abx
                qy = py - t * aby
                if qx * qx + qy * qy > far_sq:
                    continue
                d = math.hypot(qx, qy)
                d_lo = d
            else:
                d = dist[i - i0, j - j0]
                d_lo = dist_lo[i - i0, j - j0]
                if d_lo > reach and d > reach:
                    continue
            if d <= R:
                uncut[i, j] = False
                if use_also:
                    also[i, j] = False
                if full and z_lo < floor[i, j]:
                    floor[i, j] = z_lo
            if not full:
                continue
            far = d + hd
            if far <= R:
                h = z_hi + _profile(shape, R, corner, far)
                if h < surface[i, j]:
                    surface[i, j] = h
            near = d_lo - hd
            if near <= R:
                h = z_lo + _profile(shape, R, corner, max(near, 0.0))
                if h < surface_lo[i, j]:
                    surface_lo[i, j] = h


def _mark_segment_loops(uncut, floor, surface, surface_lo, full, also, use_also, i0, i1, j0,
                        j1, x0, y0, cell, sx, sy, abx, aby, ab2, R, hd, z_lo, z_hi, shape,
                        corner):
    """Mark the tool's cut along the segment from (sx, sy) along (abx, aby) (``ab2`` its
    squared length, at least 1e-300) over the window rows i0:i1, columns j0:j1 of the grids,
    cell centres at x0 + (j + 0.5) cell, y0 + (i + 0.5) cell: a cell whose centre lies
    within R leaves ``uncut`` and its floor drops to z_lo; the estimate drops to z_hi plus
    the profile at the cell's farthest point (``hd`` beyond its centre) where that lies
    within R, its lower bound to z_lo plus the profile at its nearest point where that does.
    Without ``full`` only the cells within R leave ``uncut`` (the other grids stay); with
    ``use_also`` they leave the grid ``also`` too."""
    none = surface[:0, :0]
    _mark_window(uncut, floor, surface, surface_lo, full, also, use_also, i0, i1, j0, j1,
                 True, none, none, x0, y0, cell, sx, sy, abx, aby, ab2, R, hd, z_lo, z_hi,
                 shape, corner)


def _mark_field_loops(uncut, floor, surface, surface_lo, full, also, use_also, i0, j0, dist,
                      dist_lo, R, hd, z_lo, z_hi, shape, corner):
    """Mark the cut of a path whose distances (mm) from the cells of the window at row i0,
    column j0 are bounded by ``dist`` (above) and ``dist_lo`` (below), as
    :func:`_mark_segment_loops` does (the estimate by ``dist``, its lower bound by
    ``dist_lo``)."""
    h, w = dist.shape
    _mark_window(uncut, floor, surface, surface_lo, full, also, use_also, i0, i0 + h, j0,
                 j0 + w, False, dist, dist_lo, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, R, hd,
                 z_lo, z_hi, shape, corner)


mark_segment = Kernel(_mark_segment_loops)
mark_field = Kernel(_mark_field_loops)
