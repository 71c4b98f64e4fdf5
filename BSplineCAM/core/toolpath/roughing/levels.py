# SPDX-License-Identifier: LGPL-2.1-or-later
"""The levels: their heights and cutting order, and the clearing of one level by distance
fronts grown from the air, its entries into closed pockets and the floor already cut, cut
again with bent and narrower fronts where it cuts too wide."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ...simulation.simulate import ToolShape
from ..common import label_regions
from .constants import (
    _EPS,
    FLAT_SLOPE_DEG,
    FLAT_TOOL_AREAS,
    RING_MARGIN_CELLS,
    WALL_LAYER_RADII,
    WALL_LAYER_STEPS,
)
from .gridops import capped_distance, grown_capped_distance, squared_distance
from .rings import _Ring, front_radius, ring_step, ring_steps
from .tips import tip_height


def _levels(part, T, in_stock, stock, stepdown, aa, cell, R, flat_levels) -> tuple:
    """(levels, main): stock top - k stepdown down to the lowest level needed (``main``,
    top-down) plus the flat-area heights (``levels``, all of them, top-down)."""
    reach = T[in_stock]
    low = max(float(reach.min()) if reach.size else stock.z_min, stock.z_min)
    top = stock.z_max
    levels = []
    k = 1
    while top - k * stepdown > low + 1e-6:
        levels.append(top - k * stepdown)
        k += 1
    if low < top - 1e-6:
        levels.append(low)
    main = list(levels)
    if flat_levels:
        finite = np.isfinite(part)
        filled = np.where(finite, part, 0.0)
        gy, gx = np.gradient(filled, cell)
        flat = finite & in_stock & (np.hypot(gx, gy) < math.tan(math.radians(FLAT_SLOPE_DEG)))
        flat[1:-1, 1:-1] &= finite[:-2, 1:-1] & finite[2:, 1:-1] & finite[1:-1, :-2] & \
            finite[1:-1, 2:]
        if flat.any():
            labels, n = label_regions(flat)
            counts = np.bincount(labels[flat], minlength=n)
            big = np.flatnonzero(counts * cell * cell >= FLAT_TOOL_AREAS * math.pi * R * R)
            for comp in big.tolist():
                h = float(np.median(part[labels == comp])) + aa
                if low + 1e-3 < h < top - 1e-3 and all(abs(h - z) > 1e-3 for z in levels):
                    levels.append(h)
    return sorted(levels, reverse=True), main


def _cutting_order(levels: list, main: list, top: float, fine: float | None) -> list:
    """(z, z_above, step_up) per level in cutting order.  Without ``fine`` the levels run
    top-down, each below the one above.  With it the ``main`` levels (at the step-down from
    the top, and the lowest) run top-down, and after each the band between it and the one above
    gets levels every ``fine`` mm (and the flat-area levels in it), cut from the bottom up
    (step_up True): each clears, beside the floor already cut, the terrace left there up to
    the band's top, so a terrace is never thicker than ``fine`` and its material is cut once."""
    if fine is None:
        return [(z, top if i == 0 else levels[i - 1], False) for i, z in enumerate(levels)]
    extra = [z for z in levels if z not in main]
    out = []
    above = top
    for z in main:
        band = {round(z + k * fine, 9) for k in range(1, int((above - z) / fine) + 1)
                if z + k * fine < above - 1e-3}
        band |= {e for e in extra if z < e < above}
        band = sorted(band)
        band = [b for i, b in enumerate(band) if b in extra or
                all(abs(b - e) > 1e-3 for e in extra)]
        out.append((z, above, False))
        out.extend((b, above, True) for b in band)
        above = z
    return out


@dataclass
class _LevelStart:
    """What every run of a level starts from (:meth:`_Levels.level_start`): its heights, its
    share of the progress bar, its allowed centres A, the cleared centres Q its fronts grow
    from, the wall term of their field, the rim of A (with rings) and the rings."""

    z: float
    z_above: float
    frac0: float
    nlevels: int
    A: np.ndarray
    Q: np.ndarray
    wall: np.ndarray
    rim: np.ndarray | None
    rings: list
    #: the capped distance (cells) to the cells outside A (:meth:`near_walls`) once asked
    #: for, under "walls"; shared by the copies
    fields: dict = field(default_factory=dict)

    def copy(self) -> _LevelStart:
        """The same start with rings of their own (a run changes their radii); the arrays,
        which no run changes, shared."""
        return replace(self, rings=[replace(r) for r in self.rings])

    def near_walls(self, R: float, cell: float) -> np.ndarray:
        """1 at the walls (the cells outside A) down to 0 at WALL_LAYER_RADII tool radii R
        from them (mm; ``cell`` the grid's)."""
        width = WALL_LAYER_RADII * R
        if "walls" not in self.fields:
            self.fields["walls"] = capped_distance(~self.A, width / cell + 1)
        return np.clip(1.0 - self.fields["walls"] * cell / width, 0.0, 1.0)


