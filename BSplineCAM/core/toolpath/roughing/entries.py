# SPDX-License-Identifier: LGPL-2.1-or-later
"""How a pass is reached and entered: stay-down links and lead-ins, straight descents where the
tool's disk is clear, ramps along the pass, and the entries into closed pockets: helices,
zig-zag ramps along a chord and, with a centre-cutting end mill, straight plunges."""

from __future__ import annotations

import math

import numpy as np

from ...typing import FloatArray
from .constants import (
    _EPS,
    BACK_RAMP_ROUNDS,
    BACK_RAMP_TOL_MM,
    CHORD_DIRECTIONS,
    GRID_GROWTH_CELLS,
    HELIX_CHORD_MM,
    LEAD_IN_DIAMETERS,
    LEAD_IN_LATTICE,
    LEAD_IN_REACH_RADII,
    LEAD_IN_ROUTES,
    LEAD_IN_TRIES,
    ZIGZAG_MIN_DIAMETERS,
)
from .contours import marching_squares
from .gridops import _densify, capped_distance, same_point, squared_distance
from .passes import _chord_angle
from .rings import _Ring


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
        closed = len(p) > 2 and same_point(p[0], p[-1])
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

    def enter(self, mask: np.ndarray, z: float, z_above: float) -> tuple | None:
        """Enter a component of the level's allowed centres not reaching air (a closed pocket
        or hole): by a helix where one fits (:meth:`helix`), else by a zig-zag ramp along its
        longest straight chord where that is at least ZIGZAG_MIN_DIAMETERS tool diameters
        long (:meth:`zigzag`; a centre-cutting tool ramps there too), else, with a
        centre-cutting tool (``centre_cutting``), by a straight plunge at its point farthest
        from the walls (:meth:`plunge`); the last two end with a lap round the component's
        boundary.  Returns the cells the level's fronts grow from (the helix's disc, the
        ramp's chord, the cells round the plunge's point) and the ring round them
        (:class:`~.rings._Ring`, None for a chord), or None where none of these enters it:
        the pocket is then left, recorded in ``skipped`` (level, the level above, its place,
        the XY box of its walls, the largest tool diameter whose helix would enter it) for
        the run's note (:meth:`~.job._Job.report_leftover`)."""
        cell = self.cell
        idx = np.argwhere(mask)
        i0, j0 = idx.min(axis=0) - 1
        i1, j1 = idx.max(axis=0) + 2
        i0, j0 = max(i0, 0), max(j0, 0)
        sub = mask[i0:i1, j0:j1]
        d = np.sqrt(squared_distance(~sub))
        d[~sub] = 0.0
        at = int(np.argmax(d))
        ci, cj = divmod(at, sub.shape[1])
        cx, cy = (float(v) for v in self.xy(np.array([[cj + j0, ci + i0]], dtype=float))[0])
        near_rim = capped_distance(mask, self.s / cell + 2) * cell <= self.s
        r_fit = (float(d.flat[at]) - 1.5) * cell
        if r_fit >= max(2 * cell, 0.05 * self.tool.diameter):
            rh = self.helix(cx, cy, r_fit, z)
            seed = mask & ((self.X - cx) ** 2 + (self.Y - cy) ** 2 <= rh * rh)
            return seed, _Ring(mask, (cx, cy), rh, near_rim)
        chord = _longest_chord(d >= 1.5, ci, cj)
        if chord is not None:
            ends = self.xy(np.array([[c[1] + j0, c[0] + i0] for c in chord], dtype=float))
            if math.dist(ends[0], ends[1]) >= ZIGZAG_MIN_DIAMETERS * self.tool.diameter - 1e-9:
                self.zigzag(ends, z, mask)
                seed = np.zeros_like(mask)
                seed[i0:i1, j0:j1] = _segment_cells(sub.shape, chord) & (d >= 1.0)
                return seed, None
        if self.centre_cutting:
            self.plunge(cx, cy, z, mask)
            r0 = 1.5 * cell  # the cells round the point: the fronts' seed
            seed = mask & ((self.X - cx) ** 2 + (self.Y - cy) ** 2 <= r0 * r0)
            seed[ci + i0, cj + j0] = True
            return seed, _Ring(mask, (cx, cy), r0, near_rim)
        iy, ix = np.nonzero(sub)
        lo = self.xy(np.array([[ix.min() + j0, iy.min() + i0]], dtype=float))[0]
        hi = self.xy(np.array([[ix.max() + j0, iy.max() + i0]], dtype=float))[0]
        # the pocket's walls: the allowed centres' cells grown by the tool radius, the radial
        # allowance and the tip map's growth (half a cell to a cell's edge)
        grow = self.R + self.ar + (GRID_GROWTH_CELLS + 0.5) * cell
        box = (float(lo[0]) - grow, float(hi[0]) + grow, float(lo[1]) - grow,
               float(hi[1]) + grow)
        self.skipped.append((z, z_above, cx, cy, box,
                             self.entering_diameter(float(d.flat[at]) * cell)))
        return None

    def entry_top(self, pts: FloatArray, z: float) -> float:
        """Height (mm) an entry over the points pts (n, 2) starts its descent at: the highest
        :meth:`safe_at` among them (the material the surface estimate holds there)."""
        return float(self.safe_heights(np.asarray(pts, dtype=float), z).max())

    def start_entry(self, x: float, y: float, top: float) -> int:
        """Retract, rapid over (x, y) and down to 1 mm above ``top``, feed to ``top``; the
        index of the first move of the entry."""
        w = self.writer
        w.retract()
        first = len(w.moves)
        w.add("rapid", x, y, w.clear)
        if top + 1.0 < w.clear:
            w.add("rapid", x, y, top + 1.0)
        w.add("feed", x, y, top)
        return first

    def helix(self, cx: float, cy: float, r_fit: float, z: float) -> float:
        """Helical entry round (cx, cy) (mm) of radius min(0.4 D, 0.8 R, r_fit) at the ramp
        angle down to level z from the material's top, a last flat turn at z; its radius."""
        rh = min(0.4 * self.tool.diameter, 0.8 * self.R, r_fit)
        w = self.writer
        sx, sy = cx + rh, cy
        z_above = self.safe_at(np.array([sx, sy]), z)
        first = self.start_entry(sx, sy, z_above)
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
        self.mark(np.column_stack([px, py]))
        # the core within R - rh of the centre
        self.mark(np.array([[cx, cy], [cx, cy]]))
        return rh

    def zigzag(self, ends: FloatArray, z: float, mask: np.ndarray) -> None:
        """Zig-zag ramp along the chord ``ends`` (2, 2) (mm) of the component ``mask`` of the
        level's allowed centres: from the highest material along it (:meth:`entry_top`) back
        and forth between its ends at the ramp angle, down to the height from which the
        component's boundary (:meth:`lap_from`) ramped down once at the ramp angle reaches
        level z (the last sweep turning back short where a whole one would go too low; the
        ramp starts in the air above the material where that is less high), then that lap
        and one more round it at z (:meth:`ramp_round`), every move of which descends or
        runs on the descent's track (an entry, as the job simulation counts them): the boundary lies within a
        few cells of the chord (no helix fits), so the lap at z also cuts the wedge the
        sweeps left along it.  Without such a lap the ramp goes on down to z, to the end it
        was heading for and back along the whole chord at z."""
        w = self.writer
        slope = self.ramp_slope
        a, b = np.asarray(ends[0], dtype=float), np.asarray(ends[1], dtype=float)
        length = float(np.hypot(*(b - a)))
        top = self.entry_top(_densify(np.array([a, b]), self.cell), z)
        laps = [self.lap_from(mask, a), self.lap_from(mask, b)]
        if laps[0] is not None:
            # at least the lap's whole ramp (in the air above the material if need be)
            top = max(top, z + slope * laps[0][0])
        first = self.start_entry(a[0], a[1], top)
        here, there, h = a, b, top
        if all(lap is not None for lap in laps):
            k = 0  # the lap from ``here``: laps[k]
            while True:
                lead, route = laps[k]
                need = slope * lead  # the drop round the lap (and the feed to it) from here
                if h - z <= need + 1e-9:
                    break
                if h - z - need < slope * length:
                    # a whole sweep would go too low: out and back part of the way
                    t = 0.5 * (h - z - need) / slope
                    p = here + (there - here) * (t / length)
                    h -= slope * t
                    w.add("feed", p[0], p[1], h)
                    h = z + need
                    w.add("feed", here[0], here[1], h)
                    break
                h -= slope * length
                w.add("feed", there[0], there[1], h)
                here, there, k = there, here, 1 - k
            self.ramp_round(here, h, route, z)
        else:
            drop = h - z
            while drop > _EPS:
                step = min(length, drop / slope)
                drop -= step * slope
                p = here + (there - here) * (step / length)
                w.add("feed", p[0], p[1], z + max(drop, 0.0))
                if step < length - 1e-9:
                    break
                here, there = there, here
            w.add("feed", there[0], there[1], z)
            w.add("feed", here[0], here[1], z)
        self.entry_spans.append([first, len(w.moves)])
        self.zigzags += 1
        self.passes += 1
        self.mark(np.array([a, b]))

    def plunge(self, cx: float, cy: float, z: float, mask: np.ndarray) -> None:
        """Straight plunge at (cx, cy) (mm), for an end mill that cuts at its centre, into the
        component ``mask`` of the level's allowed centres, then its boundary (:meth:`lap_from`)
        ramped down once at the ramp angle and lapped once more at level z
        (:meth:`ramp_round`).  The plunge, from the material's top (:meth:`entry_top`), stops
        as high above z as that ramp descends (starting above the material where that is
        less high).  The lap takes the ring between the plunge's
        reach and the wall, which the level's wall pass would take as a sliver thinner than
        its tolerance and leave; in a hole barely wider than the tool it is all that is left.
        Where no such lap is found, only the plunge is made."""
        w = self.writer
        c = np.array([cx, cy])
        lap = self.lap_from(mask, c)
        top = self.entry_top(np.array([[cx, cy]]), z)
        if lap is not None:
            top = max(top, z + self.ramp_slope * lap[0])
        first = self.start_entry(cx, cy, top)
        if lap is None:
            w.add("feed", cx, cy, z)
        else:
            start = z + self.ramp_slope * lap[0]
            w.add("feed", cx, cy, start)
            self.ramp_round(c, start, lap[1], z)
        self.entry_spans.append([first, len(w.moves)])
        self.plunges += 1
        self.passes += 1
        self.mark(np.array([c, c]))

    def lap_from(self, mask: np.ndarray, at: FloatArray) -> tuple | None:
        """The boundary of the component ``mask`` of the allowed centres (:meth:`_wall_loop`)
        as a closed route (xy, mm) from its point nearest ``at``, and the length (mm) of the
        feed from ``at`` to it and round it; None if there is none or that feed leaves the
        component."""
        loop = self._wall_loop(mask)
        if loop is None:
            return None
        k = int(np.argmin(np.hypot(*(loop[:-1] - at).T)))
        if not self._in_mask(mask, np.asarray(at, dtype=float), loop[k]):
            return None
        route = np.vstack([loop[k:-1], loop[:k + 1]])
        length = float(np.hypot(*(route[0] - at))) + float(
            np.hypot(*np.diff(route, axis=0).T).sum())
        return length, route

    def ramp_round(self, at: FloatArray, h: float, route: FloatArray, z: float) -> None:
        """From ``at`` (xy, mm) at height h feed to the closed ``route`` and round it, down to
        level z evenly by length, then round it again at z; the route is marked cut."""
        w = self.writer
        path = np.vstack([np.asarray(at, dtype=float)[None, :], route])
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))])
        heights = h - (h - z) * arc / max(float(arc[-1]), 1e-12)
        for (x, y), hh in zip(path[1:], heights[1:]):
            w.add("feed", x, y, hh)
        for x, y in route[1:]:
            w.add("feed", x, y, z)
        self.mark(route)

    def _in_mask(self, mask: np.ndarray, a: FloatArray, b: FloatArray) -> bool:
        """The segment a-b (xy, mm) runs through cells of ``mask`` up to half a cell short of
        b (b itself on the mask's boundary, within a cell of an allowed centre)."""
        length = float(np.hypot(*(b - a)))
        if length <= 0.5 * self.cell:
            return True
        end = a + (b - a) * (1.0 - 0.5 * self.cell / length)
        f = np.rint(self.idx(_densify(np.array([a, end]), 0.5 * self.cell))).astype(int)
        ny, nx = mask.shape
        if not ((f[:, 0] >= 0) & (f[:, 0] < nx) & (f[:, 1] >= 0) & (f[:, 1] < ny)).all():
            return False
        return bool(mask[f[:, 1], f[:, 0]].all())

    def _wall_loop(self, mask: np.ndarray) -> FloatArray | None:
        """The longest closed boundary (xy, mm; first point repeated) of the component
        ``mask`` of the allowed centres; None if none."""
        ii, jj = np.nonzero(mask)
        ny, nx = mask.shape
        i0, i1 = max(int(ii.min()) - 2, 0), min(int(ii.max()) + 3, ny)
        j0, j1 = max(int(jj.min()) - 2, 0), min(int(jj.max()) + 3, nx)
        # half-way between its cells and the others: the same loop at every level of a hole
        # with straight walls (T - z would move it by up to a cell with z), and within a cell
        # of an allowed centre, which the tip map's growth covers
        F = np.where(mask[i0:i1, j0:j1], -0.5, 0.5)
        loops = [q for q in marching_squares(F)
                 if len(q) > 3 and same_point(q[0], q[-1])]
        if not loops:
            return None
        q = max(loops, key=lambda q: float(np.hypot(*np.diff(q, axis=0).T).sum()))
        return self.xy(q + np.array([j0, i0], dtype=float))


