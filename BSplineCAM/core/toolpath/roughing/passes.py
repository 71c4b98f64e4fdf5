# SPDX-License-Identifier: LGPL-2.1-or-later
"""The passes along a level's contours: the fronts' and the walls' pieces that meet uncut
material, put on a ring's circle or smoothed or straightened across the stairs of a shallow
wall, and cut nearest next first."""

from __future__ import annotations

import math

import numpy as np

from ...typing import FloatArray
from ..common import simplify
from .constants import RING_CHORD_MM, SMOOTH_ROUNDS, STAIR_CELLS, WALL_SLIVER
from .contours import _stretches, marching_squares
from .gridops import _bilinear, capped_distance, same_point


class _Passes:
    """Part of a roughing run (:class:`~.job._Job`): the passes along the contours of a level,
    each reached and cut by :meth:`~.entries._Entries.cut_path`."""

    def cut_contours(self, F, z, z_above, front, reached=None, circles=(),
                     smooth: np.ndarray | None = None) -> None:
        """Cut the contour F = 0 where the tool meets uncut material.

        With ``front`` (distance to the cleared centres less the step, mm) and ``reached``
        (that distance) the contour is a new front: its front pieces are cut first (climb),
        then the pieces on the walls {T = z} that the front newly reached, each from its end
        nearer the new front towards the old one, so that the strip beside it is already cut.
        Without, the contour is the level's final wall pass.  ``circles``: (component mask,
        the rings round a helix still round (:class:`_Ring`); front pieces of a ring within a
        cell of its circle (the grid's contour of it) are put on it (:meth:`on_circles`) and
        cut in chords within RING_CHORD_MM of it.  ``smooth``: the floor rings' zones
        (:meth:`emit`).
        """
        lines = marching_squares(F)
        if not lines:
            return
        # distance (cells) to uncut material, only around the contour (values beyond the
        # window are not needed: a vertex's window reaches past the tool radius)
        every = np.concatenate(lines)
        i0, i1, j0, j1 = self.window(every, self.Rc + 4)
        du = np.full(F.shape, 1e9)
        sub = self.uncut[i0:i1, j0:j1]
        if sub.any():
            du[i0:i1, j0:j1] = capped_distance(sub, self.Rc + 2)
        back = int(2 * self.Rc) + 2
        fronts, walls = [], []
        for line in lines:
            dv = _bilinear(du, line[:, 0], line[:, 1])
            cuts = dv < self.Rc - 1.25
            if not cuts.any():
                continue
            closed = len(line) > 2 and same_point(line[0], line[-1])
            free, clear = dv >= self.Rc - 1.25, dv >= self.Rc + 1.0
            if front is None:
                for piece in _stretches(line, cuts, free, clear, closed, back):
                    ends = _bilinear(du, piece[[0, -1], 0], piece[[0, -1], 1]) >= self.Rc + 1.0
                    fronts.append(piece[::-1] if ends[1] and not ends[0] else piece)
                continue
            tz = _bilinear(self.T - z, line[:, 0], line[:, 1])
            fr = _bilinear(front, line[:, 0], line[:, 1])
            # front where the front's distance decides the contour; on a flat floor both are
            # about 0 and rounding would cut the front into slivers, each with its own ramp
            is_front = fr >= tz - 0.25 * self.cell
            for piece in _stretches(line, cuts & is_front, free, clear, closed, back):
                # climb, unless only the end is out of the material (saves a ramp)
                ends = _bilinear(du, piece[[0, -1], 0], piece[[0, -1], 1]) >= self.Rc + 1.0
                fronts.append(piece[::-1] if ends[1] and not ends[0] else piece)
            # wall pieces away from the old boundary (distance to it above 1.5 cells)
            new = _bilinear(reached, line[:, 0], line[:, 1]) > 1.5 * self.cell
            for piece in _stretches(line, cuts & ~is_front & new, free, clear, closed, back):
                d = _bilinear(front, piece[:, 0], piece[:, 1])
                closed_piece = len(piece) > 2 and same_point(piece[0], piece[-1])
                walls.append(piece if closed_piece or d[0] >= d[-1] else piece[::-1])
        if circles and fronts:
            fronts, circles = self.on_circles(fronts, circles)
        self.emit(fronts, z, z_above, circles, field=F, smooth=smooth)
        self.emit(self.deep_walls(walls), z, z_above, field=F)

    def on_circles(self, pieces: list, rings: list) -> tuple:
        """The front pieces (fractional indices) with those of each ring put on its circle,
        and the circles ((centre (x, y), radius) mm).  The circle's radius is the one the
        ring's contour has: the median distance from the centre of its points within three
        cells of the ring's radius (the grid's distance fronts fall short of it by up to
        about 0.1 mm a ring); its points within a cell of it are moved onto it radially."""
        every = np.concatenate(pieces)
        ny, nx = self.T.shape
        inside = [ring.mask[np.clip(np.rint(every[:, 1]).astype(int), 0, ny - 1),
                            np.clip(np.rint(every[:, 0]).astype(int), 0, nx - 1)]
                  for ring in rings]
        starts = np.cumsum([0] + [len(p) for p in pieces])
        circles = []
        for ring, mine in zip(rings, inside):
            c = self.idx(np.array([ring.centre]))[0]
            rel = every - c
            dist = np.hypot(rel[:, 0], rel[:, 1])
            near = (np.abs(dist * self.cell - ring.radius) <= 3 * self.cell) & mine
            if not near.any():
                continue
            rc = float(np.median(dist[near]))
            snap = (np.abs(dist - rc) <= 1.0) & mine & (dist > 0)
            every[snap] = c + rel[snap] * (rc / dist[snap])[:, None]
            circles.append((ring.centre, rc * self.cell))
        return [every[a:b] for a, b in zip(starts[:-1], starts[1:])], circles

    def deep_walls(self, walls: list) -> list:
        """The wall pieces (fractional indices) along which the material still uncut after the
        front reaches deeper than WALL_SLIVER of the stepover into the tool's disk; the thinner
        slivers are left to the level's last pass, which follows the whole wall."""
        if not walls:
            return walls
        i0, i1, j0, j1 = self.window(np.concatenate(walls), self.Rc + 4)
        sub = self.uncut[i0:i1, j0:j1]
        if not sub.any():
            return []
        du = capped_distance(sub, self.Rc + 2)
        keep = []
        for piece in walls:
            dv = _bilinear(du, piece[:, 0] - j0, piece[:, 1] - i0)
            if (self.Rc - float(dv.min())) * self.cell >= WALL_SLIVER * self.s:
                keep.append(piece)
        return keep

    def emit(self, stretches: list, z: float, z_above: float, circles=(),
             field: FloatArray | None = None, smooth: np.ndarray | None = None) -> None:
        """Simplify the stretches (fractional indices) within cell/4, and with ``field`` (the
        F whose contour they are) straighten them inwards (:meth:`inner_chords`), and cut
        them, nearest next first; an open stretch is cut in its own direction, a closed one
        from its vertex nearest the tool.  A chord between two points on one of the
        ``circles`` (see :meth:`on_circles`, (centre, radius) mm) is cut as an arc in chords
        within RING_CHORD_MM of it.  With ``smooth`` (cells: the floor rings' zones) a
        stretch wholly inside it is cut as a smooth curve (:meth:`smoothed`) instead of
        straightened."""
        if not stretches:
            return
        pts = [self.xy(p) for p in stretches]
        starts = np.cumsum([0] + [len(p) for p in pts])
        allp = np.concatenate(pts)
        keep = simplify(np.column_stack([allp, np.full(len(allp), z)]), starts,
                        0.25 * self.cell, "planar")
        paths = [allp[a:b][keep[a:b]] for a, b in zip(starts[:-1], starts[1:])]
        if field is not None:
            ny, nx = self.T.shape
            for i, st in enumerate(stretches):
                jj = np.clip(np.rint(st[:, 0]).astype(int), 0, nx - 1)
                ii = np.clip(np.rint(st[:, 1]).astype(int), 0, ny - 1)
                if smooth is not None and smooth[ii, jj].all():
                    paths[i] = self.smoothed(paths[i], z)  # a floor ring's front
                else:
                    paths[i] = self.inner_chords(paths[i], field)
        if circles:
            paths = [_arc_fill(q, circles, RING_CHORD_MM) for q in paths]
        # a stretch that simplification left as one point (two equal ones) would only plunge
        paths = [q for q in paths if len(q) > 1 and np.hypot(*np.diff(q, axis=0).T).sum() > 1e-9]
        remaining = list(range(len(paths)))
        while remaining:
            here = np.array(self.writer.pos[:2]) if self.writer.pos is not None else \
                paths[remaining[0]][0]
            best, best_d, best_i = None, math.inf, 0
            for r in remaining:
                p = paths[r]
                if len(p) > 2 and same_point(p[0], p[-1]):
                    dd = np.hypot(*(p - here).T)
                    i = int(np.argmin(dd))
                    d0 = float(dd[i])
                else:
                    i, d0 = 0, math.dist(here, p[0])
                if d0 < best_d:
                    best, best_d, best_i = r, d0, i
            remaining.remove(best)
            p = paths[best]
            if len(p) > 2 and same_point(p[0], p[-1]) and best_i:
                p = np.concatenate([p[best_i:-1], p[:best_i + 1]])
            self.cut_path(p, z, z_above)

    def smoothed(self, path: FloatArray, z: float) -> FloatArray:
        """A floor ring's front (xy) as a smooth curve in short chords: SMOOTH_ROUNDS rounds
        of Chaikin's corner cutting (1974; the limit is the quadratic B-spline of the
        vertices, inside their polygon's corners), simplified within RING_CHORD_MM; the path
        itself where that leaves {T <= z}.  A chord of a curved front sweeps across more of
        the material ahead of its end than the tangent move the ring step assumes (3 mm
        chords on a 17 mm ring: about 0.5 mm wider)."""
        if len(path) < 3:
            return path
        closed = same_point(path[0], path[-1])
        q = path[:-1] if closed else path
        for _ in range(SMOOTH_ROUNDS):
            nxt = np.roll(q, -1, axis=0)
            cut = np.empty((2 * len(q), 2))
            cut[0::2] = 0.75 * q + 0.25 * nxt
            cut[1::2] = 0.25 * q + 0.75 * nxt
            q = cut if closed else np.vstack([path[:1], cut[1:-2], path[-1:]])
        q = np.vstack([q, q[:1]]) if closed else q
        keep = simplify(np.column_stack([q, np.full(len(q), z)]), np.array([0, len(q)]),
                        RING_CHORD_MM, "planar")
        q = q[keep]
        return q if self.path_in_region(q, z) else path

    def inner_chords(self, path: FloatArray, field: FloatArray) -> FloatArray:
        """Path (xy) with the vertices dropped that a chord between two others passes on the
        inner side of, within STAIR_CELLS cells: the chord stays where ``field`` (the F of
        the contour: distance to the cleared centres less the step, or the wall term) is at
        most 0, so it cuts no wider than the contour and keeps as far from the walls, and its
        whole swath (:meth:`engaged_width`) is no wider than the stepover or the widest of the
        moves it replaces.  The contour of a tip height that rises in one-cell plateaus along
        a shallow wall runs in stairs of a cell; each stair's jog is a short move sideways
        into the material (4.5 mm wide at a 3.2 mm stepover on a 3 degree slope)."""
        n = len(path)
        if n < 3:
            return path
        if not same_point(path[0], path[-1]) and n > 4:
            # an open path keeps its first and last moves: where it ends at a wall the last
            # one is the head-on cut, which a long move running into it would only widen
            # (the job simulation measures the whole swath of a move)
            return np.vstack([path[:1], self._chords_within(path[1:-1], field), path[-1:]])
        return self._chords_within(path, field)

    def _chords_within(self, path: FloatArray, field: FloatArray) -> FloatArray:
        """:meth:`inner_chords` of the whole path, its ends kept."""
        n = len(path)
        if n < 3:
            return path
        limit = STAIR_CELLS * self.cell
        out = [path[0]]
        i = 0
        while i < n - 1:
            j = i + 1
            while j + 1 < n:
                a, b = path[i], path[j + 1]
                ab = b - a
                L2 = float(ab @ ab)
                if L2 < 1e-18:
                    break
                mid = path[i + 1:j + 1]
                t = np.clip((mid - a) @ ab / L2, 0.0, 1.0)
                dev = np.hypot(*(mid - a - t[:, None] * ab).T)
                if dev.max() > limit:
                    break
                f = self.along(a, b)
                if np.any(_bilinear(field, f[:, 0], f[:, 1]) > 1e-3):
                    break
                j += 1
            # a chord that would sweep wider than the moves it replaces (a run along a wall
            # taken into the head-on cut at its end) gives back vertices
            while j > i + 1 and self.engaged_width(path[i], path[j]) > max(
                    self.s, *(self.engaged_width(path[k], path[k + 1])
                              for k in range(i, j))):
                j -= 1
            out.append(path[j])
            i = j
        return np.array(out)


