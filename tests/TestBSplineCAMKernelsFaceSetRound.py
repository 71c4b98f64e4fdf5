# SPDX-License-Identifier: LGPL-2.1-or-later
"""The drop-cutter's fused compiled kernels (BSplineCAM.core.kernels.faceset_round_kernels,
faceset_wall_kernels) against the numpy engine's steps they replace: a level's bounds
(to rounding: the nets' affine parts are summed in another order than numpy's matrix
product), its contacts, open pairs, cuts and halves, and the walls' drop (the same bits),
on adversarial faces (a narrow spike, trimmed faces with many segments, rational faces,
walls, several faces) and end to end through FaceSet.drop_ball."""

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
    plate_with_hole,
    rectangle,
    same,
    same_drops,
)

from BSplineCAM.core import kernels
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.geometry.surface import Surface
from BSplineCAM.core.toolpath import faceset_bounds, faceset_branch, faceset_subdivide
from BSplineCAM.core.toolpath.faceset import FaceSet
from BSplineCAM.core.toolpath.faceset_branch import _root_pairs
from BSplineCAM.core.toolpath.faceset_walls import _vertical, _Walls

pytestmark = pytest.mark.skipif(importlib.util.find_spec("numba") is None,
                                reason="numba is not installed: no compiled engine to compare")


def numba_engine():
    """The numba engine (skip without it)."""
    ctx = kernels.forced("numba")
    e = ctx.__enter__()
    if e.name != "numba":
        ctx.__exit__(None, None, None)
        pytest.skip(f"no numba engine: {e.reason}")
    return ctx


def spike():
    """A narrow spike (0.4 mm wide, 0.44 mm tall) on a flat uniform cubic net."""
    n = 81
    x = np.linspace(0.0, 8.0, n)
    pts = np.zeros((n, n, 3))
    pts[..., 0], pts[..., 1] = np.meshgrid(x, x, indexing="ij")
    pts[40, 40, 2] = 11.25
    s = NurbsSurface.from_surface(Surface(pts, knots="uniform"))
    return Face(s, rectangle(s), index=0)


def trimmed_cylinder():
    ns = cylinder_quarter(10.0, 30.0)
    outer = np.array([[0.02, 0.02], [0.98, 0.02], [0.98, 0.98], [0.02, 0.98], [0.02, 0.02]])
    return Face(ns, outer, holes=(circle(0.5, 0.5, 0.2, 200),))


def wall(x0, y0, y1, z0, z1, index):
    """A vertical plane x = x0 from y0 to y1 and z0 to z1 (unselected: a wall)."""
    poles = np.array([[[x0, y0, z0], [x0, y1, z0]], [[x0, y0, z1], [x0, y1, z1]]], float)
    s = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    return Face(s, rectangle(s), index=index, selected=False)


FACES = {
    "spike": lambda: [spike()],
    "cylinder": lambda: [trimmed_cylinder()],
    "hole": lambda: [holed_plane(300)],
    "fillet_plate": lambda: [plate_with_hole(), fillet_ring()],
    "dome": dome_faces,
    "walls": lambda: [plate_with_hole(), wall(5.0, 0.0, 40.0, 0.0, 14.0, 2),
                      wall(35.0, 0.0, 40.0, 0.0, 12.0, 3)],
}


def queries(fs: FaceSet, n: int, seed: int) -> np.ndarray:
    lo, hi = fs.bounds(selected_only=False)
    return np.random.default_rng(seed).uniform(lo[:2] - 2.0, hi[:2] + 2.0, (n, 2))


