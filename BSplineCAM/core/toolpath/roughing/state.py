# SPDX-License-Identifier: LGPL-2.1-or-later
"""The grid state of a roughing run: the tool and the tip-height map on the grid, the
level's grids of uncut material, the surface estimate and its lower bound, and the
queries on them (where the tool may descend, which feeds stay in the region); and the writer
of the moves."""

from __future__ import annotations

import math

import numpy as np

from ... import kernels
from ...kernels import roughing_kernels as _rk
from ...kernels import roughing_mark_kernels as _mk
from ...kernels import roughing_sample_kernels as _sk
from ...typing import FloatArray
from ..common import Move
from .constants import CELL_HALF_DIAGONAL, TRAVEL_GAP_MM
from .gridops import _bilinear, _densify, _pieces, _polyline_distance, capped_distance


def _segment_distance(xs: FloatArray, ys: FloatArray, seg: FloatArray) -> FloatArray:
    """Distance (mm) from each cell centre (ys[i], xs[j]) to the segment seg (2, 2)."""
    ab = seg[1] - seg[0]
    ab2 = max(float(ab @ ab), 1e-300)
    if kernels.use_numba():
        try:
            return _rk.segment_distance(xs, ys, float(seg[0, 0]), float(seg[0, 1]),
                                        float(ab[0]), float(ab[1]), ab2)
        except kernels.KernelUnavailable:
            pass
    px = xs[None, :] - seg[0, 0]
    py = ys[:, None] - seg[0, 1]
    t = np.clip((px * ab[0] + py * ab[1]) / ab2, 0.0, 1.0)
    return np.hypot(px - t * ab[0], py - t * ab[1])


class _Writer:
    """Moves with the tool's position and the count of retracts to the clearance height."""

    def __init__(self, clearance: float):
        self.moves: list[Move] = []
        self.clear = clearance
        self.pos = None  # (x, y, z) or None before the first move
        self.retracts = 0

    def add(self, kind: str, x: float, y: float, z: float) -> None:
        p = (float(x), float(y), float(z))
        if self.pos is not None and all(a == b or abs(a - b) <= 1e-9
                                        for a, b in zip(p, self.pos)):
            return
        self.moves.append(Move(kind, *p))
        self.pos = p

    def retract(self) -> None:
        if self.pos is not None and self.pos[2] < self.clear:
            self.add("rapid", self.pos[0], self.pos[1], self.clear)
            self.retracts += 1


