# SPDX-License-Identifier: LGPL-2.1-or-later
"""The width of cut of feeds at the level, as the job simulation measures a move, and the check
that a route's feeds keep within the bound the passes keep."""

from __future__ import annotations

import math

import numpy as np

from ... import kernels
from ...kernels import roughing_kernels as _rk
from ...simulation.simulate import ToolShape, corner_height
from ...typing import FloatArray
from .constants import CELL_HALF_DIAGONAL, FILLET_MM


class _Engagement:
    """Part of a roughing run (:class:`~.job._Job`): widths of cut on its grid state
    (:class:`~.state._GridState`)."""

    def engaged_width(self, a, b) -> float:
        """Width of cut (mm) of a feed from a to b (xy) at the level, by the uncut grid, as the
        job simulation measures a move: the extent across the move of all the uncut cells it
        sweeps (within R of it, ahead of its start), plus a cell.  A move entering a band at a
        slant cuts a swath wider than the width at any one of its positions."""
        return float(self.engaged_widths(np.asarray(a, dtype=float)[None, :2],
                                         np.asarray(b, dtype=float)[None, :2])[0])

    def engaged_widths(self, A: FloatArray, B: FloatArray) -> FloatArray:
        """:meth:`engaged_width` of the feeds from A[i] to B[i] (n, 2), over the uncut cells
        of the window round all of them at once."""
        return self.engaged(A, B)[0]

    def engaged(self, A: FloatArray, B: FloatArray, task: np.ndarray | None = None,
                material: np.ndarray | None = None) -> tuple:
        """(widths, counts): :meth:`engaged_widths` of the feeds from A[i] to B[i], and how
        many of the cells of ``task`` (a grid of the level's shape; None: the uncut cells)
        each sweeps within R (ahead of its start, as the widths count)."""
        out = np.zeros(len(A))
        counts = np.zeros(len(A), int)
        length = np.array([math.dist(a, b) for a, b in zip(A.tolist(), B.tolist())])
        live = np.flatnonzero(length >= 1e-9)
        if not len(live):
            return out, counts
        A, B, length = A[live], B[live], length[live]
        if len(A) == 1:
            (ax, ay), (bx, by) = A[0].tolist(), B[0].tolist()
            i0, i1, j0, j1 = self.window_of(ax, ay, bx, by, self.Rc + 2)
        else:
            i0, i1, j0, j1 = self.window(self.idx(np.concatenate([A, B])), self.Rc + 2)
        flat = self.tool.shape is ToolShape.FLAT
        if flat and kernels.use_numba():
            # the window's cells gathered in the kernel's loop
            g = self.grid
            uncut = self.uncut if material is None else material
            try:
                out[live], counts[live] = _rk.engaged_flat_window(
                    np.ascontiguousarray(A), length, (B - A) / length[:, None], uncut,
                    uncut if task is None else task, i0, i1, j0, j1, g.x0, g.y0, g.cell,
                    float(self.R))
                return out, counts
            except kernels.KernelUnavailable:
                pass
        uncut = base = (self.uncut if material is None else material)[i0:i1, j0:j1]
        work = uncut if task is None else task[i0:i1, j0:j1]
        if not flat:
            # a bull-nose's or ball's passes leave fillets under their corners, which the
            # surface estimate holds: material there counts as the simulation counts it
            above = self.surface[i0:i1, j0:j1] - self.z
            above_lo = self.surface_lo[i0:i1, j0:j1] - self.z
            uncut = uncut | (above > FILLET_MM)
        iy, ix = np.nonzero(uncut | work)
        if not len(iy):
            return out, counts
        cells = self.xy(np.column_stack([ix + j0, iy + i0]).astype(float))
        d = (B - A) / length[:, None]
        rx = cells[None, :, 0] - A[:, :1]
        ry = cells[None, :, 1] - A[:, 1:]
        along = rx * d[:, :1] + ry * d[:, 1:]
        across = ry * d[:, :1] - rx * d[:, 1:]
        L = length[:, None]
        swept = (along > 0) & (np.abs(across) <= self.R) & (along <= L) | (
            (along > L) & ((along - L) ** 2 + across * across <= self.R * self.R))
        counts[live] = (swept & work[iy, ix][None, :]).sum(axis=1)
        swept &= uncut[iy, ix][None, :]
        if not flat:
            # material left under a corner counts where the move's tool, over the whole cell,
            # passes below it (a pass over the same line leaves the same fillet), and only
            # what stands above corner_height of the move's deepest cut, as the simulation
            # counts it (fresh material: the uncut cells, at the level's top)
            h = above[iy, ix]  # the estimate bounds the material's top, uncut cells' too
            fresh = base[iy, ix]
            dist = np.where(along > L, np.hypot(along - L, across), np.abs(across))
            bottom = self.tool.profile(dist + CELL_HALF_DIAGONAL * self.cell)
            # the move's deepest cut, as the simulation takes it: the most the tool drops
            # any cell by, not the highest material it passes (a fillet's crest beside it
            # under the corner would lift the corner's height over the toes it does skim);
            # from the estimate's lower bound less the tool's highest point over each cell,
            # so that it is never deeper than the simulation's and sets the corner no higher
            axial = np.where(swept, above_lo[iy, ix][None, :] - bottom, 0.0).max(axis=1)
            corner = corner_height(self.tool, np.maximum(axial, 0.0))
            swept &= fresh[None, :] | ((h[None, :] > corner[:, None] + FILLET_MM)
                                       & (h[None, :] > bottom + FILLET_MM))
        hi = np.where(swept, across, -np.inf).max(axis=1)
        lo = np.where(swept, across, np.inf).min(axis=1)
        out[live] = np.where(swept.any(axis=1), hi - lo + self.cell, 0.0)
        return out, counts

    def runs_within(self, path: FloatArray) -> bool:
        """Every feed of path (xy) after its first cuts no wider than 1.1 stepover, the bound
        the passes keep (:meth:`engaged_width` of its whole swath, a cell over the width
        along a pass), each measured after the feeds before it have cut (a trial on the
        grids, undone)."""
        f = self.idx(path)
        i0, i1, j0, j1 = self.window(f, self.Rc + 3)
        saved = [(g, g[i0:i1, j0:j1].copy())
                 for g in (self.uncut, self.floor, self.surface, self.surface_lo)]
        try:
            self.mark(path[:2])
            for a, b in zip(path[1:-1], path[2:]):
                if self.engaged_width(a, b) > 1.1 * self.s:
                    return False
                self.mark(np.array([a, b]))
            return True
        finally:
            for g, view in saved:
                g[i0:i1, j0:j1] = view