def levels(d, q, R, count, most=1500):
    """The pairs of ``count`` halvings of face ``d``'s roots near ``q`` (numpy engine), at
    most ``most`` of them (every few) kept at each level."""
    with kernels.forced("numpy"):
        groups = _root_pairs([d], q, R)
        if not groups:
            return []
        it = groups[0][2]
        out = []
        for _ in range(count + 1):
            if len(it.query) > most:
                it = it.take(np.arange(0, len(it.query), -(-len(it.query) // most)))
            out.append(it)
            it = faceset_subdivide.children(d, it)
    return out


# -- a level's bounds --------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["spike", "cylinder", "hole", "fillet_plate", "dome"])
def test_bound_pairs_agree(name):
    """The fused bounds against the numpy engine's: upper bounds to rounding, the lower
    bounds and their contacts alike; with the queries' lower bounds as the floor too (the
    rim bound's pairs)."""
    faces = FACES[name]()
    fs = FaceSet(faces)
    q = queries(fs, 40, 11)
    R = 3.0
    seen = 0
    for d in fs.data:
        for it in levels(d, q, R, 16):
            with kernels.forced("numpy"):
                a = faceset_bounds.sub_patch_bounds(d, it, q, R)
                floor = np.where(np.isfinite(a[1]), a[1], -np.inf)
                fa = faceset_bounds.sub_patch_bounds(d, it, q, R, floor)
            ctx = numba_engine()
            try:
                b = faceset_bounds._fused_bounds(d, it, q, R, -np.inf)
                fb = faceset_bounds._fused_bounds(d, it, q, R, floor)
            finally:
                ctx.__exit__(None, None, None)
            for x, y in ((a, b), (fa, fb)):
                close(x[0], y[0])
                for k in (1, 2, 3):
                    close(x[k], y[k], 1e-12)
            seen += len(it.query)
    assert seen


def test_rim_bound_agrees():
    """The compiled rim bound (faceset_rim_kernels) against the numpy engine's on the same
    level's bounds, straddling pairs and planes, balls whose rim grazes the faces' sides
    included: the same bits.  It is reached: it lowers bounds, on the rational cylinder and
    on straddling pairs (their material's vertices) too."""
    seen = {}
    real = faceset_bounds._rim_bound
    R = 3.0

    def both(d, it, P, qq, R_, ub, dd, floor, m):
        a, b = ub.copy(), ub.copy()
        with kernels.forced("numpy"):
            real(d, it, P, qq, R_, a, dd, floor, m)
        faceset_bounds._rim_compiled(d, it, P, qq, R_, b, dd, floor, m)
        same(a, b)
        lowered = a != ub
        seen["all"] = seen.get("all", 0) + int(lowered.sum())
        if d.face.surface.rational:
            seen["rational"] = seen.get("rational", 0) + int(lowered.sum())
        if len(m.strad):
            rows = m.strad[m.listed]
            seen["straddling"] = seen.get("straddling", 0) + int(lowered[rows].sum())
        ub[:] = b

    for name in ("spike", "cylinder", "hole", "fillet_plate", "dome"):
        faces = FACES[name]()
        fs = FaceSet(faces)
        q = queries(fs, 40, 11)
        # balls whose rim grazes the faces' sides from outside (the rim bound's pairs)
        lo, hi = fs.bounds(selected_only=False)
        t = np.linspace(0.0, 1.0, 40)
        ring = []
        for off in (0.9 * R, 0.97 * R, 0.995 * R):
            x = lo[0] - off + t * (hi[0] - lo[0] + 2 * off)
            y = lo[1] - off + t * (hi[1] - lo[1] + 2 * off)
            ring += [np.column_stack([x, np.full(40, lo[1] - off)]),
                     np.column_stack([x, np.full(40, hi[1] + off)]),
                     np.column_stack([np.full(40, lo[0] - off), y]),
                     np.column_stack([np.full(40, hi[0] + off), y])]
        q = np.vstack([q] + ring)
        ctx = numba_engine()
        try:
            faceset_bounds._rim_bound = both
            for d in fs.data:
                for it in levels(d, q, R, 18):
                    faceset_bounds._fused_bounds(d, it, q, R, -np.inf)
            FaceSet(faces).drop_ball(q, R)
        finally:
            faceset_bounds._rim_bound = real
            ctx.__exit__(None, None, None)
    assert seen["all"] > 100 and seen["rational"] and seen["straddling"], seen


# -- contacts, open pairs and halves -----------------------------------------------------------
def test_record_contacts_agrees():
    """The largest finite lower bound per query, the last of equals, only where it beats the
    face's best so far."""
    rng = np.random.default_rng(2)
    n, m = 500, 40
    query = rng.integers(0, m, n)
    lb = rng.choice([-np.inf, np.inf, np.nan, 1.0, 2.0, 0.0, -0.0], n)
    lb[rng.random(n) < 0.5] = rng.normal(size=(rng.random(n) < 0.5).sum())[:1]
    lu, lv = rng.random(n), rng.random(n)
    fb0 = np.where(rng.random((2, m)) < 0.3, 1.5, -np.inf)

    class It:
        pass

    it = It()
    it.query = query
    out = []
    for fused in (False, True):
        fb, fu, fv = fb0.copy(), np.zeros((2, m)), np.zeros((2, m))
        if fused:
            ctx = numba_engine()
            try:
                faceset_branch.rk.record_contacts(1, query.astype(np.int64), lb, lu, lv, fb,
                                                  fu, fv, np.zeros(m, bool))
            finally:
                ctx.__exit__(None, None, None)
        else:
            faceset_branch._record_contacts(1, it, lb, lu, lv, fb, fu, fv)
        out.append((fb, fu, fv))
    same(out[0], out[1])
    assert (out[0][0][1] > fb0[1]).any()


def _state(it, m, nf, j, rng, crowd):
    """A level's state around pairs ``it`` of face row ``j``: the queries' best (a little
    below some pairs' upper bounds), regions around some pairs' boxes (some holding them,
    some cutting them), some queries given up; ``crowd``: many pairs of one query open."""
    ub = rng.uniform(0.0, 1.0, len(it.query))
    best = np.full(m, 0.5)
    best[rng.random(m) < 0.2] = -np.inf
    reg_box = np.zeros((nf, m, 4))
    reg_val = np.full((nf, m), np.inf)
    for qi in range(m):
        rows = np.flatnonzero(it.query == qi)
        if len(rows) == 0 or rng.random() < 0.4:
            continue
        b = it.box[rng.choice(rows)]
        wu, wv = b[1] - b[0], b[3] - b[2]
        grow = rng.uniform(-0.3, 0.8)
        reg_box[j, qi] = [b[0] - grow * wu, b[1] + grow * wu, b[2] - 0.1 * wv, b[3] + 0.3 * wv]
        reg_val[j, qi] = best[qi] + rng.choice([0.0, 1.0])
    given_up = rng.random(m) < 0.1
    if crowd:
        ub[it.query == it.query[0]] = rng.uniform(0.6, 0.9, (it.query == it.query[0]).sum())
        ub[::7] = ub[::5][: len(ub[::7])]  # ties
        given_up[it.query[0]] = False
    return ub, best, reg_box, reg_val, given_up


@pytest.mark.parametrize("name", ["spike", "cylinder", "hole", "fillet_plate", "walls"])
@pytest.mark.parametrize("crowd", [False, True])
def test_open_children_agree(name, crowd):
    """Open pairs, gaps, crowded queries, cuts along regions' sides and the classified halves
    (parents with listed and with too many segments): the same bits."""
    faces = FACES[name]()
    fs = FaceSet(faces)
    m = 30 if not crowd else 3
    q = queries(fs, m, 13)
    if crowd:
        lo, hi = fs.bounds(selected_only=False)
        q[:] = 0.5 * (lo[:2] + hi[:2])
    R = 3.0
    rng = np.random.default_rng(17)
    seen = crowded_seen = 0
    for j, d in enumerate(fs.data):
        for depth, it in enumerate(levels(d, q, R, 8)):
            if crowd and depth < 6:
                continue
            ub, best, reg_box, reg_val, given_up = _state(it, m, len(fs.data), j, rng, crowd)
            it.depth[:] = np.where(rng.random(len(it.depth)) < 0.05, 48, it.depth)
            certify = 1e-4
            with kernels.forced("numpy"):
                gap_a = np.zeros(m)
                stats = {"uncertified": 0}
                open_, rb, inreg, crowded_a = faceset_branch._open_pairs(
                    j, it, ub, best, gap_a, reg_box, reg_val, given_up, certify, stats, m)
                halves_a = faceset_subdivide.children(
                    d, it, open_, faceset_subdivide.region_cuts(it, open_, rb, inreg))
            gap_b = np.zeros(m)
            crowded_b = np.zeros(m, bool)
            ctx = numba_engine()
            try:
                halves_b, unc = faceset_subdivide.open_children(
                    j, d, it, ub, best, gap_b, reg_box, reg_val, given_up, certify, crowded_b)
            finally:
                ctx.__exit__(None, None, None)
            same(gap_a, gap_b)
            same(crowded_a, crowded_b)
            assert unc == stats["uncertified"]
            for key in ("query", "node", "nets", "box", "depth", "status", "segs"):
                same(getattr(halves_a, key), getattr(halves_b, key))
            seen += len(halves_a.query)
            crowded_seen += int(crowded_a.any())
    assert seen
    assert crowded_seen or not crowd


# -- walls -------------------------------------------------------------------------------------
def test_walls_drop_agrees():
    """The walls' border chords: the same heights, walls and contacts, queries beside, on
    and between the walls, a ball touching a chord's end with its rim."""
    faces = [plate_with_hole(), wall(5.0, 0.0, 40.0, 0.0, 14.0, 2),
             wall(35.0, 0.0, 40.0, 0.0, 12.0, 3), wall(20.0, 10.0, 10.0 + 1e-9, 0.0, 9.0, 4)]
    idx = [k for k, f in enumerate(faces) if not f.selected and _vertical(f.surface)]
    w = _Walls([faces[k] for k in idx], idx)
    rng = np.random.default_rng(5)
    q = np.vstack([rng.uniform(-2.0, 42.0, (600, 2)), [[5.0, 20.0], [8.0, 40.0], [2.0, -3.0],
                                                       [20.0, 10.0], [23.0, 10.0]]])
    with kernels.forced("numpy"):
        a = w.drop(q, 3.0)
    ctx = numba_engine()
    try:
        b = w.drop(q, 3.0)
    finally:
        ctx.__exit__(None, None, None)
    same(a, b)
    assert (a[1] >= 0).sum() > 100


@pytest.mark.parametrize("block", [1, 3, 16, 1000])
def test_walls_blocks_agree(block, monkeypatch):
    """The compiled walls' drop passes over runs of chords out of reach whole: the same
    answers as the numpy engine's whatever the runs' length, on walls of many chords, a
    chord of NaN box among them."""
    from BSplineCAM.core.toolpath import faceset_walls

    monkeypatch.setattr(faceset_walls, "WALL_BLOCK", block)
    faces = [plate_with_hole(), wall(5.0, 0.0, 40.0, 0.0, 14.0, 2),
             wall(35.0, 0.0, 40.0, 0.0, 12.0, 3), wall(20.0, 10.0, 30.0, 0.0, 9.0, 4)]
    idx = [k for k, f in enumerate(faces) if not f.selected and _vertical(f.surface)]
    w = _Walls([faces[k] for k in idx], idx)
    # many chords: each border chord cut into pieces, in order along it
    n = 60
    a, b = w.seg[:, 0], w.seg[:, 1]
    t = np.linspace(0.0, 1.0, n + 1)
    w.seg = np.stack([np.stack([a + (b - a) * t[k], a + (b - a) * t[k + 1]], axis=1)
                      for k in range(n)], axis=1).reshape(-1, 2, 3)
    w.owner = np.repeat(w.owner, n)
    w.uv = np.repeat(w.uv, n, axis=0)
    w.seg[7, 0, 0] = np.nan
    w.boxes_of_chords()
    assert w.block == block and len(w.block_lo) == -(-len(w.seg) // block)
    q = np.random.default_rng(9).uniform(-4.0, 44.0, (800, 2))
    with kernels.forced("numpy"):
        want = w.drop(q, 3.0)
    ctx = numba_engine()
    try:
        got = w.drop(q, 3.0)
    finally:
        ctx.__exit__(None, None, None)
    same(want, got)
    assert (want[1] >= 0).sum() > 100


# -- the drop-cutter, end to end ---------------------------------------------------------------
@pytest.mark.parametrize("name", ["spike", "walls", "fillet_plate", "cylinder"])
def test_drop_ball_agrees(name):
    """Heights, contacts and pair counts under both engines."""
    faces = FACES[name]()
    q = queries(FaceSet(faces), 250, 21)
    if name == "spike":
        q = np.vstack([q, np.column_stack([np.linspace(3.0, 5.0, 60), np.full(60, 4.0)])])
    out = []
    for choice in ("numpy", "numba"):
        if choice == "numpy":
            ctx = kernels.forced("numpy")
            ctx.__enter__()
        else:
            ctx = numba_engine()
        try:
            fs = FaceSet(faces)
            out.append((fs.drop_ball(q, 3.0), dict(fs.stats)))
        finally:
            ctx.__exit__(None, None, None)
    same_drops(*out)
    (ra, _), _ = out
    assert np.isfinite(ra[0]).sum() > 100
