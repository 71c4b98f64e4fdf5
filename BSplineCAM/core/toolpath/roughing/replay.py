# SPDX-License-Identifier: LGPL-2.1-or-later
"""The replay of a level's moves on its grids as they were at its start: the widest cut of its
feeds outside the entries, and the walk the peel of the feeds still too wide takes."""

from __future__ import annotations

import contextlib
import math
from typing import Callable

import numpy as np

from ...simulation.simulate import ToolShape
from ...typing import FloatArray
from ..common import Move
from .constants import DESCENT_BAND_MM, ENTRY_TRACK_MM
from .gridops import _polyline_distance


class _Replay:
    """Part of a roughing run (:class:`~.job._Job`): the replay of a level's moves on its grid
    state (:class:`~.state._GridState`)."""

    def mark_level(self, path_xy: FloatArray) -> None:
        """:meth:`mark` on the replay's grid of the material cut at the level only
        (``uncut_level``; the descents of entries cut less)."""
        self.mark(path_xy, only=self.uncut_level)

    def replay_start(self) -> tuple:
        """Set the uncut grid and the surface estimate back to the level's start for a replay
        of its moves: (moves, index of the level's first, which are entries (per index), the
        run's (uncut, floor, surface, surface_lo) to put back after)."""
        moves = self.writer.moves
        first = self.level_first
        entry = np.zeros(len(moves) + 1, bool)
        for a, b in self.entry_spans:
            if b > first:
                entry[max(a, first):b] = True
                # the level moves that follow on the descent's track (the way back over a
                # ramp, a helix's closing turn) clear the wedge it left: entry too, as the
                # job simulation counts them (a peel of one strayed off the track)
                track = np.array([(m.x, m.y) for m in moves[max(a - 1, 0):b]])
                z = moves[b - 1].z
                j = b
                while j < len(moves) and moves[j].kind == "feed" and \
                        abs(moves[j].z - z) < 1e-6:
                    p, q = moves[j - 1], moves[j]
                    probe = np.array([(q.x, q.y), (0.5 * (p.x + q.x), 0.5 * (p.y + q.y))])
                    if float(_polyline_distance(probe, track).max()) > ENTRY_TRACK_MM:
                        break
                    entry[j] = True
                    j += 1
        saved = self.uncut, self.floor, self.surface, self.surface_lo
        self.uncut = self.level_uncut.copy()
        self.floor, self.surface = self.floor.copy(), self.level_surface.copy()
        self.surface_lo = self.level_surface_lo.copy()
        return moves, first, entry, saved

    def replay(self, z: float, visit: Callable) -> None:
        """Replay the level's moves in order from its start (:meth:`replay_start`), with the
        grid ``uncut_level`` of the material cut at the level only beside them (entries'
        descents and ramps cut less than the level: they leave it uncut there), and call
        ``visit(i, move, ab)`` for each move i after the level's first: ab the (a, b) xy ends
        of a feed at z outside the entries, which ``visit`` measures (:meth:`level_width`)
        and marks (:meth:`mark_both`), else None (the replay has marked the other feeds).
        The run's grids are put back after."""
        moves, first, entry, saved = self.replay_start()
        run: list = []  # consecutive feeds not measured, marked at once
        levels: list = []  # whether each of run's feeds lies at the level (not a descent)
        heights: list = []  # the tip's height at each of run's points

        def flush() -> None:
            # (a flat end mill's width counts the uncut grid only: no pieces for it)
            band = math.inf if self.tool.shape is ToolShape.FLAT else DESCENT_BAND_MM
            path, zs, at = _split_descents(np.array(run), np.array(heights), levels, band)
            k = 1
            while k < len(path):
                # the feeds at the level at once; a descent's in pieces each within
                # DESCENT_BAND_MM of height, marked at theirs (as at the level, a ramp's
                # fillets beside it were taken 0.28 mm lower than it left them, and a peel
                # step by them measured 3.71 mm where the simulation found 4.75)
                j = k
                if at[k]:
                    while j + 1 < len(path) and at[j + 1]:
                        j += 1
                    self.mark(path[k - 1:j + 1])
                    for q in range(k, j + 1):  # a descent cuts less than the level
                        self.mark_level(path[q - 1:q + 1])
                else:
                    while j + 1 < len(path) and not at[j + 1] and \
                            np.ptp(zs[k - 1:j + 2]) <= band:
                        j += 1
                    piece, xy = zs[k - 1:j + 1], path[k - 1:j + 1]
                    # a plunge (no move across) leaves what its lowest point does
                    top = piece.min() if np.ptp(xy, axis=0).max() < 1e-9 else piece.max()
                    self.mark(xy, heights=(float(piece.min()), float(top)))
                k = j + 1
            run.clear()
            levels.clear()
            heights.clear()

        self.uncut_level = self.level_uncut.copy()
        try:
            for i in range(max(first, 1), len(moves)):
                p, m = moves[i - 1], moves[i]
                if m.kind != "feed":
                    flush()
                    visit(i, m, None)
                    continue
                a, b = (p.x, p.y), (m.x, m.y)
                at_level = abs(p.z - z) < 1e-6 and abs(m.z - z) < 1e-6
                if not entry[i] and at_level:
                    flush()
                    visit(i, m, (a, b))
                else:
                    if not run or run[-1] != a:
                        flush()
                        run.append(a)
                        levels.append(False)
                        heights.append(p.z)
                    run.append(b)
                    levels.append(at_level)
                    heights.append(m.z)
                    visit(i, m, None)
            flush()
        finally:
            self.uncut, self.floor, self.surface, self.surface_lo = saved
            del self.uncut_level

    def level_width(self, a, b) -> float:
        """Width of cut (mm) of the feed a-b in a replay (:meth:`engaged`), the material that
        of ``uncut_level``: beside an entry's ramp the wedge it left above the level counts
        (the uncut grid takes the ramp's track as cut: a pass beside one measured 0.29 mm
        where the job simulation found 2.95)."""
        return float(self.engaged(np.asarray(a, dtype=float)[None, :2],
                                  np.asarray(b, dtype=float)[None, :2],
                                  material=self.uncut_level)[0][0])

    def mark_both(self, path_xy: FloatArray) -> None:
        """:meth:`mark` and :meth:`mark_level` of a feed at the level in a replay (one pass:
        the same cells leave both grids of uncut cells)."""
        self.mark(path_xy, also=self.uncut_level)

    def widest_cut(self, z: float, stop: float = math.inf) -> float:
        """Widest cut (mm, :meth:`level_width`) of the level's feed moves at z outside its
        entries, replayed in order (:meth:`replay`) on the level's grids as they were at its
        start (every feed move, entries included, cuts its swath; the wedge an entry's
        descent leaves above the level stays material for the width).  The replay stops at
        the first move as wide as ``stop`` (mm) or wider and gives that move's width: a
        caller that keeps only a cut narrower than ``stop`` needs no more of it."""
        worst = 0.0

        def visit(i: int, m: Move, ab: tuple | None) -> None:
            nonlocal worst
            if ab is not None:
                worst = max(worst, self.level_width(*ab))
                if worst >= stop:
                    raise _Wider
                self.mark_both(np.array(ab))

        with contextlib.suppress(_Wider):
            self.replay(z, visit)
        return worst


class _Wider(Exception):
    """A replay's move is as wide as the bound :meth:`_Replay.widest_cut` was given."""


def _split_descents(path: FloatArray, zs: FloatArray, at_level: list,
                    band: float) -> tuple:
    """A polyline (xy ``path``, tip heights ``zs``; ``at_level[k]`` whether the feed to point
    k lies at the level) with every other feed but a plunge cut into pieces each descending
    at most ``band`` (mm): (path, zs, at_level) with the points added."""
    if len(path) < 2:
        return path, zs, list(at_level)
    P, Z, A = [path[0]], [zs[0]], [False]
    for k in range(1, len(path)):
        plunge = float(np.abs(path[k] - path[k - 1]).max()) < 1e-9  # its lowest point rules
        n = 1 if at_level[k] or plunge else max(1, int(math.ceil(abs(zs[k] - zs[k - 1]) / band)))
        for t in np.arange(1, n + 1) / n:
            P.append(path[k - 1] + t * (path[k] - path[k - 1]))
            Z.append(zs[k - 1] + t * (zs[k] - zs[k - 1]))
            A.append(bool(at_level[k]))
    return np.array(P), np.array(Z), A
