# SPDX-License-Identifier: LGPL-2.1-or-later
"""The compiled twins of the drop-cutter's local certificates and contact polish
(BSplineCAM/core/kernels/regions_kernels.py) against the numpy engine: each kernel's answers on
the inputs a drop-cutter run gives it, and whole drops over polynomial, rational and trimmed
faces, under both engines (the numba half skips where numba is missing)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from bsplinecam_helpers import (
    circle,
    cylinder_quarter,
    fillet_ring,
    plate_with_hole,
    rectangle,
    two_faces,
)

from BSplineCAM.core import Surface, kernels
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.toolpath import faceset_contacts, faceset_regions
from BSplineCAM.core.toolpath.faceset import FaceSet

ROOT = Path(__file__).resolve().parent.parent
R = 3.0


def _wavy_fillet() -> NurbsSurface:
    """A quarter-circle fillet (radius 3, along y) raised to degree 5 along y with uneven poles
    and weights: rational both ways, its N hull along y not zero."""
    c = math.sqrt(0.5)
    arc = [(0.0, 3.0), (3.0, 3.0), (3.0, 0.0)]
    ys = np.array([0.0, 1.0, 3.5, 4.0, 6.5, 8.0])
    wy = np.array([1.0, 1.1, 0.9, 1.05, 0.95, 1.0])
    poles = np.array([[[x, y, z] for y in ys] for x, z in arc])
    weights = np.array([[w * wy_ for wy_ in wy] for w in (1.0, c, 1.0)])
    return NurbsSurface(poles, [0, 0, 0, 1, 1, 1], [0.0] * 6 + [1.0] * 6, 2, 5,
                        weights=weights)


def _case_study() -> list:
    ns = NurbsSurface.from_surface(Surface.from_json(ROOT / "examples" / "case-study.json"))
    return [Face(ns, rectangle(ns), holes=(circle(0.3, 0.6, 0.08, 90),))]


def _trimmed_cylinder() -> list:
    ns = cylinder_quarter(10.0, 30.0)
    outer = np.array([[0.02, 0.02], [0.98, 0.02], [0.98, 0.98], [0.02, 0.98], [0.02, 0.02]])
    return [Face(ns, outer, holes=(circle(0.5, 0.5, 0.2, 200),))]


def _fillet_and_top() -> list:
    fillet = _wavy_fillet()
    top = NurbsSurface(np.array([[[-6.0, 0.0, 3.0], [-6.0, 8.0, 3.0]],
                                 [[0.0, 0.0, 3.0], [0.0, 8.0, 3.0]]]),
                       [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    notch = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.45], [0.7, 0.5], [1.0, 0.55], [1.0, 1.0],
                      [0.0, 1.0], [0.0, 0.0]])
    return [Face(fillet, rectangle(fillet)), Face(top, notch, index=1)]


def _boss() -> list:
    return [plate_with_hole(), fillet_ring()]


CASES = {
    "case-study": (_case_study, (0.0, 100.0, 0.0, 100.0)),
    "trimmed-cylinder": (_trimmed_cylinder, (-8.0, 8.0, 0.0, 30.0)),
    "fillet-and-top": (_fillet_and_top, (-6.0, 6.0, 0.0, 8.0)),
    "boss": (_boss, (0.0, 40.0, 0.0, 40.0)),
    "two-faces": (two_faces, (0.0, 32.0, 0.0, 24.0)),
}


def _queries(box, n: int = 300, seed: int = 7) -> np.ndarray:
    x0, x1, y0, y1 = box
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(x0, x1, n), rng.uniform(y0, y1, n)])


@pytest.fixture
def numba_engine():
    pytest.importorskip("numba")
    with kernels.forced("numba") as e:
        if e.name != "numba":
            pytest.skip(f"numba does not run here: {e.reason}")
    return e


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.kind == "f":
        return bool(np.all((a == b) | (np.isnan(a) & np.isnan(b))))
    return bool(np.array_equal(a, b))


def _recorded_regions(faces, q):
    """The arguments of every face_regions call of a numpy-engine drop over ``faces``."""
    calls = []
    original = faceset_regions.face_regions

    def record(*args):
        calls.append(args)
        return original(*args)

    faceset_regions.face_regions = record
    try:
        with kernels.forced("numpy"):
            FaceSet(faces).centre_heights(q, R)
    finally:
        faceset_regions.face_regions = original
    return calls


@pytest.mark.parametrize("name", sorted(CASES))
def test_face_regions_kernel_agrees(name, numba_engine):
    make, box = CASES[name]
    faces = make()
    calls = _recorded_regions(faces, _queries(box))
    assert calls, "the drop sought no local certificate"
    rows = found = 0
    for args in calls:
        with kernels.forced("numpy"):
            ref = faceset_regions.face_regions(*args)
        with kernels.forced("numba"):
            got = faceset_regions.face_regions(*args)
        for a, b in zip(ref, got):
            assert _same(a, b)
        rows += len(ref[0])
        found += int(ref[0].sum())
    assert found > 0 and rows > found / 2


def _perturbed_contacts(fs: FaceSet, q: np.ndarray, seed: int):
    """Contacts near the certified ones (moved by up to 2 % of the domain, pulled back into
    it) with their values f as lower bounds: polish's starting points."""
    with kernels.forced("numpy"):
        res = fs.centre_heights(q, R)
    rng = np.random.default_rng(seed)
    face, u, v = res.face.copy(), res.u.copy(), res.v.copy()
    best = np.full(len(q), -np.inf)
    for d in fs.data:
        idx = np.flatnonzero(face == d.index)
        (u0, u1), (v0, v1) = d.face.surface.domain
        u[idx] = np.clip(u[idx] + rng.uniform(-0.02, 0.02, len(idx)) * (u1 - u0), u0, u1)
        v[idx] = np.clip(v[idx] + rng.uniform(-0.02, 0.02, len(idx)) * (v1 - v0), v0, v1)
        # a third exactly on their old contact (on a trim edge: the edge polish's start)
        keep = idx[::3]
        u[keep], v[keep] = res.u[keep], res.v[keep]
        p = d.face.surface.evaluate(u[idx], v[idx])
        d2 = ((p[:, :2] - q[idx]) ** 2).sum(axis=1)
        ok = (d2 <= R * R) & d.inside(u[idx], v[idx])
        best[idx] = np.where(ok, p[:, 2] + np.sqrt(np.maximum(R * R - d2, 0.0)), -np.inf)
    face[~np.isfinite(best)] = -1
    return best, face, u, v