class _GridState:
    """The grids of one roughing run and what is read and marked on them: the tip-height map
    ``T``, the part's heights plus the axial allowance ``Hp``, the lowest level cut at each
    cell (``floor``), and per level the uncut cells (``uncut``), the surface estimate
    (``surface``) and its lower bound (``surface_lo``) at the level ``z``."""

    def __init__(self, grid, T, Hp, tool, s, ar, cell, stock):
        self.grid, self.T, self.Hp, self.tool = grid, T, Hp, tool
        self.s, self.ar, self.cell, self.stock = s, ar, cell, stock
        self.R = tool.radius
        self.Rc = tool.radius / cell
        self.floor = np.full(T.shape, stock.z_max)  # lowest level cut at each cell

    def xy(self, f: FloatArray) -> FloatArray:
        g = self.grid
        return np.column_stack([g.x0 + (f[:, 0] + 0.5) * g.cell, g.y0 + (f[:, 1] + 0.5) * g.cell])

    def idx(self, p: FloatArray) -> FloatArray:
        g = self.grid
        p = np.atleast_2d(np.asarray(p, dtype=float))
        return np.column_stack([(p[:, 0] - g.x0) / g.cell - 0.5, (p[:, 1] - g.y0) / g.cell - 0.5])

    def window(self, f: FloatArray, pad: float) -> tuple[int, int, int, int]:
        ny, nx = self.T.shape
        j0 = max(int(math.floor(f[:, 0].min() - pad)), 0)
        j1 = min(int(math.ceil(f[:, 0].max() + pad)) + 1, nx)
        i0 = max(int(math.floor(f[:, 1].min() - pad)), 0)
        i1 = min(int(math.ceil(f[:, 1].max() + pad)) + 1, ny)
        return i0, i1, j0, j1

    def window_of(self, ax: float, ay: float, bx: float, by: float,
                  pad: float) -> tuple[int, int, int, int]:
        """:meth:`window` of the fractional indices of the two points (ax, ay), (bx, by) (xy
        mm), in plain floats: the same arithmetic, without arrays."""
        g = self.grid
        ny, nx = self.T.shape
        fa, fb = (ax - g.x0) / g.cell - 0.5, (bx - g.x0) / g.cell - 0.5
        ga, gb = (ay - g.y0) / g.cell - 0.5, (by - g.y0) / g.cell - 0.5
        return (max(math.floor(min(ga, gb) - pad), 0), min(math.ceil(max(ga, gb) + pad) + 1, ny),
                max(math.floor(min(fa, fb) - pad), 0), min(math.ceil(max(fa, fb) + pad) + 1, nx))

    @property
    def X(self):
        xs, ys = self.grid.centres()
        return xs[None, :]

    @property
    def Y(self):
        xs, ys = self.grid.centres()
        return ys[:, None]

    def mark(self, path_xy: FloatArray, only: np.ndarray | None = None,
             heights: tuple | None = None, also: np.ndarray | None = None) -> None:
        """Record the cut of the tool along a path at the level: cells within R of it leave
        the uncut grid, and cells the tool covers whole (their centre within R less half a
        diagonal) drop in the surface estimate to the level plus the profile at their
        farthest point, so that the estimate bounds the material over the whole cell; its
        lower bound ``surface_lo`` drops wherever the tool reaches the cell, to the level plus
        the profile at the cell's nearest point.
        Distances come from the path's samples rounded to cells (good to 3/4 cell), exact to
        the path's segments in the band where that rounding could decide either; a path of
        one segment (most calls) has them exact over its whole window, at less cost.  With
        ``only``, the cells leave that grid of uncut cells and nothing else changes.  With
        ``heights`` (low, high) the path is not at the level but between those tip heights
        (a descent's): the estimate drops to the high one plus the profile, its lower bound
        and the floor to the low one.  With ``also`` (a grid of uncut cells, not with
        ``only``) the cells within R leave that grid too."""
        path_xy = np.asarray(path_xy, dtype=float)
        if len(path_xy) == 2:
            (ax, ay), (bx, by) = path_xy.tolist()
            i0, i1, j0, j1 = self.window_of(ax, ay, bx, by, self.Rc + 2)
            g = self.grid
            if kernels.use_numba():
                ab = path_xy[1] - path_xy[0]
                try:
                    self._mark_kernel(_mk.mark_segment, only, heights, also, i0, i1, j0, j1,
                                      g.x0, g.y0, g.cell, ax, ay, bx - ax, by - ay,
                                      max(float(ab @ ab), 1e-300))
                    return
                except kernels.KernelUnavailable:
                    pass
            xs = g.x0 + (np.arange(j0, j1) + 0.5) * g.cell
            ys = g.y0 + (np.arange(i0, i1) + 0.5) * g.cell
            dist = _segment_distance(xs, ys, path_xy)
            dist_lo = dist
        else:
            f = self.idx(_densify(path_xy, 0.5 * self.cell))
            i0, i1, j0, j1 = self.window(f, self.Rc + 2)
            m = np.zeros((i1 - i0, j1 - j0), bool)
            ii = np.clip(np.rint(f[:, 1]).astype(int) - i0, 0, i1 - i0 - 1)
            jj = np.clip(np.rint(f[:, 0]).astype(int) - j0, 0, j1 - j0 - 1)
            m[ii, jj] = True
            d = capped_distance(m, self.Rc + 1)
            dist = np.minimum(d + 0.75, self.Rc + 1.0) * self.cell  # >= the true distance
            dist_lo = np.maximum(d - 0.75, 0.0) * self.cell  # <= it
            band = np.flatnonzero((d > self.Rc - 3.0) & (d <= self.Rc + 1.0))
            if len(band):
                by, bx = np.divmod(band, j1 - j0)
                pts = self.xy(np.column_stack([bx + j0, by + i0]).astype(float))
                dist.flat[band] = dist_lo.flat[band] = _polyline_distance(pts, path_xy)
            if kernels.use_numba():
                try:
                    self._mark_kernel(_mk.mark_field, only, heights, also, i0, j0, dist,
                                      dist_lo)
                    return
                except kernels.KernelUnavailable:
                    pass
        cut = dist <= self.R
        if only is not None:  # that grid of uncut cells only
            only[i0:i1, j0:j1] &= ~cut
            return
        z_lo, z_hi = (self.z, self.z) if heights is None else heights
        self.uncut[i0:i1, j0:j1] &= ~cut
        if also is not None:
            also[i0:i1, j0:j1] &= ~cut
        fl = self.floor[i0:i1, j0:j1]
        fl[cut] = np.minimum(fl[cut], z_lo)
        # the estimate bounds the material's top over the whole cell: a cell drops only where
        # its farthest point (half a diagonal out) lies within the tool, to the profile there
        far = dist + CELL_HALF_DIAGONAL * self.cell
        whole = far <= self.R
        sf = self.surface[i0:i1, j0:j1]
        sf[whole] = np.minimum(sf[whole], z_hi + self.tool.profile(far[whole]))
        # and its lower bound: the tool's lowest point over the cell, where it reaches any
        near = dist_lo - CELL_HALF_DIAGONAL * self.cell
        some = near <= self.R
        lo = self.surface_lo[i0:i1, j0:j1]
        lo[some] = np.minimum(lo[some], z_lo + self.tool.profile(np.maximum(near[some], 0.0)))

    def _mark_kernel(self, kernel, only, heights, also, *where) -> None:
        """:meth:`mark` by one of :mod:`~BSplineCAM.core.kernels.roughing_mark_kernels`
        (``where``: its arguments between the grids and the tool's)."""
        z_lo, z_hi = (self.z, self.z) if heights is None else heights
        grids = (self.uncut, self.floor, self.surface, self.surface_lo) if only is None else \
            (only, self.floor, self.surface, self.surface_lo)
        kernel(*grids, only is None, grids[0] if also is None else also, also is not None,
               *where, float(self.R),
               float(CELL_HALF_DIAGONAL * self.cell), float(z_lo), float(z_hi),
               _mk.SHAPES[self.tool.shape.value], float(self.tool.corner_radius))

    def safe_at(self, q: FloatArray, z: float) -> float:
        """Lowest tip height (>= z) at q (xy) where the tool meets none of the material the
        surface estimate holds (:meth:`safe_heights` of one point)."""
        return float(self.safe_heights(np.asarray(q, dtype=float)[None, :], z)[0])

    def safe_heights(self, qs: FloatArray, z: float) -> FloatArray:
        """:meth:`safe_at` of each point of qs (n, 2): the highest cell of the surface estimate
        within the tool's disk less the tool's profile there, the cells taken 3/4 cell nearer
        for their size (the profile of a bull-nose or ball rises steeply at its rim), at
        least z."""
        f = self.idx(np.asarray(qs, dtype=float))
        base = np.floor(f).astype(int)
        k = int(math.ceil(self.Rc + 0.75)) + 1
        o = np.arange(-k, k + 2)
        oj, oi = (a.ravel() for a in np.meshgrid(o, o))
        # only offsets that can reach the disk (the point lies within 1.5 cells of its base)
        reach = np.hypot(oj, oi) <= self.Rc + 0.75 + 1.5
        oj, oi = oj[reach], oi[reach]
        jj = base[:, 0:1] + oj[None, :]
        ii = base[:, 1:2] + oi[None, :]
        r = np.hypot(jj - f[:, 0:1], ii - f[:, 1:2]) * self.cell - 0.75 * self.cell
        ny, nx = self.surface.shape
        inside = (r <= self.R) & (jj >= 0) & (jj < nx) & (ii >= 0) & (ii < ny)
        top = np.full(r.shape, -np.inf)
        top[inside] = self.surface[ii[inside], jj[inside]] - self.tool.profile(
            np.maximum(r[inside], 0.0))
        return np.maximum(top.max(axis=1), z)

    def clear_at(self, qs: FloatArray, z: float) -> np.ndarray:
        """Which points of qs (n, 2) the tool may descend straight to z at: :meth:`safe_heights`
        within 0.01 mm of z, measured only where the nearest cell of the estimate above that
        (its distance on the grid, give or take the point's offset from its cell's centre)
        lies neither beyond the tool's reach (clear) nor under its flat bottom (not)."""
        qs = np.asarray(qs, dtype=float)
        f = self.idx(qs)
        i0, i1, j0, j1 = self.window(f, self.Rc + 3)
        high = self.surface[i0:i1, j0:j1] > z + 0.01
        ok = np.ones(len(qs), bool)
        if not high.any():
            return ok
        d = capped_distance(high, self.Rc + 3)
        jr = np.rint(f[:, 0]).astype(int) - j0
        ir = np.rint(f[:, 1]).astype(int) - i0
        # a point off the grid has no cell of its own there: measured
        on = (jr >= 0) & (jr < j1 - j0) & (ir >= 0) & (ir < i1 - i0)
        dq = np.where(on, d[np.clip(ir, 0, i1 - i0 - 1), np.clip(jr, 0, j1 - j0 - 1)], np.nan)
        far = (dq - CELL_HALF_DIAGONAL - 0.75) * self.cell > self.R
        # such a cell within the tool's flat bottom (where its profile is 0) blocks it
        tool = self.tool
        flat = {"flat": self.R, "bullnose": self.R - tool.corner_radius}.get(tool.shape.value,
                                                                             0.0)
        blocked = (dq + CELL_HALF_DIAGONAL - 0.75) * self.cell <= flat
        ok[blocked] = False
        near = ~(far | blocked)  # NaN (off the grid) is neither
        if near.any():
            ok[near] = self.safe_heights(qs[near], z) <= z + 0.01
        return ok

    def link_ok(self, p: tuple, q: tuple, z: float) -> bool:
        """A feed from p to q at level z stays in {T <= z} and its tool meets no uncut
        material (within the grid's rounding of the cut region)."""
        if not self.in_region(p, q, z):
            return False
        f = self.along(p, q)
        i0, i1, j0, j1 = self.window(f, self.Rc + 3)
        sub = self.uncut[i0:i1, j0:j1]
        if not sub.any():
            return True
        d = capped_distance(sub, self.Rc + 2)
        return bool(np.all(_bilinear(d, f[:, 0] - j0, f[:, 1] - i0) >= self.Rc - 1.25))

    def along(self, a, b) -> FloatArray:
        """Fractional grid indices of points half a cell apart along the segment a-b (xy)."""
        return self.idx(_densify(np.array([a[:2], b[:2]], dtype=float), 0.5 * self.cell))

    def in_region(self, a, b, z) -> bool:
        """The straight feed from a to b (xy) stays in {T <= z}."""
        return bool(self.in_region_many(np.asarray(a, dtype=float)[None, :2],
                                        np.asarray(b, dtype=float)[None, :2], z)[0])

    def in_region_many(self, A: FloatArray, B: FloatArray, z: float) -> np.ndarray:
        """:meth:`in_region` of the feeds from A[i] to B[i] (n, 2), sampled at once: the
        points of :func:`_densify` of each, half a cell apart."""
        if kernels.use_numba():
            g = self.grid
            try:
                return _sk.in_region(self.T, np.ascontiguousarray(A, dtype=float),
                                     np.ascontiguousarray(B, dtype=float), g.x0, g.y0, g.cell,
                                     0.5 * self.cell, float(z + 1e-3))
            except kernels.KernelUnavailable:
                pass
        D = B - A
        owner, t = _pieces(D, 0.5 * self.cell)
        pts = np.concatenate([A, A[owner] + t[:, None] * D[owner]])
        f = self.idx(pts)
        high = _bilinear(self.T, f[:, 0], f[:, 1]) > z + 1e-3
        out = ~high[:len(A)]
        out &= np.bincount(owner, weights=high[len(A):], minlength=len(A)) == 0
        return out

    def path_in_region(self, path: FloatArray, z: float) -> bool:
        """Every feed along the polyline ``path`` (xy) stays in {T <= z} (:meth:`in_region`
        of each, sampled at once)."""
        p = np.asarray(path, dtype=float)[:, :2]
        a, b = (p[:-1], p[1:]) if len(p) > 1 else (p, p)
        return bool(self.in_region_many(a, b, z).all())

    def travel_height(self, a: FloatArray, b: FloatArray) -> float:
        """Height (mm) at which a rapid from a to b (xy) meets no material: the highest
        surface estimate within the tool radius plus two cells of the segment, plus
        TRAVEL_GAP_MM."""
        path = np.array([a, b], dtype=float)
        f = self.idx(path)
        i0, i1, j0, j1 = self.window(f, self.Rc + 3)
        jj, ii = np.meshgrid(np.arange(j0, j1), np.arange(i0, i1))
        sub = self.surface[i0:i1, j0:j1]
        high = sub > -np.inf
        if not high.any():
            return -np.inf
        pts = self.xy(np.column_stack([jj[high], ii[high]]).astype(float))
        near = _polyline_distance(pts, path) <= self.R + 2 * self.cell
        return float(sub[high][near].max(initial=-np.inf)) + TRAVEL_GAP_MM
