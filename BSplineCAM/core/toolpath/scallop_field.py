# SPDX-License-Identifier: LGPL-2.1-or-later
"""Grid fields of the constant-scallop finish (:mod:`.faces_scallop`): a distance counted in
stepovers, propagated over a grid of ball-centre positions, and its contours.

* :func:`propagate` is a chamfer distance transform with direction-dependent weights
  (Borgefors 1986, "Distance transformations in digital images"): every node is joined to its
  32 neighbours (the 8 nearest, the 8 a knight's move away and the 16 at (1, 3) and (2, 3)
  steps), an edge of XY length L along axis k costs L (c_k(p) + c_k(q)) / 2, c_k the cost per
  mm along axis k.  The distance of a node is the least cost of a path of such edges from
  the sources; with exact edge lengths it overestimates a straight distance by at most
  1 / cos(half the widest angle between neighbouring axes) - 1, 0.6 % (18.4 degrees between
  (1, 2) and (1, 3) steps), never underestimates it.  Its level sets are polygons with a
  corner on each ray between two axes, and nested ones stand further apart at the corners
  by that same factor: 2 % with the 16-neighbourhood (22.5 degrees between axes), which
  left scallops 4 % over the asked height round a hole.  It is solved by sweeps, rows
  forward then backward, each row from the rows before it in one vectorised step and along
  itself by a segmented running minimum (a path along a row is a prefix sum of its edge
  costs), repeated until nothing changes.  A knight's move steps over a blocked line one
  node wide; the longer steps do not pass a blocked node (those nearest their segment) and
  sum the costs at those nodes by the trapezoid rule.
* :func:`contours` is marching squares (Lorensen & Cline 1987; the case table and chaining of
  :mod:`.waterline`) with the crossing on each grid edge interpolated linearly.
* :func:`near_distance` gives the XY distance of grid nodes near polylines to them: the exact
  start values next to a boundary or a pass, so the field does not inherit the grid's
  staircase; :class:`NearField` keeps it for a growing set of polylines, searching near the
  new ones only.

The loops run compiled (:mod:`..kernels.scallop_kernels`) under the numba engine.
"""

from __future__ import annotations

import math

import numpy as np

from .. import kernels
from ..kernels import scallop_kernels as _sk
from ..typing import FloatArray
from .waterline import _chain, _crossings

#: The 32-neighbourhood's axes: (di, dj) with di > 0 or (di == 0 and dj > 0); the stepover is
#: evaluated across each (the pass perpendicular to it).
AXES = ((0, 1), (1, 0), (1, 1), (1, -1), (1, 2), (2, 1), (1, -2), (2, -1),
        (1, 3), (3, 1), (1, -3), (3, -1), (2, 3), (3, 2), (2, -3), (3, -2))
#: Sweep rounds at most (each a forward and a backward sweep).
MAX_ROUNDS = 60


def axis_vectors(dx: float, dy: float) -> FloatArray:
    """Unit XY vectors of :data:`AXES` on a grid of spacing dx (along i) and dy (along j)."""
    v = np.array([[di * dx, dj * dy] for di, dj in AXES], dtype=float)
    return v / np.linalg.norm(v, axis=1)[:, None]


def _between(di: int, dj: int) -> list[tuple[int, int]]:
    """Nodes (offsets from the step's start) nearest the segment of a step longer than a
    knight's move, which must be free for the step to be taken."""
    n = max(abs(di), abs(dj))
    if n <= 2:
        return []
    pts = {(round(t * di / n + 1e-9 * np.sign(di)), round(t * dj / n + 1e-9 * np.sign(dj)))
           for t in range(1, n)}
    return sorted(pts - {(0, 0), (di, dj)})


def _shifted(row: FloatArray, dj: int, fill: float) -> FloatArray:
    """row[j - dj] at j (``fill`` where j - dj is outside the row)."""
    if dj == 0:
        return row
    out = np.full_like(row, fill)
    if dj > 0:
        out[dj:] = row[:-dj]
    else:
        out[:dj] = row[-dj:]
    return out


