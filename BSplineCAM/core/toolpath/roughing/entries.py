# SPDX-License-Identifier: LGPL-2.1-or-later
"""How a pass is reached and entered: stay-down links and lead-ins, straight descents where the
tool's disk is clear, ramps along the pass and helical entries into pockets."""

from __future__ import annotations

import math

import numpy as np

from ...geometry.distance import squared_distance
from ...typing import FloatArray
from .constants import (
    _EPS,
    BACK_RAMP_ROUNDS,
    BACK_RAMP_TOL_MM,
    HELIX_CHORD_MM,
    LEAD_IN_DIAMETERS,
    LEAD_IN_LATTICE,
    LEAD_IN_REACH_RADII,
    LEAD_IN_ROUTES,
    LEAD_IN_TRIES,
)
from .passes import _chord_angle


class _Entries:
    """Part of a roughing run (:class:`~.job._Job`): the entries into its passes, written by
    its writer and marked on its grid state (:class:`~.state._GridState`)."""

    def lead_in(self, p: FloatArray, z: float) -> int | None:
        """Index k of a vertex of pass p (xy) that the tool, at level z nearby, may reach by
        a straight feed cutting no wider than the stepover and staying
        in {T <= z}: the first such vertex within LEAD_IN_DIAMETERS tool diameters along p."""
        w = self.writer
        if w.pos is None or abs(w.pos[2] - z) > 1e-9:
            return None
        here = np.array(w.pos[:2])
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
        for k in range(1, len(p)):
            if arc[k] > LEAD_IN_DIAMETERS * self.tool.diameter:
                break
            q = p[k]
            if math.dist(here, q) > 10 * self.tool.diameter:
                continue
            if self.in_region(here, q, z) and self.engaged_width(here, q) <= self.s:
                return k
        return None

    def cleared_lead_in(self, p: FloatArray, z: float) -> tuple | None:
        """A straight descent and a lead-in into pass p (xy) on level z from the floor already
        cut: a point c within LEAD_IN_REACH_RADII tool radii of the pass's start and a tool
        diameter of the stock's footprint, where the surface estimate leaves the tool's disk
        clear down to z, and the index k of a vertex within LEAD_IN_DIAMETERS tool diameters
        along p, such that the feed from c to p[k] stays in {T <= z} and its whole swath is no
        wider than the stepover (:meth:`engaged_width`), and the route's first moves after it
        (for k > 0 back to the start and on), up to a diameter past p[k], within 1.1 stepover
        (:meth:`runs_within`, at most LEAD_IN_ROUTES routes).  The start is tried first, then
        the vertices along; in each, the shortest feeds first, at most LEAD_IN_TRIES of them;
        (c, k) or None."""
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
        ks = np.flatnonzero(arc <= LEAD_IN_DIAMETERS * self.tool.diameter)
        ks = ks[:: max(1, len(ks) // 8)]
        step = max(self.cell, LEAD_IN_LATTICE * self.R)
        reach = LEAD_IN_REACH_RADII * self.R
        n = int(reach / step)
        g = np.arange(-n, n + 1) * step
        off = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
        off = off[np.hypot(off[:, 0], off[:, 1]) <= reach]
        C = p[0] + off
        # by the stock, not farther out in the air than a tool diameter beyond its rim
        f = np.rint(self.idx(C)).astype(int)
        ny, nx = self.T.shape
        inside = (f[:, 0] >= 0) & (f[:, 0] < nx) & (f[:, 1] >= 0) & (f[:, 1] < ny)
        f = f[inside]
        C = C[inside][self.outside_mm[f[:, 1], f[:, 0]] <= 2 * self.R]
        C = C[self.clear_at(C, z)] if len(C) else C
        if not len(C):
            return None
        dist = np.hypot(C[:, None, 0] - p[ks][None, :, 0], C[:, None, 1] - p[ks][None, :, 1])
        # the start first, then further along (whence the route runs back to the start); the
        # route's first moves, up to a diameter past where the lead-in joined it, must cut
        # within 1.1 stepover too (a start at a wall could be met head-on)
        checked = 0
        for group in (ks == 0, ks > 0):
            sub = np.where(group[None, :], dist, np.inf)
            tries = np.argsort(sub, axis=None, kind="stable")[:LEAD_IN_TRIES]
            tries = tries[np.isfinite(sub.flat[tries])]
            # the feeds of the tries in one go: long enough, in the region, narrow enough
            ci_all, kj_all = np.divmod(tries, len(ks))
            good = dist[ci_all, kj_all] > 1e-9
            good[good] = self.in_region_many(C[ci_all[good]], p[ks[kj_all[good]]], z)
            good[good] = self.engaged_widths(C[ci_all[good]], p[ks[kj_all[good]]]) <= self.s
            for ci, kj in zip(ci_all[good].tolist(), kj_all[good].tolist()):
                c, k = C[ci], int(ks[kj])
                route = _lead_route(p, k)
                length = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(route, axis=0).T))])
                m = int(np.searchsorted(length, 2.0 * arc[k] + self.tool.diameter))
                if self.runs_within(np.vstack([c, route[:m + 1]])):
                    return c, k
                checked += 1
                if checked >= LEAD_IN_ROUTES:
                    return None
        return None

    def descend(self, q: FloatArray, z: float, over: float) -> None:
        """Lift, rapid over q, rapid down to ``over`` and feed down to z.  The lift goes to
        the clearance height, or only as high as the material along the way needs
        (:meth:`travel_height`) when that is lower."""
        w = self.writer
        h = w.clear
        if w.pos is not None and w.pos[2] < w.clear:
            h = max(self.travel_height(np.array(w.pos[:2]), np.asarray(q, dtype=float)),
                    over, w.pos[2])
            if h < w.clear - 1e-9:
                w.add("rapid", w.pos[0], w.pos[1], h)
                self.lifts += 1
            else:
                h = w.clear
                w.retract()
        w.add("rapid", q[0], q[1], h)
        if over < h:
            w.add("rapid", q[0], q[1], over)
        w.add("feed", q[0], q[1], z)

    def link(self, q: tuple) -> None:
        """A stay-down feed to q (x, y, z) between passes, its index kept in ``links``."""
        n = len(self.writer.moves)
        self.writer.add("feed", *q)
        if len(self.writer.moves) > n:
            self.links.append(n)

    def back_ramp(self, p: FloatArray, z: float, top: float,
                  slope: float) -> tuple | None:
        """A ramp into the open pass p (xy) that reaches level z at its start, so that the pass
        follows without going back over the ramp: the walk of length L = (h - z) / ``slope``
        (dz/dxy) from the start along p (back and forth along a shorter p, as
        :func:`_ramp`), taken from its far end backwards, h the height there that clears the
        material (:meth:`safe_at`, at least ``top``).  Returns the ramp's top (x, y, h) and
        its points (k, 3) down to the start, or None if no such height is found."""
        height = top
        for _ in range(BACK_RAMP_ROUNDS):
            fwd, _ = _ramp(p, False, height - z, slope)
            walk = np.vstack([p[:1], fwd[:, :2]])
            h = self.safe_at(walk[-1], z)
            # the far end moves with the height: where the material's top slopes along the
            # pass (beside a stock's rim under a ball) the heights converge geometrically
            if h <= height + BACK_RAMP_TOL_MM:
                break
            height = h
        else:
            return None
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(walk, axis=0).T))])
        ramp = np.column_stack([walk[:-1][::-1], z + slope * arc[:-1][::-1]])
        return (float(walk[-1, 0]), float(walk[-1, 1]), height), ramp

    def cut_path(self, p: FloatArray, z: float, z_above: float) -> None:
        """Reach the start of pass p (xy) on level z and cut it: a straight stay-down link if
        it meets no uncut material, or a stay-down lead-in to a vertex a few diameters along
        the pass that cuts within the stepover (:meth:`lead_in`); else lift (:meth:`descend`)
        and descend straight at the start where the surface estimate leaves the tool's disk
        clear down to z, or on the floor already cut near it, followed by a lead-in to the
        start or a vertex along the pass (:meth:`cleared_lead_in`); else ramp down along the
        pass itself at the ramp angle from the surface: along an open pass backwards to its
        start (:meth:`back_ramp`), round a closed one from its start."""
        w = self.writer
        closed = len(p) > 2 and bool(np.allclose(p[0], p[-1]))
        q = (float(p[0, 0]), float(p[0, 1]), z)
        route = p
        if w.pos is not None and abs(w.pos[2] - z) < 1e-9 and \
                math.dist(w.pos[:2], q[:2]) <= 10 * self.tool.diameter and \
                self.link_ok(w.pos, q, z):
            self.link(q)
        elif (k := self.lead_in(p, z)) is not None:
            # a stay-down feed into the pass at k within the stepover, then the pass: round a
            # closed one back to k, an open one back to its start and then all along it
            here = np.array(w.pos[:2])
            self.link((float(p[k, 0]), float(p[k, 1]), z))
            self.mark(np.array([here, p[k]]))
            route = _lead_route(p, k)
        elif (top := self.safe_at(p[0], z)) <= z + 0.01:
            self.descend(p[0], z, z + 1.0)
        elif (lead := self.cleared_lead_in(p, z)) is not None:
            c, k = lead
            self.descend(c, z, z + 1.0)
            self.link((float(p[k, 0]), float(p[k, 1]), z))
            self.mark(np.array([c, p[k]]))
            self.lead_ins += 1
            route = _lead_route(p, k)
        else:
            slope = self.ramp_slope
            back = None if closed else self.back_ramp(p, z, top, slope)
            if back is not None:
                # down along the pass backwards to its start, then the whole pass
                start, ramp = back
                self.descend(start[:2], start[2], start[2] + 1.0)
                first = len(w.moves)
                route = p
            else:
                self.descend(p[0], top, top + 1.0)
                first = len(w.moves)
                ramp, route = _ramp(p, closed, top - z, slope)
                ramp[:, 2] += z
            for x, y, zz in ramp:
                w.add("feed", x, y, zz)
            self.entry_spans.append([first, len(w.moves)])
            self.ramps += 1
        for x, y in route[1:]:
            w.add("feed", x, y, z)
        self.passes += 1
        self.mark(p)

    def entering_diameter(self, reach: float) -> float:
        """The largest tool diameter (mm) whose helix fits a pocket where this tool's centre
        reaches ``reach`` mm from the pocket's middle (0 when none the grid resolves): the
        pocket is this tool's radius wider than its centre's reach, and a tool of radius r
        needs its centre's reach to hold the helix's smallest radius as :meth:`helix` asks,
        max(2 cells, 0.1 r), beside the 1.5 cells kept from the walls."""
        pocket = reach + self.R
        radius = min(pocket - 3.5 * self.cell, (pocket - 1.5 * self.cell) / 1.1)
        return max(0.0, 2.0 * radius)

    def helix(self, mask, z, z_above):
        """Helical entry into a component not reaching air; (cx, cy, radius) or None."""
        idx = np.argwhere(mask)
        i0, j0 = idx.min(axis=0) - 1
        i1, j1 = idx.max(axis=0) + 2
        i0, j0 = max(i0, 0), max(j0, 0)
        sub = mask[i0:i1, j0:j1]
        d = np.sqrt(squared_distance(~sub))
        d[~sub] = 0.0
        at = int(np.argmax(d))
        ci, cj = divmod(at, sub.shape[1])
        r_fit = (float(d.flat[at]) - 1.5) * self.cell
        r_min = max(2 * self.cell, 0.05 * self.tool.diameter)
        cx, cy = self.xy(np.array([[cj + j0, ci + i0]], dtype=float))[0]
        if r_fit < r_min:
            self.skipped.append((z, float(cx), float(cy), mask.sum() * self.cell ** 2,
                                 self.entering_diameter(float(d.flat[at]) * self.cell)))
            return None
        rh = min(0.4 * self.tool.diameter, 0.8 * self.R, r_fit)
        w = self.writer
        w.retract()
        first = len(w.moves)
        sx, sy = cx + rh, cy
        w.add("rapid", sx, sy, w.clear)
        z_above = self.safe_at(np.array([sx, sy]), z)
        if z_above + 1.0 < w.clear:
            w.add("rapid", sx, sy, z_above + 1.0)
        w.add("feed", sx, sy, z_above)
        dth = _chord_angle(rh, HELIX_CHORD_MM)
        per_turn = 2 * math.pi * rh * self.ramp_slope
        # at least one turn down, so that the helix ends where it began and its last flat
        # turn only trims the wedge the descent left (a shallow drop goes down more gently)
        turns = max((z_above - z) / per_turn, 1.0 if z_above > z + _EPS else 0.0)
        total = 2 * math.pi * (turns + 1.0)
        n = max(8, int(math.ceil(total / dth)))
        th = np.linspace(0.0, total, n + 1)[1:]
        zz = np.maximum(z_above - (z_above - z) * th / max(2 * math.pi * turns, 1e-12), z)
        # clockwise: the material outside stays on the left (climb)
        px, py = cx + rh * np.cos(-th), cy + rh * np.sin(-th)
        for x, y, zh in zip(px, py, zz):
            w.add("feed", x, y, zh)
        self.entry_spans.append([first, len(w.moves)])
        self.helical += 1
        self.passes += 1
        ring = np.column_stack([px, py])
        self.mark(ring)
        # the core within R - rh of the centre
        self.mark(np.array([[cx, cy], [cx, cy]]))
        return float(cx), float(cy), rh


