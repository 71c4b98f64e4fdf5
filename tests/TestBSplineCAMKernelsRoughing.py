# SPDX-License-Identifier: LGPL-2.1-or-later
"""The Z-level roughing's two engines (core.kernels.roughing_kernels, roughing_mark_kernels,
roughing_contour_kernels, roughing_front_kernels, roughing_sample_kernels and the numpy code
of core.toolpath.roughing) agree exactly: the distance transforms, the distances to segments
and polylines, the record of a cut on the grids, the widths of cut, the contours, the radius
of the fronts, the samples of a grid, and whole programs (the case study, a pocketed part
entered by helices, a ball in a bowl), move for move at full precision."""

from __future__ import annotations

import numpy as np
import pytest
from bsplinecam_helpers import numba_ready, under_both
from bsplinecam_roughing import bare_job, bowl, case_study_part

from BSplineCAM.core import kernels
from BSplineCAM.core.geometry.distance import squared_distance as squared_distance_numpy
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.toolpath.roughing import (
    Stock,
    contours,
    front_radius,
    generate_roughing,
    gridops,
)
from BSplineCAM.core.toolpath.roughing.state import _segment_distance

needs_numba = pytest.mark.skipif(not numba_ready(), reason="numba does not import")


def _masks():
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:37, 0:53]
    disc = (xx - 20) ** 2 + (yy - 11) ** 2 <= 49
    specks = rng.random((37, 53)) < 0.02
    one = np.zeros((1, 9), bool)
    one[0, 4] = True
    return [disc, ~disc, specks, ~specks, np.zeros((5, 6), bool), np.ones((4, 3), bool), one,
            rng.random((64, 40)) < 0.3]


def _moves(rough):
    return [(m.kind, m.x.hex(), m.y.hex(), m.z.hex()) for m in rough.moves]


def pocket(xs, ys):
    """A plate 10 mm thick (NaN off it) with two closed round pockets 6 mm deep (helical
    entries)."""
    X, Y = np.meshgrid(np.asarray(xs, float), np.asarray(ys, float))
    h = np.where((np.abs(X) <= 24.0) & (np.abs(Y) <= 11.0), 10.0, np.nan)
    for cx in (-12.0, 12.0):
        h[np.hypot(X - cx, Y) <= 9.0] = 4.0
    return h


def test_numpy_distances_match_geometry():
    """The numpy engine of the roughing's squared distance is the geometry's."""
    with kernels.forced("numpy"):
        for m in _masks():
            assert np.array_equal(gridops.squared_distance(m), squared_distance_numpy(m))


@needs_numba
@pytest.mark.parametrize("cap", [0.5, 2.0, 3.7, 12.0, 18.0, 45.0])
def test_capped_distance_engines_agree(cap):
    for m in _masks():
        a, b = under_both(lambda m=m: gridops.capped_distance(m, cap))
        assert np.array_equal(a, b)


@needs_numba
def test_squared_distance_engines_agree():
    for m in _masks():
        a, b = under_both(lambda m=m: gridops.squared_distance(m))
        assert np.array_equal(a, b)


@needs_numba
def test_segment_and_polyline_distances_engines_agree():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-5, 5, (300, 2))
    walk = np.cumsum(rng.uniform(-0.4, 0.4, (300, 2)), axis=0)  # long: most segments pruned
    for path in (rng.uniform(-4, 4, (2, 2)), rng.uniform(-4, 4, (9, 2)),
                 np.array([[1.0, 1.0], [1.0, 1.0]]), walk):
        a, b = under_both(lambda path=path: gridops._polyline_distance(pts, path))
        assert np.array_equal(a, b)
        xs, ys = np.linspace(-5, 5, 41), np.linspace(-3, 6, 29)
        a, b = under_both(lambda path=path: _segment_distance(xs, ys, path[:2]))
        assert np.array_equal(a, b)


def _marked(tool: Tool) -> list:
    """The grids after marking segments and polylines (at the level, between two heights,
    on a grid of their own, and on the run's grids and another at once) on a run's state
    whose surface estimate is uneven."""
    job, xs, ys = bare_job(0.3, 15.0, tool)
    rng = np.random.default_rng(11)
    shape = job.T.shape
    job.z = 2.0
    job.uncut = rng.random(shape) < 0.8
    job.surface = rng.uniform(1.0, 6.0, shape)
    job.surface[rng.random(shape) < 0.1] = -np.inf
    job.surface_lo = job.surface - 0.5
    job.floor = rng.uniform(2.0, 8.0, shape)
    only = np.ones(shape, bool)
    also = np.ones(shape, bool)
    for k in range(12):
        path = rng.uniform(-16.0, 16.0, (2 if k % 3 else 5, 2))
        if k % 4 == 1:
            path[1] = path[0]  # a plunge: a segment of no length
        heights = (1.5, 3.0) if k % 4 == 2 else None
        job.mark(path, heights=heights, also=also if k % 2 else None)
        job.mark(path[::-1], only=only)
    return [job.uncut, job.floor, job.surface, job.surface_lo, only, also]


@needs_numba
@pytest.mark.parametrize("tool", [Tool(8.0, "flat"), Tool(6.0, "ball"),
                                  Tool(10.0, "bullnose", 1.5)], ids=lambda t: t.shape.value)
def test_mark_engines_agree(tool):
    """A cut's record on the grids (``_GridState.mark``: the uncut cells, the floor, the
    surface estimate and its lower bound) is the same to the bit under both engines."""
    a, b = under_both(lambda: _marked(tool))
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    assert not a[0].all() and not a[4].all() and not a[5].all()  # the marks took cells out


