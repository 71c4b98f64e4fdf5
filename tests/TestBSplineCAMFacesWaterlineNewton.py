# SPDX-License-Identifier: LGPL-2.1-or-later
"""The faces waterline's crossing polish with the height's slopes (core/toolpath/
faces_waterline.py polish_crossings ``slopes``): Newton steps from the latest point where
the height is smooth, the dyadic bisection where it jumps.  Against the closed form of a ball
beside a plate's edge: the points land on their level (or on the air side of the jump) as
without slopes, in fewer queries, and the levels a jump crosses on one grid edge share their
queries."""

from __future__ import annotations

import numpy as np
import pytest
from bsplinecam_helpers import plane, rectangle

from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.toolpath import faces_waterline
from BSplineCAM.core.toolpath.faces_waterline import FALSI_STEPS, polish_crossings
from BSplineCAM.core.toolpath.faceset import FaceSet

R = 3.0
TOP = 5.0  # mm, the plate's height
EDGE = 20.0  # mm, x of the plate's edge
CELL = 0.75  # mm, the grid edge of the waterline (R / 4)
EPS = 2e-6  # mm, tolerance / 1000 of the CLI's default
WIDTH = 2.5e-4  # mm, tolerance / 8 of the CLI's default


def plate() -> FaceSet:
    ns = plane(0.0, EDGE, 0.0, 20.0, TOP)
    return FaceSet([Face(ns, rectangle(ns))])


def beside_edge(d: np.ndarray) -> np.ndarray:
    """Closed form: tip height of the ball whose axis stands d mm beyond the plate's edge."""
    return np.where(d <= R, TOP - R + np.sqrt(np.clip(R * R - d * d, 0.0, None)), np.nan)


class Asked:
    """Heights and slopes of the plate (the op's remembering query), counting the rounds and
    the distinct points asked about."""

    def __init__(self):
        self.query = faces_waterline._MemoQuery(plate(), R)
        self.calls = 0
        self.points: set = set()

    def heights(self, xy):
        self.calls += 1
        self.points.update(map(tuple, np.asarray(xy).tolist()))
        return self.query.heights(xy)[0]

    def slopes(self, xy):
        return self.query.heights_and_slopes(xy)[1]


def edges(rng, n: int, near_rim: bool):
    """Grid edges across the plate's edge, one end resting on the plate, the other beyond
    the ball's reach (no face), and levels crossed between."""
    if near_rim:
        d_cross = R - rng.uniform(0.005, 0.02, n)
        end_d = np.maximum(d_cross + CELL * rng.uniform(0.0, 1.0 / 32.0, n), R + 1e-6)
    else:
        end_d = R + rng.uniform(1e-4, 0.74, n)
        d_cross = np.clip(end_d - CELL * rng.uniform(0.02, 0.98, n), 0.05, R - 1e-3)
    start = end_d - CELL
    y = rng.uniform(5.0, 15.0, n)
    p0, p1 = np.column_stack([EDGE + start, y]), np.column_stack([EDGE + end_d, y])
    return p0, p1, beside_edge(d_cross)


@pytest.mark.parametrize("near_rim", [False, True])
@pytest.mark.parametrize("flip", [False, True])
def test_newton_lands_on_the_level_in_fewer_queries(near_rim, flip):
    """Crossings between a corner resting on the plate and one with no face: with slopes as
    without, every point lies within EPS of its level (closed form) and every edge settles;
    the slopes take fewer queries."""
    rng = np.random.default_rng(3 + 2 * near_rim + flip)
    p0, p1, level = edges(rng, 120, near_rim)
    if flip:
        p0, p1 = p1, p0
    z0, z1 = beside_edge(p0[:, 0] - EDGE), beside_edge(p1[:, 0] - EDGE)
    asked_about = {}
    for use in (False, True):
        asked = Asked()
        t, jump, _t_up, settled = polish_crossings(
            asked.heights, p0, p1, z0, z1, level, EPS, WIDTH,
            slopes=asked.slopes if use else None)
        assert settled.all() and not jump.any()
        d = p0[:, 0] + t * (p1[:, 0] - p0[:, 0]) - EDGE
        assert np.all(np.abs(beside_edge(d) - level) <= EPS + 1e-9)
        assert asked.calls <= FALSI_STEPS
        asked_about[use] = len(asked.points)
    assert asked_about[True] < asked_about[False], asked_about


def test_jump_levels_on_one_edge_share_their_queries():
    """Levels below the ball's lowest rest on the edge (TOP - R) on the same grid edges: each
    point is on the air side within WIDTH of the jump (d = R), and the levels together ask
    about no more points than one level alone (the same dyadic points of the edge)."""
    rng = np.random.default_rng(9)
    n = 40
    end_d = R + rng.uniform(1e-4, 0.74, n)
    y = rng.uniform(5.0, 15.0, n)
    p0 = np.column_stack([EDGE + end_d - CELL, y])
    p1 = np.column_stack([EDGE + end_d, y])
    z0, z1 = beside_edge(p0[:, 0] - EDGE), beside_edge(p1[:, 0] - EDGE)
    counts = []
    for levels in ([TOP - R - 0.5], [TOP - R - 0.5, TOP - R - 1.3, TOP - R - 2.9]):
        k = len(levels)
        asked = Asked()
        level = np.repeat(levels, n)
        t, jump, t_up, settled = polish_crossings(
            asked.heights, np.tile(p0, (k, 1)), np.tile(p1, (k, 1)), np.tile(z0, k),
            np.tile(z1, k), level, EPS, WIDTH, slopes=asked.slopes)
        assert settled.all() and jump.all()
        x0, x1 = np.tile(p0[:, 0], k), np.tile(p1[:, 0], k)
        d = x0 + t * (x1 - x0) - EDGE
        d_up = x0 + t_up * (x1 - x0) - EDGE
        assert np.all(d > R) and np.all(d - R <= WIDTH)
        assert np.all(beside_edge(d_up) > level)
        counts.append(len(asked.points))
    assert counts[1] == counts[0], counts


@pytest.mark.parametrize("seed", range(5))
def test_dyadic_point_has_the_fewest_binary_digits(seed):
    """_dyadic against a search over j / 2^k: strictly inside, and no coarser one is."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.0, 1.0, 300)
    b = np.minimum(a + rng.uniform(0.0, 1.0, 300) ** 4, 1.0)
    a[:20], b[:20] = 0.0, 1.0  # the whole edge: its midpoint
    t = faces_waterline._dyadic(a, b)
    assert np.all((t > a) & (t < b))
    assert np.all(t[:20] == 0.5)
    for lo, hi, x in zip(a, b, t):
        k = 0
        while (x * 2.0 ** k) % 1.0:
            k += 1
        for coarser in range(k):  # the first j / 2^c above lo is not below hi
            s = 2.0 ** coarser
            assert (np.floor(lo * s) + 1.0) / s >= hi
