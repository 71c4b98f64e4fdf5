# SPDX-License-Identifier: LGPL-2.1-or-later
"""The Z-level roughing's two engines (core.kernels.roughing_kernels and the numpy code of
core.toolpath.roughing) agree exactly: the distance transforms, the distances to segments and
polylines, the widths of cut, and whole programs (the case study, a pocketed part entered by
helices, a ball in a bowl), move for move at full precision."""

from __future__ import annotations

import numpy as np
import pytest
from bsplinecam_roughing import bowl, case_study_part

from BSplineCAM.core import kernels
from BSplineCAM.core.geometry.distance import squared_distance as squared_distance_numpy
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.toolpath.roughing import Stock, generate_roughing, gridops
from BSplineCAM.core.toolpath.roughing.state import _segment_distance


def _numba_ready() -> bool:
    with kernels.forced("numba") as engine:
        return engine.name == "numba"


needs_numba = pytest.mark.skipif(not _numba_ready(), reason="numba does not import")


def _masks():
    rng = np.random.default_rng(7)
    yy, xx = np.mgrid[0:37, 0:53]
    disc = (xx - 20) ** 2 + (yy - 11) ** 2 <= 49
    specks = rng.random((37, 53)) < 0.02
    one = np.zeros((1, 9), bool)
    one[0, 4] = True
    return [disc, ~disc, specks, ~specks, np.zeros((5, 6), bool), np.ones((4, 3), bool), one,
            rng.random((64, 40)) < 0.3]


def _both(fn):
    with kernels.forced("numpy"):
        a = fn()
    with kernels.forced("numba"):
        b = fn()
    return a, b


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
@pytest.mark.parametrize("cap", [0.5, 2.0, 3.7, 12.0])
def test_capped_distance_engines_agree(cap):
    for m in _masks():
        a, b = _both(lambda m=m: gridops.capped_distance(m, cap))
        assert np.array_equal(a, b)


@needs_numba
def test_squared_distance_engines_agree():
    for m in _masks():
        a, b = _both(lambda m=m: gridops.squared_distance(m))
        assert np.array_equal(a, b)


@needs_numba
def test_segment_and_polyline_distances_engines_agree():
    rng = np.random.default_rng(3)
    pts = rng.uniform(-5, 5, (300, 2))
    for path in (rng.uniform(-4, 4, (2, 2)), rng.uniform(-4, 4, (9, 2)),
                 np.array([[1.0, 1.0], [1.0, 1.0]])):
        a, b = _both(lambda path=path: gridops._polyline_distance(pts, path))
        assert np.array_equal(a, b)
        xs, ys = np.linspace(-5, 5, 41), np.linspace(-3, 6, 29)
        a, b = _both(lambda path=path: _segment_distance(xs, ys, path[:2]))
        assert np.array_equal(a, b)


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
    a, b = _both(run)
    assert len(a.moves) > 50
    assert _moves(a) == _moves(b)
    assert a.stats["entries"] == b.stats["entries"]