def _scan(d: FloatArray, w: FloatArray, free: np.ndarray) -> FloatArray:
    """Least cost along a row from the left: d[j] = min(d[j], d[j-1] + w[j-1]) for all j at
    once, paths not crossing a blocked node (``free`` False: those keep their value)."""
    c = np.concatenate([[0.0], np.cumsum(np.where(np.isfinite(w), w, 0.0))])
    # a blocked node or edge starts a new segment: earlier segments cannot win after it
    brk = np.concatenate([[0], np.cumsum(~free[1:] | ~free[:-1] | ~np.isfinite(w))])
    big = 4.0 * (float(np.max(np.abs(np.where(np.isfinite(d), d, 0.0)), initial=0.0))
                 + float(c[-1]) + 1.0)
    key = np.where(free, d - c, np.inf) - brk * big
    best = np.minimum.accumulate(key) + brk * big + c
    return np.where(free, np.minimum(d, best), d)


def propagate(start: FloatArray, cost: FloatArray, dx: float, dy: float,
              free: np.ndarray, max_rounds: int = MAX_ROUNDS,
              against: FloatArray | None = None) -> FloatArray:
    """Least path cost from the sources (the finite entries of ``start``) to every free node.

    ``cost`` (len(AXES), nx, ny) holds c_k per node, the cost per mm along axis k (inf where
    blocked), ``against`` the same for travel against it (default: ``cost``, a symmetric
    metric); ``free`` marks the nodes that may take a new value (others keep ``start``).
    """
    if against is None:
        against = cost
    d = np.where(free, start, np.inf).astype(float)
    nx, ny = d.shape
    length = [math.hypot(di * dx, dj * dy) for di, dj in AXES]
    # edges into row i from the rows before it in the sweep: along axis (di, dj) from
    # (i - di, j - dj) forwards, from (i + di, j + dj) backwards
    back = [(di, dj, k, _between(di, dj)) for k, (di, dj) in enumerate(AXES) if di > 0]
    row_axis = AXES.index((0, 1))
    if kernels.use_numba():
        mids = [m for *_, mid in back for m in mid]
        ints = [np.array(v, dtype=np.int64) for v in (
            [di for di, *_ in back], [dj for _, dj, *_ in back], [k for _, _, k, _ in back],
            np.cumsum([0] + [len(mid) for *_, mid in back]), [a for a, _ in mids],
            [b for _, b in mids])]
        out = d.copy()
        try:
            _sk.propagate(out, np.ascontiguousarray(cost, dtype=float),
                          np.ascontiguousarray(against, dtype=float),
                          np.ascontiguousarray(free, dtype=bool), np.array(length), *ints,
                          row_axis, int(max_rounds))
            return out
        except kernels.KernelUnavailable:
            pass
    for _ in range(max_rounds):
        before = d.copy()
        for sweep in (1, -1):
            rows = range(nx) if sweep == 1 else range(nx - 1, -1, -1)
            # the forward sweep travels along the axes into a row, the backward one against
            c_in = cost if sweep == 1 else against
            for i in rows:
                row = d[i]
                fr = free[i]
                for di, dj, k, mid in back:
                    src_i = i - sweep * di
                    if not 0 <= src_i < nx:
                        continue
                    # the edge from (src_i, j - s dj) to (i, j) along axis k (or its reverse)
                    sj = sweep * dj
                    src = _shifted(d[src_i], sj, np.inf)
                    c_src = _shifted(c_in[k, src_i], sj, np.inf)
                    # trapezoid rule over the nodes the step passes, (src + s (a, b))
                    total = 0.5 * (c_src + c_in[k, i])
                    for a, b in mid:
                        row_m, shift_m = i - sweep * (di - a), sweep * (dj - b)
                        passed = _shifted(free[row_m], shift_m, False)
                        c_mid = _shifted(c_in[k, row_m], shift_m, np.inf)
                        total = np.where(passed, total + c_mid, np.inf)
                    cand = src + length[k] * total / (len(mid) + 1)
                    row = np.where(fr, np.minimum(row, cand), row)
                w = 0.5 * length[row_axis] * (cost[row_axis, i, 1:] + cost[row_axis, i, :-1])
                row = _scan(row, w, fr)
                w = 0.5 * length[row_axis] * (against[row_axis, i, 1:]
                                              + against[row_axis, i, :-1])
                row = _scan(row[::-1], w[::-1], fr[::-1])[::-1]
                d[i] = row
        with np.errstate(invalid="ignore"):
            change = np.abs(np.where(np.isfinite(d), d, 0.0) - np.where(np.isfinite(before),
                                                                         before, 0.0))
        if float(change.max(initial=0.0)) <= 1e-9 and np.array_equal(np.isfinite(d),
                                                                      np.isfinite(before)):
            break
    return d


