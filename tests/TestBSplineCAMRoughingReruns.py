# SPDX-License-Identifier: LGPL-2.1-or-later
"""Z-level roughing's reruns of a level (core.toolpath.roughing.levels): the runs after a
level's first start from a copy of its start and stop their replay at the first move as wide
as the narrowest so far, and the fronts' distance grows with each front's new cells only;
each gives the program that recomputing everything gives, to the bit, under both engines."""

from __future__ import annotations

import numpy as np
import pytest
from bsplinecam_helpers import same, under_both
from bsplinecam_roughing import boss_near_corner, cone_pocket

from BSplineCAM.core.simulation.simulate import Tool, ToolShape
from BSplineCAM.core.toolpath import roughing
from BSplineCAM.core.toolpath.roughing import Stock, capped_distance, generate_roughing
from BSplineCAM.core.toolpath.roughing.constants import WALL_LAYER_STEPS
from BSplineCAM.core.toolpath.roughing.gridops import grown_capped_distance
from BSplineCAM.core.toolpath.roughing.levels import _Levels


def _level_best_recomputed(self, z, z_above, in_stock, air, li, nlevels, step_up=False):
    """:meth:`_Levels.level_best` recomputing each run whole (:meth:`_Levels.level` from the
    state before the level) and replaying each run to its end."""
    before = self.snapshot()
    self.level(z, z_above, in_stock, air, li, nlevels, step_up)
    limit = self.engagement_limit * self.s
    best = self.widest_cut(z)
    if best <= limit:
        self.peel_level(z, best)
        return
    kept, used = self.snapshot(), None
    scales = (1.0,) if self.tool.shape is ToolShape.BALL else (1.0,) + self.stepover_scales
    for scale in scales:
        for step in WALL_LAYER_STEPS:
            self.restore(self.copied(before))
            self.level(z, z_above, in_stock, air, li, nlevels, step_up, layer=step,
                       scale=scale)
            width = self.widest_cut(z)
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


def _program(rough) -> tuple:
    stats = {k: v for k, v in rough.stats.items() if k != "seconds"}
    return [tuple(m) for m in rough.moves], repr(sorted(stats.items())), rough.levels


CASES = {
    # a pocket entered by a helix (rings) at fine levels above a floor cut below (floor rings)
    "cone pocket, 8 + 4 mm": (cone_pocket, Stock(-25, 25, -25, 25, 0.0, 16.0),
                              dict(stepdown=8.0, fine_stepdown=4.0, stepover=4.0)),
    # fronts running head-on into a boss near the block's corner
    "boss near corner, 4 mm": (boss_near_corner, Stock(-30, 30, -30, 30, 0.0, 15.0),
                               dict(stepdown=4.0, stepover=4.0)),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_reruns_from_a_copied_start_give_the_recomputed_program(name, monkeypatch):
    """With ENGAGEMENT_LIMIT low enough that every level is cut again at every bend and
    stepover share (so each rerun starts from the first run's start, its rings copied, and
    each replay stops early where it cannot be kept), the moves, the stats and the levels are
    those of the level_best that recomputes every run whole and replays it to its end; and
    the same with the limit as it is."""
    part, stock, kw = CASES[name]
    tool = Tool(10.0, "flat")

    def rough():
        return _program(generate_roughing(part, stock, tool, radial_allowance=0.3,
                                          axial_allowance=0.3, cell=0.4, **kw))

    for limit in (0.3, roughing.ENGAGEMENT_LIMIT):
        monkeypatch.setattr(roughing, "ENGAGEMENT_LIMIT", limit)
        cached = rough()
        with monkeypatch.context() as m:
            m.setattr(_Levels, "level_best", _level_best_recomputed)
            recomputed = rough()
        assert cached == recomputed
    assert cached[0]


def _masks(rng, shape):
    """Random sets: blobs, specks, a band, empty and full, and a grown copy of each."""
    ny, nx = shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    out = []
    for cx, cy, r in ((10, 12, 6.0), (40, 5, 3.0), (nx - 2, ny - 3, 9.0)):
        out.append(np.hypot(xx - cx, yy - cy) < r)
    out.append(rng.random(shape) < 0.01)
    out.append((xx > 20) & (xx < 24))
    out.append(np.zeros(shape, bool))
    out.append(np.ones(shape, bool))
    return out


@pytest.mark.parametrize("cap", [1.0, 2.5, 7.0, 18.0])
def test_grown_capped_distance_is_the_union_s_to_the_bit(cap):
    """grown_capped_distance(capped_distance(S), N) is capped_distance(S | N) exactly, for
    sets of every kind grown by sets of every kind (a box cropped or not), under both
    engines, which agree."""
    rng = np.random.default_rng(3)
    shape = (37, 61)
    masks = _masks(rng, shape)

    def grown():
        out = []
        for S in masks:
            d = capped_distance(S, cap)
            for N in masks:
                out.append((grown_capped_distance(d, N & ~S, cap), capped_distance(S | N, cap)))
        return out

    by_numpy, by_numba = under_both(grown)
    for g, ref in by_numpy:
        same(g, ref)
    for (g, ref), (g2, ref2) in zip(by_numpy, by_numba):
        same(g, g2)
        same(ref, ref2)
