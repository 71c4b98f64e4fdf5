# SPDX-License-Identifier: LGPL-2.1-or-later
"""The constant-scallop strategy's two engines (core.kernels.scallop_kernels and the numpy
code of core.toolpath.scallop_field, scallop_metric and scallop_gaps) agree to the bit: the
distances and vectors to polylines (ties between pieces included), the costs interpolated in
the angle, on random polylines and grids, ties and empty inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_helpers import numba_ready, under_both

from BSplineCAM.core import kernels
from BSplineCAM.core.toolpath.common import Jet, normal_curvature
from BSplineCAM.core.toolpath.scallop_field import AXES, NearField, near_vector, propagate
from BSplineCAM.core.toolpath.scallop_gaps import COVER_DIRECTIONS, tents
from BSplineCAM.core.toolpath.scallop_metric import (
    NormalCurvature,
    band_costs,
    directional_cost,
    directional_cost_on,
)

needs_numba = pytest.mark.skipif(not numba_ready(), reason="numba does not import")


def _same(a, b) -> bool:
    """Equal arrays, NaN where NaN, signed zeros alike."""
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.dtype == b.dtype and bool(
        np.all((a == b) | (np.isnan(a) & np.isnan(b)))
        and np.array_equal(np.signbit(a), np.signbit(b)))


XS, YS = np.linspace(0.0, 20.0, 81), np.linspace(-5.0, 10.0, 61)  # 0.25 mm: ties exact


def _polylines(seed: int) -> list:
    """Random walks (some leaving the grid), single points, repeated points (zero-length
    segments) and polylines through grid nodes, twice and reversed (ties between pieces)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(25):
        n = int(rng.integers(1, 12))
        out.append(np.cumsum(rng.normal(size=(n, 2)) * 3.0, axis=0) + [10.0, 2.0])
    on_nodes = np.column_stack([XS[10:40:3], np.full(10, YS[20])])
    out += [on_nodes, on_nodes.copy(), on_nodes[::-1].copy()]
    out.append(np.repeat(on_nodes[:4] + [0.1, 0.3], 2, axis=0))
    diagonal = np.column_stack([XS[5:30:4], YS[5:30:4]])
    out += [diagonal, diagonal[::-1].copy(), np.column_stack([diagonal, np.ones(7)])]
    return out


@needs_numba
@pytest.mark.parametrize("reach", [1, 2, 3, 6])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_near_vector_engines_agree(reach, seed):
    lines = _polylines(seed)
    (da, va), (db, vb) = under_both(lambda: near_vector(lines, XS, YS, reach))
    assert _same(da, db) and _same(va, vb)
    assert np.isfinite(da).sum() > 100


@needs_numba
def test_near_vector_ties_agree():
    """A node at the same distance from two pieces gets the same one's vector in both
    engines (the last to reach it, offsets outermost): nodes midway between two parallel
    lines, given in either order."""
    line = np.array([[XS[10], YS[20]], [XS[20], YS[20]]])
    below = line - [0.0, YS[1] - YS[0]]
    above = line + [0.0, YS[1] - YS[0]]
    for first, last in ((below, above), (above, below)):
        (da, va), (db, vb) = under_both(lambda f=first, la=last: near_vector([f, la], XS, YS, 2))
        assert _same(da, db) and _same(va, vb)
        assert da[15, 20] == 0.25 and abs(va[15, 20, 1]) == 0.25  # a tie, settled alike
    # two pieces in one cell as near to a node at one offset: the later one's vector
    x0, y0 = XS[12], YS[20]
    one = np.array([[x0 + 0.0625, y0 + 0.125], [x0 + 0.1875, y0 + 0.125]])
    two = np.array([[x0 + 0.125, y0 + 0.0625], [x0 + 0.125, y0 + 0.1875]])
    for first, last in ((one, two), (two, one)):
        (da, va), (db, vb) = under_both(lambda f=first, la=last: near_vector([f, la], XS, YS, 2))
        assert _same(da, db) and _same(va, vb)
        assert da[12, 20] == math.hypot(0.0625, 0.125)
        assert np.array_equal(va[12, 20], [x0, y0] - last[0])


@needs_numba
@pytest.mark.parametrize("lines", [[], [np.zeros((1, 2))], [np.zeros((0, 2))],
                                   [np.array([[100.0, 100.0], [101.0, 100.0]])]])
def test_near_vector_empty(lines):
    (da, va), (db, vb) = under_both(lambda: near_vector(lines, XS, YS, 2))
    assert _same(da, db) and _same(va, vb)
    assert np.isinf(da).all() and not va.any()