def _longest_chord(inner: np.ndarray, ci: int, cj: int) -> tuple | None:
    """The longest straight chord through cell (ci, cj) (row, column) of ``inner`` whose points
    half a cell apart all fall in cells of ``inner``, over CHORD_DIRECTIONS directions: its
    ends ((row, column), (row, column)) as fractional indices, or None if (ci, cj) is not in
    ``inner``."""
    if not inner[ci, cj]:
        return None
    ny, nx = inner.shape
    n = 2 * (ny + nx) + 2
    th = np.linspace(0.0, math.pi, CHORD_DIRECTIONS, endpoint=False)
    u = np.column_stack([np.sin(th), np.cos(th)])  # (row, column) per direction
    t = 0.5 * np.arange(1, n + 1)
    reach = []
    for sign in (1.0, -1.0):
        r = np.rint(ci + sign * u[:, :1] * t[None, :]).astype(int)
        c = np.rint(cj + sign * u[:, 1:] * t[None, :]).astype(int)
        ok = (r >= 0) & (r < ny) & (c >= 0) & (c < nx)
        ok[ok] = inner[r[ok], c[ok]]
        # the last step before the first one out
        stop = np.where(ok.all(axis=1), n, np.argmin(ok, axis=1))
        reach.append(np.where(stop > 0, t[np.maximum(stop - 1, 0)], 0.0))
    total = reach[0] + reach[1]
    k = int(np.argmax(total))
    return ((ci + reach[0][k] * u[k, 0], cj + reach[0][k] * u[k, 1]),
            (ci - reach[1][k] * u[k, 0], cj - reach[1][k] * u[k, 1]))


def _segment_cells(shape: tuple, chord: tuple) -> np.ndarray:
    """Cells (of a grid of ``shape``) the chord ((row, column), (row, column)) passes through,
    sampled half a cell apart."""
    (r0, c0), (r1, c1) = chord
    n = int(math.ceil(2.0 * math.hypot(r1 - r0, c1 - c0))) + 1
    t = np.linspace(0.0, 1.0, n + 1)
    r = np.clip(np.rint(r0 + t * (r1 - r0)).astype(int), 0, shape[0] - 1)
    c = np.clip(np.rint(c0 + t * (c1 - c0)).astype(int), 0, shape[1] - 1)
    out = np.zeros(shape, bool)
    out[r, c] = True
    return out


def _lead_route(p: FloatArray, k: int) -> FloatArray:
    """The route that cuts pass p (xy) from its vertex k, where a lead-in joins it: round a
    closed pass back to k, along an open one back to its start and then all along it."""
    closed = len(p) > 2 and same_point(p[0], p[-1])
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