def contour_keys(field: FloatArray, level: float) -> list[np.ndarray]:
    """Marching squares: the chained contours of ``field`` at ``level`` as arrays of grid
    edge keys (closed ones repeat their first key); NaN counts as below every level."""
    segments, _, _ = _crossings(field, level)
    return [np.asarray(chain) for chain in _chain(segments)]


def edge_points(field: FloatArray, xs: FloatArray, ys: FloatArray, keys: np.ndarray,
                level: float, t: FloatArray | None = None) -> FloatArray:
    """XY (mm) of the crossings on grid edges ``keys``: at ``t`` along each edge from its
    first corner, or where the field interpolated linearly meets ``level``."""
    nx, ny = field.shape
    c = edge_ends((nx, ny), keys)
    p0 = np.column_stack([xs[c[:, 0, 0]], ys[c[:, 0, 1]]])
    p1 = np.column_stack([xs[c[:, 1, 0]], ys[c[:, 1, 1]]])
    if t is None:
        f0 = field[c[:, 0, 0], c[:, 0, 1]]
        f1 = field[c[:, 1, 0], c[:, 1, 1]]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = np.clip((level - f0) / (f1 - f0), 0.0, 1.0)
        t = np.where(np.isfinite(t), t, 0.5)
    return p0 + t[:, None] * (p1 - p0)


def edge_ends(shape: tuple[int, int], keys: np.ndarray) -> np.ndarray:
    """(m, 2, 2) grid corners (i, j) of edge keys (:func:`.waterline._edge_key`: (i, j)-(i+1, j)
    is i ny + j, (i, j)-(i, j+1) is nx ny + i ny + j)."""
    nx, ny = shape
    keys = np.asarray(keys, dtype=np.intp)
    vertical = keys >= nx * ny
    k = np.where(vertical, keys - nx * ny, keys)
    i, j = k // ny, k % ny
    out = np.empty((len(keys), 2, 2), dtype=np.intp)
    out[:, 0, 0], out[:, 0, 1] = i, j
    out[:, 1, 0] = np.where(vertical, i, np.minimum(i + 1, nx - 1))
    out[:, 1, 1] = np.where(vertical, np.minimum(j + 1, ny - 1), j)
    return out


def contours(field: FloatArray, xs: FloatArray, ys: FloatArray, level: float) -> list[FloatArray]:
    """XY polylines (mm) of ``field`` at ``level`` (closed ones repeat their first point)."""
    return [edge_points(field, xs, ys, k, level) for k in contour_keys(field, level)]


def near_distance(polylines: list, xs: FloatArray, ys: FloatArray,
                  reach: int = 2) -> FloatArray:
    """XY distance (mm) from each grid node within ``reach`` cells of a segment of
    ``polylines`` to the nearest such segment; inf elsewhere."""
    return near_vector(polylines, xs, ys, reach)[0]


def near_vector(polylines: list, xs: FloatArray, ys: FloatArray,
                reach: int = 2) -> tuple[FloatArray, FloatArray]:
    """:func:`near_distance` and the XY vector (nx, ny, 2) from the nearest point of the
    segments to the node (zero where none is within reach)."""
    out, vec, _ = _near(polylines, xs, ys, reach)
    return out, vec


class NearField:
    """:func:`near_vector` of a growing list of polylines over one grid: :meth:`add` finds the
    nodes near the new ones only and merges them in, the same answer as a call over all of
    them.  Of the pieces at a node's least distance a call keeps the last to reach it, the
    neighbour offsets outermost (the offset's index decides; at one offset a later polyline
    wins), so with finite coordinates merging is exact; other polylines are searched anew
    with all the rest."""

    def __init__(self, xs: FloatArray, ys: FloatArray, reach: int = 2):
        self.xs, self.ys, self.reach = xs, ys, reach
        self.lines: list = []
        self.out, self.vec, self.offset = _near([], xs, ys, reach)
        self.finite = True

    def add(self, polylines: list) -> None:
        """Take in more polylines (after those already in, in order)."""
        polylines = list(polylines)
        self.lines += polylines
        finite = all(bool(np.isfinite(np.asarray(p, dtype=float)[:, :2]).all())
                     for p in polylines)
        if not (self.finite and finite):
            self.finite = False
            self.out, self.vec, self.offset = _near(self.lines, self.xs, self.ys, self.reach)
            return
        out, vec, offset = _near(polylines, self.xs, self.ys, self.reach)
        new = (out < self.out) | ((out == self.out) & (offset >= self.offset))
        self.out = np.where(new, out, self.out)
        self.vec = np.where(new[..., None], vec, self.vec)
        self.offset = np.where(new, offset, self.offset)