@pytest.mark.parametrize("engine", ["numpy", "numba"])
@pytest.mark.parametrize("seed", [0, 3])
def test_near_field_merged_is_one_call(engine, seed):
    """Polylines taken in by batches (the later ones repeating earlier ones: ties between
    batches) give one call's distances and vectors to the bit; a batch with a NaN point is
    searched anew with all the rest."""
    if engine == "numba" and not numba_ready():
        pytest.skip("numba does not import")
    lines = _polylines(seed)
    lines += [p.copy() for p in lines[-7:]] + [lines[0][::-1].copy()]
    with kernels.forced(engine):
        for reach in (2, 5):
            whole = near_vector(lines, XS, YS, reach)
            field = NearField(XS, YS, reach)
            for a, b in ((0, 10), (10, 11), (11, 30), (30, len(lines))):
                field.add(lines[a:b])
            assert _same(field.out, whole[0]) and _same(field.vec, whole[1])
            bad = np.array([[5.0, 1.0], [np.nan, 2.0], [7.0, 3.0]])
            with np.errstate(invalid="ignore"):  # the NaN piece's cell
                field.add([bad])
                again = near_vector(lines + [bad], XS, YS, reach)
            assert _same(field.out, again[0]) and _same(field.vec, again[1])


def _cost_grids(seed: int, shape=(30, 23)):
    rng = np.random.default_rng(seed)
    t = np.arange(COVER_DIRECTIONS) * np.pi / COVER_DIRECTIONS
    axes = np.column_stack([np.cos(t), np.sin(t)])
    cost = rng.uniform(0.1, 3.0, (COVER_DIRECTIONS,) + shape).astype(np.float32)
    against = rng.uniform(0.1, 3.0, (COVER_DIRECTIONS,) + shape).astype(np.float32)
    on = rng.random(shape) < 0.6
    m = int(on.sum())
    v = rng.normal(size=(m, 2))
    # along the directions themselves (and their opposites), zero vectors, unit vectors
    k = rng.integers(0, COVER_DIRECTIONS, m)
    along = rng.random(m) < 0.3
    v[along] = (axes[k] * rng.choice([-1.0, 1.0, 2.5], m)[:, None])[along]
    v[rng.random(m) < 0.05] = 0.0
    v[rng.random(m) < 0.05] = [0.0, -1.0]
    return cost, against, axes, on, v


@needs_numba
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_directional_cost_on_engines_agree(seed):
    cost, against, axes, on, v = _cost_grids(seed)
    a, b = under_both(lambda: directional_cost_on(cost, against, axes, on, v))
    assert _same(a, b)
    reference = directional_cost(cost[:, on], axes, v, against[:, on], bound=False)
    assert _same(a, reference)


@needs_numba
def test_directional_cost_on_empty():
    cost, against, axes, on, v = _cost_grids(0)
    none = np.zeros_like(on)
    a, b = under_both(lambda: directional_cost_on(cost, against, axes, none, v[:0]))
    assert a.shape == b.shape == (0,)


def test_directional_cost_on_is_isotropic_where_the_costs_are():
    """Equal costs in every direction: the cost of a vector is the cost per mm times its
    length, whatever its angle (either engine)."""
    cost, against, axes, on, v = _cost_grids(5)
    cost[:] = 2.0
    against[:] = 2.0
    got = directional_cost_on(cost, against, axes, on, v)
    np.testing.assert_allclose(got, 2.0 * np.hypot(v[:, 0], v[:, 1]), rtol=1e-12)
    assert math.isfinite(float(got.sum()))


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_normal_curvature_once_is_common_normal_curvature(sign):
    """The fundamental forms taken once give :func:`common.normal_curvature` to the bit, in
    random directions and along the axes, at random jets (some degenerate: Su parallel to
    Sw, a zero derivative)."""
    rng = np.random.default_rng(11)
    m = 500
    parts = [rng.normal(size=(m, 3)) for _ in range(6)]
    parts[1][:20] = 0.0  # Su = 0
    parts[2][20:40] = 2.0 * parts[1][20:40]  # Sw parallel to Su
    jet = Jet(rng.random(m), rng.random(m), *parts, sign=sign)
    curvature = NormalCurvature(jet)
    assert _same(curvature.normal, jet.normal)
    for direction in [rng.normal(size=(m, 3)), np.tile([1.0, 0.0, 0.3], (m, 1)),
                      np.zeros((m, 3))]:
        with np.errstate(invalid="ignore", divide="ignore"):
            assert _same(curvature(direction), normal_curvature(jet, direction))


