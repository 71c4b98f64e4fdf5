# SPDX-License-Identifier: LGPL-2.1-or-later
"""The drop-cutter's compiled kernels over trimmed faces (BSplineCAM.core.kernels.
faceset_kernels, faceset_trim_kernels, faceset_round_kernels) against their numpy twins: each
piece gives the same bits under both engines (a level's upper bounds the same to rounding),
and FaceSet.drop_ball the same heights, contacts, gaps and pair counts on numpy-built faces
(polynomial and rational, trimmed) and on examples/part.step."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from bsplinecam_helpers import (
    circle,
    close,
    cylinder_quarter,
    dome_faces,
    fillet_ring,
    holed_plane,
    plane,
    plate_with_hole,
    rectangle,
    same,
    step_part_queries,
    two_faces,
)

from BSplineCAM.core import kernels
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.toolpath import faceset_bounds, faceset_subdivide, faceset_trims
from BSplineCAM.core.toolpath.faceset import FaceSet
from BSplineCAM.core.toolpath.faceset_branch import _root_pairs
from BSplineCAM.core.toolpath.faceset_trims import _FaceData

needs_numba = pytest.mark.skipif(importlib.util.find_spec("numba") is None,
                                 reason="numba is not installed: no compiled engine to compare")


def both(fn):
    """``fn()`` under the numpy engine and under the numba engine."""
    with kernels.forced("numpy"):
        a = fn()
    with kernels.forced("numba") as e:
        if e.name != "numba":
            pytest.skip(f"no numba engine: {e.reason}")
        b = fn()
    return a, b


def trimmed_cylinder():
    ns = cylinder_quarter(10.0, 30.0)
    outer = np.array([[0.02, 0.02], [0.98, 0.02], [0.98, 0.98], [0.02, 0.98], [0.02, 0.02]])
    return Face(ns, outer, holes=(circle(0.5, 0.5, 0.2, 200),))


# -- the pieces ------------------------------------------------------------------------------
@needs_numba
def test_clip_agrees():
    rng = np.random.default_rng(1)
    n, K = 400, 12
    seg = rng.uniform(-0.2, 1.2, (n, K, 4))
    seg[:, 1, 2] = seg[:, 1, 0]  # vertical
    seg[:, 2, 3] = seg[:, 2, 1]  # horizontal
    seg[:, 3, 2:] = seg[:, 3, :2]  # a point
    seg[:, 4] = np.nan  # no segment
    lo = rng.uniform(0.0, 0.6, (n, 2))
    box = np.column_stack([lo[:, 0], lo[:, 0] + 0.3, lo[:, 1], lo[:, 1] + 0.3])
    box[:5, 0] = seg[:5, 1, 0]  # a vertical segment on the box's side
    a, b = both(lambda: faceset_trims._clip(seg, box))
    same(a, b)
    assert a[0].any() and not a[0].all()


@needs_numba
def test_point_in_trim_agrees():
    d = _FaceData(holed_plane(400), 0)
    rng = np.random.default_rng(2)
    u = rng.uniform(-0.1, 1.1, 5000)
    v = rng.uniform(-0.1, 1.1, 5000)
    u[:50] = 0.0
    v[50:100] = 1.0  # on the domain's sides
    a, b = both(lambda: (d.inside(u, v), d._bands(u, v), d.inside(u.reshape(50, 100), 0.3)))
    same(a, b)
    assert a[0].any() and not a[0].all()


def _boxes(rng, n, size):
    lo = rng.uniform(0.0, 1.0 - size, (n, 2))
    return np.column_stack([lo[:, 0], lo[:, 0] + size, lo[:, 1], lo[:, 1] + size])


@needs_numba
@pytest.mark.parametrize("make", [lambda: dome_faces()[0], trimmed_cylinder, holed_plane])
def test_classification_and_vertices_agree(make):
    d = _FaceData(make(), 0)
    rng = np.random.default_rng(3)
    big = _boxes(rng, 300, 0.25)
    every = np.full((len(big), 1), -2)
    a, b = both(lambda: d._classify(big, every))
    same(a, b)
    status, segs = a
    strad = np.flatnonzero(status == 2)
    assert len(strad)
    # quarters of the straddling boxes, classified by their parents' segments
    parent = np.repeat(strad, 4)
    pb = big[parent]
    hu = 0.5 * (pb[:, 0] + pb[:, 1])
    hv = 0.5 * (pb[:, 2] + pb[:, 3])
    k = np.tile(np.arange(4), len(strad))
    small = pb.copy()
    small[:, 0] = np.where(k % 2 == 1, hu, pb[:, 0])
    small[:, 1] = np.where(k % 2 == 0, hu, pb[:, 1])
    small[:, 2] = np.where(k >= 2, hv, pb[:, 2])
    small[:, 3] = np.where(k < 2, hv, pb[:, 3])
    listed = segs[parent]
    a2, b2 = both(lambda: d._classify(small, listed))
    same(a2, b2)
    s2 = np.flatnonzero((a2[0] == 2) & (a2[1][:, 0] >= 0))
    assert len(s2)
    same(*both(lambda: d._vertices(small[s2], a2[1][s2])))


@needs_numba
@pytest.mark.parametrize("make", [lambda: dome_faces()[0], trimmed_cylinder,
                                  lambda: fillet_ring()])
def test_halving_and_splits_agree(make):
    d = _FaceData(make(), 0)
    rng = np.random.default_rng(4)
    pn = d.nets[rng.integers(0, len(d.nets), 50)]
    pn = pn * rng.uniform(0.5, 1.5, (50, 1, 1, 1))  # other scales (weights too)
    a, b = both(lambda: faceset_subdivide._halve(d, pn.copy()))
    same(a, b)
    t = rng.uniform(0.05, 0.95, 50)
    for axis in (2, 3):
        same(*both(lambda: faceset_subdivide._split_both(pn, axis, t)))


def _levels(d, q, R, levels):
    """The pairs of ``levels`` halvings of face ``d``'s roots near queries ``q``, every
    level's bounds (the numpy engine lays the pairs out)."""
    with kernels.forced("numpy"):
        groups = _root_pairs([d], q, R)
        it = groups[0][2]
        out = [it]
        for _ in range(levels):
            it = faceset_subdivide.children(d, it)
            out.append(it)
    return out