class _Levels:
    """Part of a roughing run (:class:`~.job._Job`): the clearing of its levels."""

    def level_best(self, z, z_above, in_stock, air, li, nlevels, step_up=False) -> None:
        """Cut level z by :meth:`level`; where its widest cut (:meth:`widest_cut`, every move
        outside the entries) passes ENGAGEMENT_LIMIT stepovers, cut it again with the fronts
        bent towards the walls, at each of WALL_LAYER_STEPS, and if none keeps within the
        limit, again so with the fronts grown by each of STEPOVER_SCALES of the stepover in
        turn (not for a ball), until one does.  The narrowest cut is kept.  Every run of the
        level starts alike (:meth:`level_start`: its material, its entries, the fields its
        fronts grow in), so the runs after the first start from a copy of the first one's
        start (:meth:`snapshot`) and grow their fronts only (:meth:`level_fronts`)."""
        start = self.level_start(z, z_above, in_stock, air, li, nlevels, step_up)
        started = self.snapshot()
        self.level_fronts(start.copy())
        limit = self.engagement_limit * self.s
        best = self.widest_cut(z)
        if best <= limit:
            self.peel_level(z, best)
            return
        kept, used = self.snapshot(), None
        # a ball's cut at the level is not the grid's flat swath: closer fronts shave more
        # of the previous passes' cusps (a sloped plane at 2.4 mm: 80 -> 114 moves over)
        scales = (1.0,) if self.tool.shape is ToolShape.BALL else \
            (1.0,) + self.stepover_scales
        for scale in scales:
            for step in WALL_LAYER_STEPS:
                self.restore(self.copied(started))
                self.level_fronts(start.copy(), layer=step, scale=scale)
                width = self.widest_cut(z, stop=best)  # only a narrower one is kept
                if width < best:
                    best, kept, used = width, self.snapshot(), scale
                if best <= limit:
                    break
            if best <= limit:
                break
        self.restore(kept)
        self.peel_level(z, best)
        if used is not None:
            self.bent_levels.append(float(z))
        if used is not None and used < 1.0:
            self.narrowed_levels.append([float(z), used])

    def level(self, z, z_above, in_stock, air, li, nlevels, step_up=False,
              layer: float | None = None, scale: float = 1.0) -> None:
        """Cut level z: :meth:`level_start`, then :meth:`level_fronts`."""
        start = self.level_start(z, z_above, in_stock, air, li, nlevels, step_up)
        self.level_fronts(start, layer=layer, scale=scale)

    def level_start(self, z, z_above, in_stock, air, li, nlevels,
                    step_up=False) -> _LevelStart:
        """Set up level z (its uncut material, its grids as at its start), enter its closed
        pockets (:meth:`enter`) and return what its fronts start from (:meth:`level_fronts`)."""
        tip, cell = self.T, self.cell
        if not hasattr(self, "surface"):
            # a cell whose centre lies just outside the block still holds a sliver of it (its
            # square reaches in): material in the estimate until a pass's disk covers it, so
            # that no rapid or descent crosses the block's uncut corners
            rim = ~in_stock & (self.outside_mm <= 0.5 * math.sqrt(2.0) * cell)
            self.surface = np.where(in_stock | rim, self.stock.z_max, -np.inf)
            self.surface_lo = self.surface.copy()
        A = tip <= z + _EPS
        self.uncut = in_stock & (self.Hp < z_above - _EPS)
        self.z = z
        labels, n = label_regions(A)
        Q = A & air
        if step_up:
            # a level above one already cut: only material above z is uncut, and the fronts
            # start from the centres where the tool meets none (the floor cut below)
            self.uncut &= self.surface > z + _EPS
            clear = tip_height(np.where(np.isfinite(self.surface), self.surface, np.nan),
                               cell, self.tool, 0.0, 0.0, -math.inf, self.ztol)
            Q |= A & (clear <= z + _EPS)
        self.level_first = len(self.writer.moves)
        self.level_uncut = self.uncut.copy()
        self.level_surface = self.surface.copy()
        self.level_surface_lo = self.surface_lo.copy()
        floor_rings = self.floor_rings(A & ~air, Q) if step_up else []
        entered = np.zeros(n + 1, bool)  # index -1 -> the last slot stays False
        entered[np.unique(labels[Q])] = True
        self.outside += int(entered.sum())
        self.allowed = A & entered[labels]
        rings: list[_Ring] = []  # round the components entered by a helix or a plunge
        for comp in range(n):
            if entered[comp]:
                continue
            mask = labels == comp
            entry = self.enter(mask, z, z_above)
            if entry is None:
                continue
            entered[comp] = True
            self.allowed |= mask
            seed, ring = entry
            Q |= seed
            if ring is not None:
                rings.append(ring)
        rings += floor_rings
        # growing fronts.  On a level at a flat floor T - z is 0 over whole areas, where a
        # front's contour would run through the cells' centres (stairs of cell-long moves
        # across the round fronts of a cylinder stock, each stair a burst of engagement):
        # inside {T <= z} the wall term is taken a cell lower, so that there the distance
        # places the contour.  It still crosses only cell edges from an allowed centre, which
        # GRID_GROWTH_CELLS covers.
        wall = np.where(A, tip - z - cell, tip - z)
        # allowed cells beside a disallowed one: the rim the rings grow towards
        rim = (capped_distance(~A, 2.0) <= 1.0) & A if rings else None
        return _LevelStart(z, z_above, (li + 0.05) / nlevels, nlevels, A, Q, wall, rim, rings)

    def level_fronts(self, start: _LevelStart, layer: float | None = None,
                     scale: float = 1.0) -> None:
        """Grow the fronts of a level set up by :meth:`level_start` (``start``, whose rings
        change) by the stepover times ``scale``, with ``layer`` bent towards the walls, and
        cut them, then the level's walls.  The distance to the cleared centres is updated
        with each front's new centres only (:func:`grown_capped_distance`)."""
        z, z_above, A, Q, wall, rim, rings = (start.z, start.z_above, start.A, start.Q,
                                              start.wall, start.rim, start.rings)
        cell = self.cell
        base = np.full(A.shape, self.s * scale)
        if layer is not None:
            # fronts grow by less near the walls, so that they bend and meet them at a slant
            near = start.near_walls(self.R, cell)
            base *= 1.0 - (1.0 - layer) * near * near
        shut = A & ~self.allowed  # allowed centres of components no entry reached
        cap = self.s / cell + 2
        dQ = capped_distance(Q, cap)
        count = int(Q.sum())
        k = 0
        while True:
            self.monitor(0.05 + 0.9 * (start.frac0 + min(k, 50) / 60.0 / start.nlevels))
            dQ_mm = dQ * cell
            step = base.copy()
            rho = None
            for ring in rings:
                # a ring round a helix grows by the step that keeps the arc of the tool's
                # edge in the material that of a straight pass (see the module docstring
                # for the rings that near a wall)
                if ring.radius is not None:
                    ds = ring_step(ring.radius, self.R, self.s * scale)
                    near = ~A & ring.near_rim
                    if near.any():
                        # nearest wall, and the farthest point of the component's rim
                        gap = float(dQ_mm[near].min())
                        far = float(dQ_mm[rim & ring.mask].max(initial=math.inf))
                    else:
                        gap = far = math.inf
                    margin = RING_MARGIN_CELLS * cell
                    if far <= ds or gap <= ds - margin:
                        # the ring reaches the wall all round by no more than ds, or it
                        # meets the wall on one side (a long pocket) and grows by the
                        # stepover on
                        ring.radius = None
                    else:
                        if gap <= ds + margin:
                            ds = 0.5 * gap  # not along the wall: half way there first
                        step[ring.mask] = ds
                        ring.radius += ds
                if not ring.exact:
                    # a floor cut below is round only roughly: where its front bends more
                    # than the ring's radius says, it grows by the ring step of the radius
                    # it has there (:func:`front_radius`)
                    if rho is None:
                        rho = front_radius(Q, cell, self.R)
                    step[ring.mask] = np.minimum(step[ring.mask],
                                                 ring_steps(rho[ring.mask], self.R, self.s * scale))
            F = np.maximum(dQ_mm - step, wall)
            F[shut] = 1.0
            Qn = F <= 0.0
            grown = int(Qn.sum())
            if grown <= count:
                break
            k += 1
            # the rings still round: their front pieces go on the exact circle
            circles = [r for r in rings if r.radius is not None and r.exact]
            zones = [r.mask for r in rings if not r.exact]  # the floor rings' fronts
            self.cut_contours(F, z, z_above, front=dQ_mm - step, reached=dQ_mm, circles=circles,
                              smooth=np.logical_or.reduce(zones) if zones else None)
            dQ = grown_capped_distance(dQ, Qn & ~Q, cap)
            Q, count = Qn, grown
        # walls
        F = self.T - z
        F[shut] = 1.0
        self.cut_contours(F, z, z_above, front=None)

    def floor_rings(self, A: np.ndarray, Q: np.ndarray) -> list:
        """Rings round the parts of the floor already cut away from the air (a fine level's
        fronts grow outwards from a pocket cut below it), grown by :func:`ring_step` of the
        radius of a disc of the same area, as round a helix but not put on a circle; each
        with the cells of A nearer to it than to the rest of Q as its component."""
        labels, n = label_regions(Q & A)
        out = []
        cell = self.cell
        for comp in range(n):
            mask = labels == comp
            count = int(mask.sum())
            if count < 16:
                continue
            rest = Q & ~mask
            mine = np.sqrt(squared_distance(mask))
            zone = A & (mine < np.sqrt(squared_distance(rest))) if rest.any() else A.copy()
            ci, cj = np.argwhere(mask).mean(axis=0)
            centre = self.xy(np.array([[cj, ci]], dtype=float))[0]
            out.append(_Ring(zone, (float(centre[0]), float(centre[1])),
                             math.sqrt(count / math.pi) * cell,
                             capped_distance(zone, self.s / cell + 2) * cell <= self.s,
                             exact=False))
        return out