def _propagate_case(seed: int, nx: int, ny: int):
    """Costs with blocked entries (inf), an asymmetric twin, blocked nodes, a few sources."""
    rng = np.random.default_rng(seed)
    cost = rng.uniform(0.5, 2.0, (len(AXES), nx, ny))
    cost[:, rng.random((nx, ny)) < 0.05] = np.inf
    against = cost * rng.uniform(0.8, 1.2, cost.shape)
    free = rng.random((nx, ny)) < 0.85
    start = np.full((nx, ny), np.inf)
    start[rng.random((nx, ny)) < 0.02] = 0.0
    start[nx // 2, ny // 2] = 0.3
    free[nx // 2, ny // 2] = True
    return start, cost, against, free


@needs_numba
@pytest.mark.parametrize("shape", [(40, 31), (60, 17), (7, 1), (1, 9), (3, 3)])
@pytest.mark.parametrize("seed", [0, 1])
def test_propagate_engines_agree(shape, seed):
    start, cost, against, free = _propagate_case(seed, *shape)
    for other, rounds in ((None, 60), (against, 60), (against, 1), (None, 2)):
        a, b = under_both(lambda o=other, r=rounds: propagate(start, cost, 0.3, 0.4, free, r, o))
        assert _same(a, b)
    assert np.isfinite(a).any()


@needs_numba
def test_propagate_engines_agree_without_sources_or_free_nodes():
    start, cost, against, free = _propagate_case(2, 20, 15)
    for st, fr in ((np.full_like(start, np.inf), free), (start, np.zeros_like(free))):
        a, b = under_both(lambda s=st, f=fr: propagate(s, cost, 0.3, 0.4, f, against=against))
        assert _same(a, b) and not np.isfinite(a).any()


@needs_numba
@pytest.mark.parametrize("dtype", [np.float64, np.float32])
@pytest.mark.parametrize("sides", [(1, -1), (1,), (-1,)])
def test_band_costs_engines_agree(sides, dtype):
    """Whole and fractional steps (repeated rounded offsets), blocked and zero costs, a
    direction with no finite cost, reaches beyond the grid."""
    rng = np.random.default_rng(4)
    t = np.arange(COVER_DIRECTIONS) * np.pi / COVER_DIRECTIONS
    steps = np.vstack([np.column_stack([np.cos(t), np.sin(t)]) * 0.7, [[1, 0], [2, -1]]])
    cost = rng.uniform(0.02, 3.0, (len(steps), 35, 28))
    cost[:, rng.random((35, 28)) < 0.1] = np.inf
    cost[:, rng.random((35, 28)) < 0.05] = 0.0
    cost[3] = np.inf
    cost = cost.astype(dtype)
    a, b = under_both(lambda: band_costs(cost, steps, 0.3, 0.2, sides=sides))
    assert _same(a, b)
    assert (a[0] > cost[0]).any()


@needs_numba
@pytest.mark.parametrize("shape", [(30, 22), (1, 8), (9, 1), (2, 2)])
@pytest.mark.parametrize("seed", [0, 1])
def test_tents_engines_agree(shape, seed):
    """E with NaN (off the surface) and the far value, rates with zeros and inf, unit vectors
    along the axes, opposed and zero, nodes on and off."""
    rng = np.random.default_rng(seed)
    e = rng.uniform(0.0, 1.2, shape)
    e[rng.random(shape) < 0.1] = np.nan
    e[rng.random(shape) < 0.05] = 1.0
    rate = rng.uniform(0.0, 3.0, shape)
    rate[rng.random(shape) < 0.05] = 0.0
    rate[rng.random(shape) < 0.02] = np.inf
    ang = rng.uniform(0.0, 2.0 * np.pi, shape)
    axis = rng.random(shape) < 0.2
    ang[axis] = rng.integers(0, 4, int(axis.sum())) * (np.pi / 2)
    unit = np.stack([np.cos(ang), np.sin(ang)], axis=-1)
    unit[rng.random(shape) < 0.05] = 0.0
    on = rng.random(shape) < 0.8
    for dx, dy in ((0.1, 0.1), (0.07, 0.13)):
        with np.errstate(invalid="ignore"):
            a, b = under_both(lambda dx=dx, dy=dy: tents(e, rate, unit, on, dx, dy))
        assert _same(a, b)
    if min(shape) > 2:
        assert (a > e).any()