def _chord_angle(radius: float, sag: float) -> float:
    """Angle (radians) of the chords of a circle of ``radius`` that lie within ``sag`` of it
    (mm)."""
    return 2.0 * math.acos(max(1.0 - sag / radius, -1.0))


def _arc_fill(path: FloatArray, circles: list, sag: float) -> FloatArray:
    """The path (xy, mm) with each chord whose two ends lie on one of ``circles`` ((centre,
    radius), mm) replaced by the shorter arc between them in chords within ``sag`` of it."""
    if len(path) < 2:
        return path
    out = [path[0]]
    for a, b in zip(path[:-1], path[1:]):
        for (cx, cy), r in circles:
            ra, rb = math.hypot(a[0] - cx, a[1] - cy), math.hypot(b[0] - cx, b[1] - cy)
            if abs(ra - r) > 1e-6 * max(r, 1.0) or abs(rb - r) > 1e-6 * max(r, 1.0):
                continue
            ta, tb = math.atan2(a[1] - cy, a[0] - cx), math.atan2(b[1] - cy, b[0] - cx)
            d = (tb - ta + math.pi) % (2 * math.pi) - math.pi
            step = _chord_angle(r, sag)
            n = int(math.ceil(abs(d) / step)) if step > 0 else 1
            for t in np.arange(1, n) / n:
                out.append(np.array([cx + r * math.cos(ta + t * d), cy + r * math.sin(ta + t * d)]))
            break
        out.append(b)
    return np.array(out)
