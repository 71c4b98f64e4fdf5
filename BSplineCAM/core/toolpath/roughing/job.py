# SPDX-License-Identifier: LGPL-2.1-or-later
"""A roughing run's state: its grid state (:class:`~.state._GridState`) with the writer, the
running counts and the parts that clear its levels, enter and cut its passes, replay and peel
them; and the report of what it left."""

from __future__ import annotations

import copy
import math

import numpy as np

from ..common import label_regions
from .constants import ENGAGEMENT_LIMIT, GRID_GROWTH_CELLS, PEEL_OVER, STEPOVER_SCALES
from .engagement import _Engagement
from .entries import _Entries
from .levels import _Levels
from .passes import _Passes
from .peel import _Peel
from .replay import _Replay
from .state import _GridState, _Writer
from .tips import disk_max


class _Job(_Levels, _Passes, _Entries, _Peel, _Replay, _Engagement, _GridState):
    """State of one roughing run: the grids, the writer and the running counts."""

    def __init__(self, grid, T, Hp, tool, s, ar, cell, stock, clearance, notes, monitor):
        super().__init__(grid, T, Hp, tool, s, ar, cell, stock)
        self.notes, self.monitor = notes, monitor
        self.writer = _Writer(clearance)
        self.passes = 0
        self.helical = 0
        self.zigzags = 0  # closed pockets entered by a zig-zag ramp along a chord
        self.plunges = 0  # closed pockets entered by a straight plunge (centre-cutting)
        self.centre_cutting = False  # the end mill cuts at its centre: it may plunge
        self.outside = 0
        self.ramps = 0
        self.lead_ins = 0  # straight descents on the floor already cut, then a lead-in
        self.bent_levels: list = []  # levels (z) cut with the fronts bent towards the walls
        self.narrowed_levels: list = []  # [z, share of the stepover] of those cut narrower
        self.lifts = 0
        self.entry_spans: list = []
        self.peeled_moves = 0
        self.links: list[int] = []
        self.skipped: list = []
        # the bounds of the clearing (:meth:`level_best`, :meth:`peel_level`);
        # :func:`~BSplineCAM.core.toolpath.roughing.generate_roughing` sets them from the
        # package's names of the same constants
        self.engagement_limit = ENGAGEMENT_LIMIT
        self.stepover_scales = STEPOVER_SCALES
        self.peel_over = PEEL_OVER

    def snapshot(self) -> dict:
        """A copy of the run's state (:meth:`copied`)."""
        return self.copied(self.__dict__)

    def copied(self, state: dict) -> dict:
        """A deep copy of a state, the grids and objects that never change shared."""
        shared = [self.grid, self.T, self.Hp, self.tool, self.stock, self.monitor, self.notes,
                  getattr(self, "in_stock", None), getattr(self, "outside_mm", None)]
        writer = state.get("writer")
        if writer is not None:
            shared += writer.moves  # immutable: the copy's list holds the same moves
        return copy.deepcopy(dict(state), {id(v): v for v in shared})

    def restore(self, state: dict) -> None:
        """Back to a :meth:`snapshot` (attributes set since then go too: the first level
        makes the surface estimate)."""
        self.__dict__.clear()
        self.__dict__.update(state)

    def report_leftover(self) -> None:
        """Notes for the run's result: the closed pockets no entry reached (:meth:`enter`;
        grouped by place), and the material left more than a stepdown above the part away
        from every wall that explains it, both left for a smaller tool.

        A pocket's note gives its place (x, y mm), the XY box of its walls (its allowed
        centres grown by the tool radius, the radial allowance and the tip map's growth), and
        the Z range: from its lowest skipped level up to the level above its highest one,
        where the material left stands; the largest tool diameter whose helix enters it, and,
        for a tool not known to cut at its centre, that it would plunge it if it did."""
        cell = self.cell
        if self.skipped:
            # one entry per place (levels of one pocket lie within a tool radius)
            groups: list = []
            for z, z_above, x, y, box, fits in self.skipped:
                for g in groups:
                    if math.hypot(g[0] - x, g[1] - y) <= self.R:
                        g[2], g[3], g[4] = max(g[2], z_above), min(g[3], z), min(g[4], fits)
                        g[5] = (min(g[5][0], box[0]), max(g[5][1], box[1]),
                                min(g[5][2], box[2]), max(g[5][3], box[3]))
                        break
                else:
                    groups.append([x, y, z_above, z, fits, box])

            def mm(v: float) -> str:  # no "-0.00"
                return f"{0.0 if abs(v) < 0.005 else v:.2f}"

            def which(fits: float) -> str:
                return (f"a tool of at most {fits:.1f} mm enters it by a helix" if fits > 0
                        else "narrower than the roughing grid resolves")

            plunge = "" if self.centre_cutting else (
                f"; this {self.tool.diameter:g} mm end mill would plunge it if it cuts at its "
                "centre (--centre-cutting, op property CentreCutting)")
            parts = "; ".join(
                f"({x:.1f}, {y:.1f}) mm, within x {mm(b[0])} to {mm(b[1])} and y {mm(b[2])} to "
                f"{mm(b[3])} mm, uncut from Z {mm(lo)} to {mm(hi)} mm ({which(fits)}{plunge})"
                for x, y, hi, lo, fits, b in groups[:6])
            more = f"; and {len(groups) - 6} more" if len(groups) > 6 else ""
            self.notes.append(
                f"{len(groups)} closed pocket(s) too narrow for a helical entry or a zig-zag "
                f"ramp of the {self.tool.diameter:g} mm tool were left uncut: {parts}{more}. "
                "The finishing tool would meet that stock at full width: rough it with the "
                "smaller tool named, or a centre-cutting end mill, or drill it, first")
        # material more than a stepdown above the part, away from every wall that explains it
        gap = self.ar + GRID_GROWTH_CELLS * cell + max(2 * cell, 0.45 * self.R)
        base = np.where(np.isfinite(self.Hp), self.Hp, self.stock.z_min)
        near = disk_max(base, gap / cell)
        left = (self.floor - base > self.stepdown + 0.1) & (near < self.floor - self.stepdown) \
            & self.in_stock
        if not left.any():
            return
        labels, n = label_regions(left)
        counts = np.bincount(labels[left], minlength=n)
        xs, ys = self.grid.centres()
        area_min = 0.05 * math.pi * self.R ** 2
        for comp in np.flatnonzero(counts * cell * cell >= area_min).tolist():
            m = labels == comp
            iy, ix = np.nonzero(m)
            self.notes.append(
                f"material the tool cannot reach left for a smaller tool: about "
                f"{counts[comp] * cell * cell:.1f} mm^2 around x={xs[ix].mean():.1f}, "
                f"y={ys[iy].mean():.1f} mm, up to {float(self.floor[m].max()):.2f} mm high "
                f"over a part down to {float(base[m].min()):.2f} mm")