def _near(polylines: list, xs: FloatArray, ys: FloatArray,
          reach: int) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """:func:`near_vector` and, per node, the index of the neighbour offset (row-major over
    [1 - reach, reach]^2) whose piece set its vector (-1 where none)."""
    nx, ny = len(xs), len(ys)
    out = np.full((nx, ny), np.inf)
    vec = np.zeros((nx, ny, 2))
    won_at = np.full((nx, ny), -1, dtype=np.int64)
    segs = [np.column_stack([p[:-1, :2], p[1:, :2]]) for p in polylines if len(p) >= 2]
    if not segs:
        return out, vec, won_at
    s = np.concatenate(segs)
    dx, dy = xs[1] - xs[0], ys[1] - ys[0]
    # split segments longer than a cell so that the nodes near each piece are found from it
    n = np.maximum(np.ceil(np.maximum(np.abs(s[:, 2] - s[:, 0]) / dx,
                                      np.abs(s[:, 3] - s[:, 1]) / dy)).astype(int), 1)
    rep = np.repeat(np.arange(len(s)), n)
    # the k-th of a segment's m pieces runs from k / m to (k + 1) / m along it
    f = (np.arange(len(rep)) - np.repeat(np.cumsum(n) - n, n)) / n[rep]
    g = f + 1.0 / n[rep]
    a = s[rep, :2] + f[:, None] * (s[rep, 2:] - s[rep, :2])
    b = s[rep, :2] + g[:, None] * (s[rep, 2:] - s[rep, :2])
    mid = 0.5 * (a + b)
    ci = np.floor((mid[:, 0] - xs[0]) / dx).astype(int)
    cj = np.floor((mid[:, 1] - ys[0]) / dy).astype(int)
    ab = b - a
    den = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
    if kernels.use_numba():
        try:
            _sk.near_vector(np.ascontiguousarray(xs, dtype=float),
                            np.ascontiguousarray(ys, dtype=float), a[:, 0].copy(),
                            a[:, 1].copy(), ab[:, 0].copy(), ab[:, 1].copy(), den,
                            ci.astype(np.int64), cj.astype(np.int64), int(reach), out, vec,
                            won_at)
            return out, vec, won_at
        except kernels.KernelUnavailable:
            pass
    offsets = [(oi, oj) for oi in range(-reach + 1, reach + 1)
               for oj in range(-reach + 1, reach + 1)]
    for o, (oi, oj) in enumerate(offsets):
        i, j = ci + oi, cj + oj
        ok = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
        p = np.column_stack([xs[np.clip(i, 0, nx - 1)], ys[np.clip(j, 0, ny - 1)]])
        t = np.clip(np.einsum("ij,ij->i", p - a, ab) / den, 0.0, 1.0)
        r = p - (a + t[:, None] * ab)
        dist = np.hypot(r[:, 0], r[:, 1])
        io, jo, do, ro = i[ok], j[ok], dist[ok], r[ok]
        np.minimum.at(out, (io, jo), do)
        won = do == out[io, jo]  # the nearest so far (a tie: the last piece)
        vec[io[won], jo[won]] = ro[won]
        won_at[io[won], jo[won]] = o
    return out, vec, won_at


def bilinear(field: FloatArray, xs: FloatArray, ys: FloatArray, xy: FloatArray) -> FloatArray:
    """``field`` interpolated bilinearly at points xy (mm), clamped to the grid."""
    dx, dy = xs[1] - xs[0], ys[1] - ys[0]
    fx = np.clip((xy[:, 0] - xs[0]) / dx, 0.0, len(xs) - 1.000001)
    fy = np.clip((xy[:, 1] - ys[0]) / dy, 0.0, len(ys) - 1.000001)
    i, j = fx.astype(int), fy.astype(int)
    tx, ty = fx - i, fy - j
    f = field
    return ((1 - tx) * (1 - ty) * f[i, j] + tx * (1 - ty) * f[i + 1, j]
            + (1 - tx) * ty * f[i, j + 1] + tx * ty * f[i + 1, j + 1])


__all__ = ["AXES", "axis_vectors", "bilinear", "contour_keys", "contours", "edge_ends",
           "edge_points", "near_distance", "near_vector", "NearField", "propagate"]