def _lead_route(p: FloatArray, k: int) -> FloatArray:
    """The route that cuts pass p (xy) from its vertex k, where a lead-in joins it: round a
    closed pass back to k, along an open one back to its start and then all along it."""
    closed = len(p) > 2 and bool(np.allclose(p[0], p[-1]))
    return np.vstack([p[k:-1], p[:k + 1]]) if closed else np.vstack([p[k::-1], p[1:]])


def _ramp(p: FloatArray, closed: bool, drop: float, slope: float) -> tuple:
    """Points (x, y, height above the level) descending ``drop`` (mm) at ``slope``
    (dz/dxy) along pass p from its start (round a closed pass, back and forth along an open
    one), and the route (xy) at the level from where the ramp ends through the whole pass."""
    need = drop / slope
    n = len(p)
    if n < 2 or need <= 0 or not np.hypot(*np.diff(p, axis=0).T).sum() > 1e-12:
        return np.empty((0, 3)), p  # nothing to ramp along (the walk would never end)
    out = []
    length = 0.0
    i, step = 0, 1
    while True:
        j = i + step
        if closed and j == n:
            i, j = 0, 1
        elif not closed and not 0 <= j < n:
            step = -step
            j = i + step
        seg = float(np.hypot(*(p[j] - p[i])))
        if length + seg >= need:
            t = (need - length) / seg if seg > 0 else 1.0
            end = p[i] + t * (p[j] - p[i])
            out.append((end[0], end[1], 0.0))
            break
        length += seg
        out.append((p[j][0], p[j][1], drop - length * slope))
        i = j
    ramp = np.array(out, dtype=float)
    end = ramp[-1, :2]
    if closed:
        # from the end point forwards round the loop back to it (segment i -> j, j = i + 1)
        route = np.vstack([end, p[j:-1], p[:j], end])
    else:
        # back along the pass to its start, then the whole pass
        k = min(i, j)
        route = np.vstack([end, p[k::-1], p[1:]])
    return ramp, route
