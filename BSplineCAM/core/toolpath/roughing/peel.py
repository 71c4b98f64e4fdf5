# SPDX-License-Identifier: LGPL-2.1-or-later
"""Peeling: a level's feed moves still wider than the bound cut instead by a few feeds each
within it that take the same material."""

from __future__ import annotations

import math

import numpy as np

from ...simulation.simulate import ToolShape
from ...typing import FloatArray
from ..common import Move
from .constants import PEEL_APPROACHES, PEEL_LATTICE, PEEL_SLACK_MM, PEEL_STEPS, PEEL_WIDTH
from .gridops import _bilinear, _polyline_distance


class _Peel:
    """Part of a roughing run (:class:`~.job._Job`): the peel of a level's moves, measured in
    its replay (:class:`~.replay._Replay`)."""

    def peel_level(self, z: float, widest: float | None = None) -> None:
        """Replay the level's feed moves at z outside its entries in order, as
        :meth:`widest_cut` does, and cut each one wider than PEEL_OVER stepovers by
        :meth:`peel` instead, where that finds a way; then mark the new moves on the run's
        state too.  The entry spans and links after a peeled move shift with it.  For flat
        and bull-nose end mills (a bull-nose's width counts the fillets its corner shaves, as
        :meth:`engaged` measures them); not for a ball, whose passes' cusps the flat
        replay does not hold.  ``widest``: the level's widest cut (:meth:`widest_cut`) when
        known; none wider than PEEL_OVER stepovers, the replay would peel nothing."""
        if self.tool.shape is ToolShape.BALL:
            return
        over = self.peel_over * self.s
        if widest is not None and widest <= over:
            return
        moves = self.writer.moves
        first = self.level_first
        out = list(moves[:max(first, 1)])
        added = np.zeros(len(moves) + 1, int)  # moves added before each old index
        extra = 0
        peeled: list = []

        def visit(i: int, m: Move, ab: tuple | None) -> None:
            nonlocal extra
            added[i] = extra
            way = None
            if ab is not None and self.level_width(*ab) > over:
                way = self.peel(np.array(ab[0]), np.array(ab[1]), z)
            if way is None:
                if ab is not None:
                    self.mark_both(np.array(ab))
                out.append(m)
            else:
                out.extend(Move("feed", float(x), float(y), z) for x, y in way[1:])
                extra += len(way) - 2
                peeled.append(way)

        self.replay(z, visit)
        if not peeled:
            return
        added[len(moves)] = extra
        self.entry_spans = [[a + added[min(a, len(moves))], b + added[min(b, len(moves))]]
                            if b > first else [a, b] for a, b in self.entry_spans]
        self.links = [k + added[min(k, len(moves))] if k >= first else k for k in self.links]
        self.writer.moves = out
        for way in peeled:
            self.mark(way)
        self.peeled_moves += len(peeled)

    def peel(self, a: FloatArray, b: FloatArray, z: float, slack: float | None = None,
             approach: bool = True) -> FloatArray | None:
        """A way (xy points from a to b at level z, in {T <= z}) that cuts the material the
        feed a-b would cut (its swept uncut cells) in feeds each no wider than PEEL_WIDTH
        stepovers (:meth:`engaged`): greedily, each next point the one, on a lattice
        PEEL_LATTICE tool radii apart within R of the feed, whose feed from the last point
        cuts the most of that material within the width, until the feed to b cuts all that
        is left of it within the width; where no step takes any of it within the width, a
        step to the point whose feed to b is the narrowest (:meth:`peel_detour`: a
        bull-nose's corner shaving the fillets beside); and where none is narrower, a way
        (a peel of its own, without this fallback) to a lattice point whose feed to b takes
        what is left within the width (:meth:`peel_approach`: the material left lies where
        the tool reaches it from b's end only, as a sliver along a wall, which a feed along
        the wall takes thin and one across it wide); at most PEEL_STEPS feeds and
        approaches.  The material is that of the replay's ``uncut_level`` grid, where the
        descents of entries did not cut (a ramp cuts less than the level beside its start).
        The region {T <= z} holds the way up to ``slack`` (mm; None: as high as the feed
        a-b rises over it, :meth:`region_slack`, at most PEEL_SLACK_MM: a contour's corner
        may stand some hundredths of a mm out, and its feed ends there).  None where no way
        is found (the replay's grids are then as they were)."""
        R, width = self.R, PEEL_WIDTH * self.s
        feed = np.array([a, b])
        if slack is None:
            slack = min(self.region_slack(a, b, z), PEEL_SLACK_MM)
        zr = z + slack
        task = np.zeros(self.uncut.shape, bool)
        i0, i1, j0, j1 = self.window(self.idx(feed), self.Rc + 2)
        jj, ii = np.meshgrid(np.arange(j0, j1), np.arange(i0, i1))
        cells = self.xy(np.column_stack([jj.ravel(), ii.ravel()]).astype(float))
        near = (_polyline_distance(cells, feed) <= R).reshape(jj.shape)
        task[i0:i1, j0:j1] = near & self.uncut_level[i0:i1, j0:j1]
        # the lattice: points within R of the feed, not at its start
        h = max(min(PEEL_LATTICE * R, 0.25 * math.dist(a, b)), 2.0 * self.cell)
        n = int(math.ceil((math.dist(a, b) + 2 * R) / h)) + 1
        ox = np.arange(n) * h + min(a[0], b[0]) - R
        oy = np.arange(n) * h + min(a[1], b[1]) - R
        lx, ly = np.meshgrid(ox, oy)
        lat = np.column_stack([lx.ravel(), ly.ravel()])
        lat = lat[_polyline_distance(lat, feed) <= R]
        saved = (self.uncut.copy(), self.floor.copy(), self.surface.copy(),
                 self.surface_lo.copy(), self.uncut_level.copy())
        way = [a]
        here = a
        for _ in range(PEEL_STEPS):
            if math.dist(here, b) < 1e-9 and not task.any():
                return np.array(way)  # a step to b itself took the last of it
            w_b, c_b = self.engaged(here[None, :], b[None, :], task,
                                    material=self.uncut_level)
            if w_b[0] <= width and c_b[0] >= task.sum() and self.in_region(here, b, zr) and \
                    math.dist(here, b) >= 1e-9:
                way.append(b)
                self.mark_both(np.array([here, b]))
                return np.array(way)
            cand = lat[np.hypot(*(lat - here).T) > 0.5 * h]
            cand = cand[self.in_region_many(np.broadcast_to(here, cand.shape).copy(), cand, zr)]
            if not len(cand):
                break
            widths, counts = self.engaged(np.broadcast_to(here, cand.shape).copy(), cand, task,
                                          material=self.uncut_level)
            ok = (widths <= width) & (counts > 0)
            if ok.any():
                q = cand[int(np.flatnonzero(ok)[np.argmax(counts[ok])])]
            else:
                # no step takes the task within the width: what makes the feed to b too
                # wide is material outside it (a bull-nose's corner shaving the fillets of
                # the passes beside): a step within the width to the point whose own feed
                # to b is the narrowest, if narrower than the one from here by a cell
                q = self.peel_detour(cand[widths <= width], b, zr, w_b[0])
                if q is None:
                    sub = self.peel_approach(here, b, z, slack, lat, task) if approach \
                        else None
                    if sub is None:
                        break
                    way.extend(sub[1:])
                    here = sub[-1]
                    task &= self.uncut_level
                    continue
            self.mark_both(np.array([here, q]))
            task &= self.uncut_level
            way.append(q)
            here = q
        self.uncut, self.floor, self.surface, self.surface_lo, self.uncut_level = saved
        return None

    def peel_approach(self, here: FloatArray, b: FloatArray, z: float, slack: float,
                      lat: FloatArray, task: np.ndarray) -> FloatArray | None:
        """For :meth:`peel`: a way from here to one of the lattice points ``lat`` whose feed
        to b stays in the region (up to ``slack``) and takes all of ``task`` within the
        width, by a peel of the feed here-q (:meth:`peel` without this fallback), the
        nearest of PEEL_APPROACHES such points first.  The grids hold the way's cut.  None
        if there is none."""
        to_b = np.broadcast_to(b, lat.shape).copy()
        w, c = self.engaged(lat, to_b, task, material=self.uncut_level)
        good = (w <= PEEL_WIDTH * self.s) & (c >= task.sum()) & \
            (np.hypot(*(lat - here).T) > 1e-9)
        good[good] = self.in_region_many(lat[good], to_b[good], z + slack)
        order = np.flatnonzero(good)
        order = order[np.argsort(np.hypot(*(lat[order] - here).T), kind="stable")]
        for k in order[:PEEL_APPROACHES]:
            sub = self.peel(here, lat[k], z, slack, approach=False)
            if sub is not None:
                return sub
        return None

    def region_slack(self, a: FloatArray, b: FloatArray, z: float) -> float:
        """How far (mm, >= 0) the feed a-b at level z rises over the region {T <= z}: the
        most T (bilinear, as :meth:`in_region` samples it) stands over z along it."""
        f = self.along(a, b)
        return max(0.0, float((_bilinear(self.T, f[:, 0], f[:, 1]) - z).max()))

    def peel_detour(self, cand: FloatArray, b: FloatArray, z: float,
                    now: float) -> FloatArray | None:
        """For :meth:`peel`: of the points ``cand`` (reached within the width), the one whose
        feed to b stays in {T <= z} and is the narrowest (:meth:`engaged`, on
        ``uncut_level``), if narrower than ``now`` (the feed to b from where the peel is) by
        a cell; ties to the nearest to b.  None if there is none."""
        if not len(cand):
            return None
        to_b = np.broadcast_to(b, cand.shape).copy()
        fits = self.in_region_many(cand, to_b, z)
        if not fits.any():
            return None
        cand, to_b = cand[fits], to_b[fits]
        w, _ = self.engaged(cand, to_b, material=self.uncut_level)
        k = int(np.lexsort((np.hypot(*(cand - b).T), w))[0])
        return cand[k] if w[k] <= now - self.cell else None