@pytest.mark.parametrize("name", sorted(CASES))
def test_polish_kernels_agree(name, numba_engine):
    make, box = CASES[name]
    fs = FaceSet(make())
    q = _queries(box, 200, seed=11)
    start = _perturbed_contacts(fs, q, seed=5)
    out = {}
    for engine in ("numpy", "numba"):
        best, face, u, v = (a.copy() for a in start)
        with kernels.forced(engine):
            faceset_contacts.polish(fs.data, q, R, best, face, u, v, steps=8)
        out[engine] = (best, face, u, v)
    for a, b in zip(out["numpy"], out["numba"]):
        assert _same(a, b)
    # the polish did move contacts
    assert np.any(out["numpy"][0] > start[0])


@pytest.mark.parametrize("name", sorted(CASES))
def test_grad_hess_kernel_agrees(name, numba_engine):
    make, box = CASES[name]
    fs = FaceSet(make())
    q = _queries(box, 200, seed=13)
    for d in fs.data:
        s = d.face.surface
        (u0, u1), (v0, v1) = s.domain
        rng = np.random.default_rng(d.index)
        u = rng.uniform(u0, u1, len(q))
        v = rng.uniform(v0, v1, len(q))
        with np.errstate(all="ignore"):
            ref = np.array(faceset_contacts.grad_hess(s, u, v, q, R * R))
        with kernels.forced("numba"):
            got = faceset_contacts._grad_hess_compiled(s, u, v, np.ascontiguousarray(q), R * R)
        assert _same(ref, got)


@pytest.mark.parametrize("name", sorted(CASES))
def test_drop_ball_agrees_between_engines(name, numba_engine):
    """Heights, contact faces, (u, v) and gaps of whole drops (fresh face sets, so no cached
    classification is shared) agree to 1e-12 mm; the faces are the same."""
    make, box = CASES[name]
    q = _queries(box, 400, seed=17)
    res = {}
    for engine in ("numpy", "numba"):
        with kernels.forced(engine):
            res[engine] = FaceSet(make()).centre_heights(q, R)
    a, b = res["numpy"], res["numba"]
    np.testing.assert_array_equal(a.face, b.face)
    found = a.face >= 0
    assert found.sum() > len(q) / 4
    for x, y in ((a.centre, b.centre), (a.u, b.u), (a.v, b.v), (a.gap, b.gap)):
        assert np.array_equal(np.isfinite(x), np.isfinite(y))
        fin = np.isfinite(x)
        assert np.max(np.abs(x[fin] - y[fin]), initial=0.0) <= 1e-12


def test_numpy_engine_runs_without_the_kernels():
    """Under the numpy engine the regions and polish never reach a kernel (they would raise
    KernelUnavailable there) and still certify regions."""
    make, box = CASES["fillet-and-top"]
    calls = _recorded_regions(make(), _queries(box, 150))
    with kernels.forced("numpy"):
        found = sum(int(faceset_regions.face_regions(*a)[0].sum()) for a in calls)
    assert found > 0
