# SPDX-License-Identifier: LGPL-2.1-or-later
"""The order contours are cut in: short moves between them, upper levels first where they
lie over lower ones.

Waterline contours come level by level; cut in that order the tool crosses the part between
every two features of a level (a hole, a fillet, a boss) and back on the next level.  Here the
next contour is the one nearest to where the tool is (greedy nearest neighbour, the usual
first heuristic of the travelling salesman problem; Rosenkrantz, Stearns & Lewis 1977), among
those it may cut now:

* **precedence**: a contour waits for every contour above it (higher by more than
  ``LEVEL_EPS``) whose XY box, grown by the ball's diameter, meets its own: on one wall the
  levels are cut top down, as the roughing left them; features apart from each other are cut
  one after the other, each top down;
* **entry**: a closed contour (first point equal to the last) at its vertex nearest the
  tool, the loop turned to start there, same direction; an open one at its start, or, when
  ``reversible``, at whichever end is nearer (run backwards from its end: a wall's levels
  cut back and forth).

:func:`orient_climb` first turns every waterline so that the material lies on the tool's
right (climb milling); ordering without ``reversible`` then keeps that direction.

The distance is the straight 3-D one from the tool to the entry point.  A contour's nearest
vertex is found only for the contours whose box could beat the best so far (boxes sorted by
their distance, a lower bound of the true one).
"""

from __future__ import annotations

import numpy as np

from ..typing import FloatArray
from .arcs import contour_side

#: Levels closer than this (mm) count as one level.
LEVEL_EPS = 1e-6


def is_closed(p: FloatArray) -> bool:
    """Whether a contour (n, 3) is a loop: more than two points, the last equal to the first."""
    return len(p) > 2 and bool(np.all(p[0] == p[-1]))


def _precedence(lo: FloatArray, hi: FloatArray, top: FloatArray, grow: float) -> np.ndarray:
    """(n, n) bool: [a, b] when contour a must be cut before b (above it, boxes meeting)."""
    meet = ((lo[:, None, 0] - grow <= hi[None, :, 0]) & (lo[None, :, 0] <= hi[:, None, 0] + grow)
            & (lo[:, None, 1] - grow <= hi[None, :, 1]) & (lo[None, :, 1] <= hi[:, None, 1] + grow))
    return meet & (top[:, None] > top[None, :] + LEVEL_EPS)


def _box_distance(at: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray:
    """Distance (mm) from point ``at`` (3,) to each box (lo, hi) (n, 3)."""
    d = np.maximum(np.maximum(lo - at, at - hi), 0.0)
    return np.sqrt((d * d).sum(axis=1))


def order_contours(passes: list, grow: float, start: FloatArray | None = None,
                   reversible: bool = False) -> list:
    """``passes`` (tip positions (n, 3)) reordered for short moves between them (see the
    module docstring); closed ones turned to start at their entry vertex.  ``grow`` (mm) is
    how far apart two contours' boxes may be and still be cut top down (the ball's
    diameter); ``start`` is where the tool comes from (default: above the first contour);
    ``reversible`` lets an open contour run from either end."""
    n = len(passes)
    if n <= 1:
        return [np.asarray(p, float) for p in passes]
    passes = [np.asarray(p, float) for p in passes]
    lo = np.array([p.min(axis=0) for p in passes])
    hi = np.array([p.max(axis=0) for p in passes])
    top = hi[:, 2]
    closed = np.array([is_closed(p) for p in passes])
    before = _precedence(lo, hi, top, grow)
    waiting = before.sum(axis=0)
    done = np.zeros(n, bool)
    at = passes[0][0] if start is None else np.asarray(start, float)
    out = []
    for _ in range(n):
        free = np.flatnonzero(~done & (waiting == 0))
        bound = _box_distance(at, lo[free], hi[free])
        best, pick, entry = np.inf, -1, 0
        for j in np.argsort(bound, kind="stable"):
            if bound[j] >= best:
                break
            k = int(free[j])
            if closed[k]:
                d = np.linalg.norm(passes[k][:-1] - at, axis=1)
                v = int(np.argmin(d))
                dist = float(d[v])
            else:
                v, dist = 0, float(np.linalg.norm(passes[k][0] - at))
                if reversible:
                    back = float(np.linalg.norm(passes[k][-1] - at))
                    if back < dist:
                        v, dist = -1, back
            if dist < best:
                best, pick, entry = dist, k, v
        p = passes[pick]
        if closed[pick] and entry:
            ring = p[:-1]
            p = np.vstack([ring[entry:], ring[:entry], ring[entry:entry + 1]])
        elif entry == -1:
            p = p[::-1].copy()
        out.append(p)
        done[pick] = True
        waiting -= before[pick]
        at = p[-1]
    return out


def orient_climb(passes: list, heights, offset: float) -> list:
    """Contours at constant Z (waterlines) each run so that the material lies on the tool's
    right: climb milling with a clockwise (M3) spindle.  The free side of each is told by
    :func:`.arcs.contour_side` (``heights(xy (m, 2)) -> tip heights``, NaN where no face is
    under the ball, asked ``offset`` mm left of its chords); a contour whose left side holds
    the material is reversed."""
    side = contour_side(heights, offset)
    return [p if side(p) > 0 else p[::-1].copy() for p in (np.asarray(q, float) for q in passes)]


__all__ = ["LEVEL_EPS", "is_closed", "order_contours", "orient_climb"]