def _widths() -> list:
    """Widths of cut and counts of swept cells (``_Engagement.engaged``) of single feeds and
    of batches, against the uncut grid, another material grid and a task grid, with feeds of
    no length among them."""
    job, xs, ys = bare_job(0.3, 15.0, Tool(8.0, "flat"))
    rng = np.random.default_rng(5)
    shape = job.T.shape
    job.z = 2.0
    job.uncut = rng.random(shape) < 0.6
    material = rng.random(shape) < 0.3
    task = rng.random(shape) < 0.5
    out = []
    for k in range(8):
        A = rng.uniform(-16.0, 16.0, (1 if k % 2 else 6, 2))
        B = A + rng.uniform(-6.0, 6.0, A.shape)
        B[0] = A[0] if k == 3 else B[0]
        for kw in ({}, {"task": task}, {"material": material}):
            out += list(job.engaged(A, B, **kw))
    return out


@needs_numba
def test_widths_of_cut_engines_agree():
    """The widths of cut of a flat end mill's feeds and the counts of the cells they sweep
    are the same under both engines."""
    a, b = under_both(_widths)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    assert sum(float(x.sum()) for x in a[::2]) > 0


def _fields() -> list:
    """Fields whose contours run round, wander, meet saddles (cells with all four corners
    across), pass through cell centres (zeros) and through infinite values."""
    rng = np.random.default_rng(1)
    yy, xx = np.mgrid[0:60, 0:80]
    ring = np.hypot(xx - 30, yy - 25) - 12.0
    walls = ring.copy()
    walls[10:20, 5:15] = np.inf
    walls[30:35, 50:60] = -np.inf
    zeros = rng.standard_normal((30, 30))
    zeros[rng.random((30, 30)) < 0.2] = 0.0
    return [ring, rng.standard_normal((40, 50)), np.sin(xx / 5.0) * np.cos(yy / 4.0), walls,
            zeros, np.ones((5, 5)), -np.ones((5, 5)), np.array([[1.0, -1.0]])]


@needs_numba
def test_marching_squares_engines_agree():
    """The contours are the same polylines, in the same order and direction, to the bit."""
    for F in _fields():
        with np.errstate(invalid="ignore"):
            a, b = under_both(lambda F=F: contours.marching_squares(F))
        assert len(a) == len(b)
        for x, y in zip(a, b):
            assert np.array_equal(x, y, equal_nan=True)
    assert len(contours.marching_squares(_fields()[1])) > 50


@needs_numba
def test_front_radius_engines_agree():
    """The radius of the fronts (``front_radius``: distances, box means, Laplacian) is the same
    under both engines, round a disc, a disc joined to a band, specks and the empty and full
    grids."""
    rng = np.random.default_rng(2)
    yy, xx = np.mgrid[0:80, 0:90]
    disc = np.hypot(xx - 40, yy - 30) <= 15
    for Q in (disc, disc | (xx > 70), rng.random((50, 60)) < 0.5, np.zeros((20, 20), bool),
              np.ones((3, 9), bool)):
        a, b = under_both(lambda Q=Q: front_radius(Q, 0.25, 5.0))
        assert np.array_equal(a, b)
    assert np.isfinite(a).sum() == 0 and np.isfinite(front_radius(disc, 0.25, 5.0)).sum() > 1000


def _samples() -> list:
    """Bilinear samples of a field (inside, on the last row and column, beyond the grid) and
    whether feeds stay in {T <= z} (within, crossing a ridge, of no length, off the grid)."""
    job, xs, ys = bare_job(0.3, 15.0, Tool(8.0, "flat"))
    rng = np.random.default_rng(9)
    X, Y = np.meshgrid(xs, ys)
    job.T = np.where(np.abs(X - 2.0) < 0.7, 6.0, np.sin(X / 3.0) + 0.1 * Y)
    ny, nx = job.T.shape
    fx = np.concatenate([rng.uniform(-3.0, nx + 2.0, 200), [0.0, nx - 1.0, nx - 1.5]])
    fy = np.concatenate([rng.uniform(-3.0, ny + 2.0, 200), [ny - 1.0, 0.0, ny - 1.0]])
    A = rng.uniform(-16.0, 16.0, (60, 2))
    B = A + rng.uniform(-5.0, 5.0, A.shape)
    B[0] = A[0]
    return [gridops._bilinear(job.T, fx, fy)] + [job.in_region_many(A, B, z)
                                                  for z in (-1.0, 1.0, 2.5)]


@needs_numba
def test_grid_samples_engines_agree():
    """Bilinear samples of a grid and the feeds that stay in {T <= z} are the same under both
    engines."""
    a, b = under_both(_samples)
    for x, y in zip(a, b):
        assert np.array_equal(x, y)
    assert 0 < int(a[2].sum()) < len(a[2])  # some feeds stay in, some leave


def _roughings():
    height, stock = case_study_part()
    return {
        "case study": lambda: generate_roughing(height, stock, Tool(10.0, "flat"), 6.0, 4.0,
                                                0.3, 0.3, cell=0.4),
        "pockets": lambda: generate_roughing(pocket, Stock(-25, 25, -12, 12, 0.0, 12.0),
                                             Tool(6.0, "flat"), 3.0, 2.4, 0.2, 0.2),
        "ball bowl": lambda: generate_roughing(bowl, Stock(-20, 20, -20, 20, 0.0, 10.0),
                                               Tool(8.0, "ball"), 2.5, 3.0,
                                               axial_allowance=0.1, cell=0.3),
    }


@needs_numba
@pytest.mark.parametrize("name", ["case study", "pockets", "ball bowl"])
def test_roughing_programs_engines_agree(name):
    """The whole program, move for move to the last bit, under both engines."""
    run = _roughings()[name]
    a, b = under_both(run)
    assert len(a.moves) > 50
    assert _moves(a) == _moves(b)
    assert a.stats["entries"] == b.stats["entries"]
