# SPDX-License-Identifier: LGPL-2.1-or-later
"""The drop-cutter's warm start (BSplineCAM.core.toolpath.faceset_hints): a hint (a
neighbour's contact) leaves every height certified (within CERTIFY of the height without
it), a hint that is no lower bound (outside the trim or the domain, out of reach, on a wall
or an unknown face) changes nothing, a hint far below changes nothing, and both engines give
the same heights, contacts and counters with the same hints.  ContactMemo offers the
nearest remembered contact."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from bsplinecam_helpers import (
    close,
    dome_faces,
    fillet_ring,
    plate_with_hole,
    rectangle,
    same,
    same_drops,
)

from BSplineCAM.core import kernels
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.toolpath.faceset import CERTIFY, FaceSet
from BSplineCAM.core.toolpath.faceset_hints import HINT_CELLS, ContactMemo

R = 3.0


def wall(x0, y0, y1, z0, z1, index):
    """A vertical plane x = x0 from y0 to y1 and z0 to z1 (unselected: a wall)."""
    poles = np.array([[[x0, y0, z0], [x0, y1, z0]], [[x0, y0, z1], [x0, y1, z1]]], float)
    s = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    return Face(s, rectangle(s), index=index, selected=False)


def low_plane(index):
    """A plane 30 mm below the others, unselected (a check face far below)."""
    poles = np.array([[[-5, -5, -20], [-5, 45, -20]], [[45, -5, -20], [45, 45, -20]]], float)
    s = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    return Face(s, rectangle(s), index=index, selected=False)


FACES = {
    "fillet_plate": lambda: [plate_with_hole(), fillet_ring()],
    "dome": dome_faces,
    "walls": lambda: [plate_with_hole(), wall(5.0, 0.0, 40.0, 0.0, 14.0, 1),
                      wall(35.0, 0.0, 40.0, 0.0, 12.0, 2), fillet_ring(), low_plane(4)],
}


def queries(fs: FaceSet, n: int, seed: int) -> np.ndarray:
    lo, hi = fs.bounds(selected_only=False)
    return np.random.default_rng(seed).uniform(lo[:2] - 2.0, hi[:2] + 2.0, (n, 2))


def neighbour_hints(fs: FaceSet, q: np.ndarray, step: float, seed: int) -> tuple:
    """The contacts of points ``step`` mm from the queries (in random directions)."""
    a = np.random.default_rng(seed).uniform(0.0, 2 * np.pi, len(q))
    near = q + step * np.column_stack([np.cos(a), np.sin(a)])
    _, face, u, v, _ = fs.drop_ball(near, R)
    return face, u, v


def engine(name):
    if name == "numba" and importlib.util.find_spec("numba") is None:
        pytest.skip("numba is not installed")
    ctx = kernels.forced(name)
    e = ctx.__enter__()
    if e.name != name:
        ctx.__exit__(None, None, None)
        pytest.skip(f"no {name} engine: {e.reason}")
    return ctx


# -- certified with any hint -------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(FACES))
@pytest.mark.parametrize("step", [0.01, 0.5, 2.5])
def test_hinted_heights_certified(name, step):
    """With neighbours' contacts as hints the heights stay within CERTIFY of the heights
    without (both are certified), the same queries find a face, and the pairs bounded do not
    grow in total."""
    faces = FACES[name]()
    fs = FaceSet(faces)
    q = queries(fs, 200, 5)
    plain = FaceSet(faces)
    tip0, face0, *_ = plain.drop_ball(q, R)
    hinted = FaceSet(faces)
    hint = neighbour_hints(fs, q, step, 6)
    tip1, face1, *_ = hinted.drop_ball(q, R, hint=hint)
    assert np.array_equal(np.isnan(tip0), np.isnan(tip1))
    ok = np.isfinite(tip0)
    assert ok.sum() > 100
    assert np.abs(tip1[ok] - tip0[ok]).max() <= CERTIFY
    assert (hint[0] >= 0).sum() > 100  # the hints were offered
    if step <= 0.5:
        assert hinted.stats["pairs"] <= plain.stats["pairs"]


def test_own_contact_as_hint_keeps_height():
    """A query's own answer as its hint: the same height to 1e-12 mm (a smooth maximum is
    polished to machine precision either way) and fewer pairs bounded."""
    faces = FACES["fillet_plate"]()
    q = queries(FaceSet(faces), 300, 8)
    plain = FaceSet(faces)
    tip0, face0, u0, v0, _ = plain.drop_ball(q, R)
    hinted = FaceSet(faces)
    tip1, face1, *_ = hinted.drop_ball(q, R, hint=(face0, u0, v0))
    close(tip1, tip0, 1e-12)
    assert hinted.stats["pairs"] < plain.stats["pairs"]


# -- hints that are no lower bound -------------------------------------------------------------
def useless_hints(fs: FaceSet, q: np.ndarray) -> dict:
    m = len(q)
    one = np.ones(m)
    return {
        # plate_with_hole (face 0): (0.5, 0.5) is the hole's centre, outside the trim
        "in the hole": (np.zeros(m, int), 0.5 * one, 0.5 * one),
        "outside the domain": (np.zeros(m, int), 1.5 * one, -0.25 * one),
        "not finite": (np.zeros(m, int), np.full(m, np.nan), np.full(m, np.inf)),
        "unknown face": (np.full(m, 99), 0.5 * one, 0.5 * one),
        "no face": (np.full(m, -1), 0.2 * one, 0.2 * one),
        "a wall": (np.full(m, 1), 0.5 * one, 0.5 * one),
        # the plate's corner (0, 0): out of reach of every query farther than R from it
        "out of reach": (np.zeros(m, int), 0.0 * one, 0.0 * one),
        # the point of the plane 30 mm below the others right under the query
        "far below": (np.full(m, 4), (q[:, 0] + 5.0) / 50.0, (q[:, 1] + 5.0) / 50.0),
    }


KINDS = ["in the hole", "outside the domain", "not finite", "unknown face", "no face", "a wall",
         "out of reach", "far below"]


@pytest.mark.parametrize("kind", KINDS)
def test_useless_hint_changes_nothing(kind):
    """Heights, contacts and counters the same to the last bit as without a hint."""
    faces = FACES["walls"]()
    fs = FaceSet(faces)
    q = queries(fs, 200, 9)
    if kind == "out of reach":
        q = q[np.hypot(q[:, 0], q[:, 1]) > R + 1e-9]
    hint = useless_hints(fs, q)[kind]
    assert sorted(useless_hints(fs, q)) == sorted(KINDS)
    plain = FaceSet(faces)
    hinted = FaceSet(faces)
    a = plain.drop_ball(q, R)
    b = hinted.drop_ball(q, R, hint=hint)
    if kind == "far below":
        # where a face above holds the ball the hint is far below its height: nothing
        # changes; where the ball stands on the low plane the hint is its contact
        over = a[0] > -10.0
        assert over.sum() > 50 and (~over).sum() > 10
        same([x[over] for x in a], [x[over] for x in b])
        close(a[0], b[0], CERTIFY)
    else:
        same(a, b)
        assert plain.stats == hinted.stats


def test_hint_arrays_checked():
    fs = FaceSet(FACES["dome"]())
    q = queries(fs, 5, 1)
    with pytest.raises(ValueError, match="hint"):
        fs.drop_ball(q, R, hint=(np.zeros(4, int), np.zeros(4), np.zeros(4)))
    with pytest.raises(ValueError, match="hint"):
        fs.drop_ball(q, R, hint=(np.zeros(6, int), np.zeros(6), np.zeros(6)))
    with pytest.raises(ValueError, match="hint"):
        fs.drop_ball(q, R, hint=(np.zeros(5, int), np.zeros(5)))


# -- both engines --------------------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(FACES))
def test_engines_agree_with_hints(name):
    """The same hints (neighbours', one in the hole, one on the plane far below) give the
    same heights (to 1e-12 mm), contacts and counters under both engines."""
    faces = FACES[name]()
    fs = FaceSet(faces)
    q = queries(fs, 200, 13)
    face, u, v = neighbour_hints(fs, q, 0.3, 14)
    face, u, v = face.copy(), u.copy(), v.copy()
    face[::7], u[::7], v[::7] = 0, 0.5, 0.5  # the hole's centre on the plate; the dome's top
    if name == "walls":  # the plane far below, under the query
        face[3::7], u[3::7], v[3::7] = 4, (q[3::7, 0] + 5.0) / 50.0, (q[3::7, 1] + 5.0) / 50.0
    out = []
    for choice in ("numpy", "numba"):
        ctx = engine(choice)
        try:
            fs = FaceSet(faces)
            out.append((fs.drop_ball(q, R, hint=(face, u, v)), dict(fs.stats)))
        finally:
            ctx.__exit__(None, None, None)
    same_drops(*out)


# -- the memo of contacts ------------------------------------------------------------------------
def test_memo_offers_nearest_contact():
    memo = ContactMemo((0.1, 1.0))
    face, u, v = memo.hints(np.array([[0.0, 0.0]]))
    same(face, np.array([-1]))
    memo.add(np.array([[0.0, 0.0], [0.5, 0.0], [5.0, 5.0], [9.0, 9.0]]), np.array([3, 4, 5, -1]),
             np.array([0.1, 0.2, 0.3, 0.4]), np.array([1.1, 1.2, 1.3, 1.4]))
    xy = np.array([[0.05, 0.0], [0.45, 0.02], [0.3, 0.0], [5.9, 5.9], [7.5, 7.5], [9.0, 9.0],
                   [np.nan, 0.0]])
    face, u, v = memo.hints(xy)
    # the fine grid first: (0.05, 0) and (0.45, 0.02) sit next to a point of it; (0.3, 0)
    # does not and takes the coarse grid's (its cell's last); (9, 9) had no face
    same(face, np.array([3, 4, 4, 5, -1, -1, -1]))
    same(u[:4], np.array([0.1, 0.2, 0.2, 0.3]))
    same(v[:4], np.array([1.1, 1.2, 1.2, 1.3]))
    # a cell keeps its last contact
    memo.add(np.array([[0.01, 0.0]]), np.array([7]), np.array([0.7]), np.array([1.7]))
    same(memo.hints(np.array([[0.05, 0.0]]))[0], np.array([7]))


def test_memo_cells_checked():
    with pytest.raises(ValueError, match="cells"):
        ContactMemo((0.0, 1.0))
    assert ContactMemo.for_radius(2.0).cells == sorted(2.0 * c for c in HINT_CELLS)