@needs_numba
@pytest.mark.parametrize("make", [lambda: dome_faces()[0], trimmed_cylinder,
                                  lambda: fillet_ring(), lambda: plate_with_hole()])
def test_sub_patch_bounds_and_children_agree(make):
    d = _FaceData(make(), 0)
    lo, hi = d.lo.min(axis=0), d.hi.max(axis=0)
    rng = np.random.default_rng(5)
    q = rng.uniform(lo[:2] - 1.0, hi[:2] + 1.0, (40, 2))
    R = 3.0
    for it in _levels(d, q, R, 5):
        a, b = both(lambda it=it: faceset_bounds.sub_patch_bounds(d, it, q, R))
        close(a, b)
        floor = np.where(np.isfinite(a[1]), a[1], -np.inf)
        close(*both(lambda it=it, f=floor: faceset_bounds.sub_patch_bounds(d, it, q, R, f)))
        ca, cb = both(lambda it=it: faceset_subdivide.children(d, it))
        for name in ("query", "node", "nets", "box", "depth", "status", "segs"):
            same(getattr(ca, name), getattr(cb, name))


# -- the drop-cutter, end to end ---------------------------------------------------------------
def drop_both(faces, xy, R):
    """FaceSet.drop_ball of ``xy`` under both engines, and each run's pair counts."""
    def run():
        fs = FaceSet(faces)
        return fs.drop_ball(xy, R), dict(fs.stats)
    return both(run)


def assert_same_drop(a, b, atol=1e-12):
    (ra, sa), (rb, sb) = a, b
    assert sa == sb  # the same decisions: the same pairs bounded at the same levels
    tip_a, tip_b = ra[0], rb[0]
    assert np.array_equal(np.isnan(tip_a), np.isnan(tip_b))
    np.testing.assert_allclose(tip_a, tip_b, rtol=0, atol=atol, equal_nan=True)
    assert np.array_equal(ra[1], rb[1]) and np.array_equal(ra[4], rb[4])
    for x, y in zip(ra[2:4], rb[2:4]):
        np.testing.assert_allclose(x, y, rtol=0, atol=atol)


@needs_numba
@pytest.mark.parametrize("name", ["two_faces", "dome", "cylinder", "fillet_plate", "hole"])
def test_drop_ball_agrees_on_numpy_faces(name):
    faces = {"two_faces": two_faces, "dome": dome_faces,
             "cylinder": lambda: [trimmed_cylinder(), Face(plane(-12, 12, -5, 35, 2.0),
                                                          rectangle(plane(-12, 12, -5, 35, 2.0)),
                                                          index=1, selected=False)],
             "fillet_plate": lambda: [plate_with_hole(), fillet_ring()],
             "hole": lambda: [holed_plane(300)]}[name]()
    fs = FaceSet(faces)
    lo, hi = fs.bounds(selected_only=False)
    rng = np.random.default_rng(6)
    xy = rng.uniform(lo[:2] - 2.0, hi[:2] + 2.0, (300, 2))
    a, b = drop_both(faces, xy, 3.0)
    assert np.isfinite(a[0][0]).any()
    assert_same_drop(a, b)


@needs_numba
def test_drop_ball_agrees_on_the_step_part():
    pytest.importorskip("OCP")
    R = 3.0
    faces, xy = step_part_queries(7, R)
    a, b = drop_both(faces, xy, R)
    assert a[1]["pairs"] > 10_000
    assert_same_drop(a, b)
