# SPDX-License-Identifier: LGPL-2.1-or-later
"""The NURBS evaluator's two engines (BSplineCAM.core.kernels.nurbs_eval): scattered points,
first and second derivatives and normals of polynomial and rational surfaces of degrees 1..7
agree between the numpy engine and the compiled kernels (1e-12 of the surface's size), the
kernels locate spans and local parameters bit for bit as ``Direction.locate``, and both agree
with Cox–de Boor summed directly (core.geometry.basis) and with scipy's BSpline (venv).

The loop functions also run as plain Python against the numpy engine, so the algorithm is
checked where numba is missing; the compiled half is skipped there."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from BSplineCAM.core import kernels
from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.geometry.basis import cox_de_boor
from BSplineCAM.core.geometry.nurbs import SECOND_ORDER, NurbsSurface, expand_knots
from BSplineCAM.core.kernels import nurbs_eval

HAS_NUMBA = importlib.util.find_spec("numba") is not None
needs_numba = pytest.mark.skipif(not HAS_NUMBA, reason="numba is not installed")

SETTINGS = settings(max_examples=40, deadline=None,
                    suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow])

#: agreement of the two engines, relative to the surface's size or the values' magnitude
ENGINES_REL = 1e-12
#: agreement with the independent references (other arithmetic: Cox–de Boor's recursion)
REFERENCE_REL = 1e-9

ORDERS = SECOND_ORDER + ((3, 0), (0, 3), (2, 2), (3, 1))
FIELDS = ("point", "su", "sw", "suu", "suw", "sww")


# --- surfaces and parameters ------------------------------------------------------------------
def make_surface(p: int, q: int, rational: bool, seed: int = 0, ends: str = "clamped",
                 periodic_u: bool = False) -> NurbsSurface:
    """A p x q surface on non-uniform knots with an interior knot of multiplicity p (and a
    double one along v when q > 1), ends clamped or free, optionally periodic in u."""
    rng = np.random.default_rng(seed)

    def knots(d, values, inner, periodic):
        if periodic:
            mults = [1] + inner + [1]
            return expand_knots(values, mults), sum(mults) - 1
        first = d + 1 if ends == "clamped" else 1
        mults = [first] + inner + [first]
        return expand_knots(values, mults), sum(mults) - d - 1

    ku, n = knots(p, [-1.0, -0.4, 0.1, 0.35, 2.0, 2.5], [1, p, 1, 1], periodic_u)
    if ends != "clamped":  # free ends need more poles than the clamped layout
        ku, n = knots(p, list(np.linspace(-1.0, 2.5, 2 * p + 6)), [1] * (2 * p + 4), periodic_u)
    kv, m = knots(q, [3.0, 3.5, 7.0, 7.25, 9.0], [1, min(2, q), 1], False)
    if ends != "clamped":
        kv, m = knots(q, list(np.linspace(3.0, 9.0, 2 * q + 6)), [1] * (2 * q + 4), False)
    poles = rng.normal(scale=10.0, size=(n, m, 3))
    weights = rng.uniform(0.3, 3.0, size=(n, m)) if rational else None
    return NurbsSurface(poles, ku, kv, p, q, weights=weights, periodic_u=periodic_u)


def parameters(s: NurbsSurface, rng: np.random.Generator, count: int = 30):
    """Random parameters, the domain's corners, every knot in the domain (exactly and one ulp
    either side) paired with random values of the other parameter, and values a hair outside
    the domain that the check clamps."""
    (u0, u1), (v0, v1) = s.domain
    ku = np.unique(s.knots_u[(s.knots_u >= u0) & (s.knots_u <= u1)])
    kv = np.unique(s.knots_v[(s.knots_v >= v0) & (s.knots_v <= v1)])
    ku = np.concatenate([ku, np.nextafter(ku, -np.inf), np.nextafter(ku, np.inf)])
    kv = np.concatenate([kv, np.nextafter(kv, -np.inf), np.nextafter(kv, np.inf)])
    hair_u, hair_v = 1e-12 * (u1 - u0), 1e-12 * (v1 - v0)
    u = [rng.uniform(u0, u1, count), [u0, u1, u0, u1, u0 - hair_u, u1 + hair_u],
         ku, rng.uniform(u0, u1, len(kv))]
    v = [rng.uniform(v0, v1, count), [v0, v0, v1, v1, v1 + hair_v, v0 - hair_v],
         rng.uniform(v0, v1, len(ku)), kv]
    u, v = np.concatenate(u), np.concatenate(v)
    return np.clip(u, u0 - hair_u, u1 + hair_u), np.clip(v, v0 - hair_v, v1 + hair_v)


def relative_error(a, b, size: float) -> float:
    a, b = np.asarray(a), np.asarray(b)
    scale = max(size, float(np.abs(b).max(initial=0.0)), 1e-300)
    return float(np.abs(a - b).max(initial=0.0)) / scale


def evaluations(s: NurbsSurface, u, v) -> dict:
    """Everything the scattered evaluator gives, keyed by name."""
    out = {}
    d = s.derivatives(u, v)
    for name in FIELDS:
        out[name] = getattr(d, name)
    for order in ORDERS:
        out[f"evaluate {order}"] = s.evaluate(u, v, *order)
    out["normals"] = s.normals(u, v)
    h = s._homogeneous_scattered(s._check(u, v)[0], s._check(u, v)[1], list(ORDERS))
    for order in ORDERS:
        out[f"homogeneous {order}"] = h[order]
    return out


def engines(s: NurbsSurface, u, v) -> tuple[dict, dict]:
    """The evaluations under the numpy engine, then under numba (which must have run)."""
    with kernels.forced("numpy"):
        expected = evaluations(s, u, v)
    with kernels.forced("numba"):
        got = evaluations(s, u, v)
        assert kernels.use_numba(), kernels.engine().reason
    return expected, got


def assert_engines_agree(s: NurbsSurface, u, v) -> float:
    expected, got = engines(s, u, v)
    worst = 0.0
    for name, value in expected.items():
        assert got[name].shape == value.shape, name
        err = relative_error(got[name], value, s.size())
        assert err <= ENGINES_REL, f"{s!r} {name}: engines differ by {err:.3g}"
        worst = max(worst, err)
    return worst


# --- the compiled engine against the numpy engine ----------------------------------------------
CASES = [(p, q, r) for p in range(1, 8) for q in (1, 2, 3, 5, 7) for r in (False, True)
         if p == q or q in (1, 3) or (p, q) in ((2, 7), (7, 5))]


@needs_numba
@pytest.mark.parametrize("p,q,rational", CASES)
def test_engines_agree_on_knots_ends_and_inside(p, q, rational):
    s = make_surface(p, q, rational, seed=p * 10 + q)
    u, v = parameters(s, np.random.default_rng(p + 100 * q))
    assert_engines_agree(s, u, v)


@needs_numba
@pytest.mark.parametrize("ends,periodic", [("free", False), ("clamped", True)])
@pytest.mark.parametrize("rational", [False, True])
def test_engines_agree_on_free_ends_and_periodic(ends, periodic, rational):
    for p, q in ((1, 1), (2, 3), (3, 3), (5, 2), (7, 4)):
        s = make_surface(p, q, rational, seed=p + q, ends=ends, periodic_u=periodic)
        u, v = parameters(s, np.random.default_rng(p * q))
        assert_engines_agree(s, u, v)


@st.composite
def surfaces(draw):
    """A surface of degrees 1..7 on random knots (random multiplicities, clamped or free
    ends), rational or not."""
    degrees = (draw(st.integers(1, 7)), draw(st.integers(1, 7)))
    knots = []
    for d in degrees:
        distinct = draw(st.integers(2, 6))
        gaps = draw(st.lists(st.floats(0.01, 1.0), min_size=distinct - 1, max_size=distinct - 1))
        values = draw(st.sampled_from([0.0, -2.5, 40.0])) + draw(
            st.sampled_from([0.1, 1.0, 30.0])) * np.concatenate([[0.0], np.cumsum(gaps)])
        mults = [draw(st.integers(1, d)) for _ in range(distinct)]
        if draw(st.booleans()):
            mults[0] = mults[-1] = d + 1
        flat = expand_knots(values, mults)
        count = len(flat) - d - 1
        assume(count >= d + 1 and flat[d] < flat[count])
        knots.append((flat, count))
    (ku, n), (kv, m) = knots
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    weights = rng.uniform(0.3, 3.0, (n, m)) if draw(st.booleans()) else None
    return NurbsSurface(rng.normal(scale=10.0, size=(n, m, 3)), ku, kv, *degrees,
                        weights=weights)


@needs_numba
@SETTINGS
@given(surfaces(), st.data())
def test_engines_agree_at_generated_parameters(s, data):
    (u0, u1), (v0, v1) = s.domain
    count = data.draw(st.integers(1, 12))
    u = np.array(data.draw(st.lists(st.floats(u0, u1), min_size=count, max_size=count)))
    v = np.array(data.draw(st.lists(st.floats(v0, v1), min_size=count, max_size=count)))
    knots = s.knots_u[(s.knots_u >= u0) & (s.knots_u <= u1)]
    u = np.concatenate([u, knots, [u0, u1]])
    v = np.concatenate([v, np.full(len(knots), v0), [v1, v0]])
    assert_engines_agree(s, u, v)


@needs_numba
@SETTINGS
@given(surfaces(), st.integers(0, 2**32 - 1))
def test_kernel_locates_as_direction_locate_bit_for_bit(s, seed):
    u, v = parameters(s, np.random.default_rng(seed))
    u, v = s._check(u, v)
    with kernels.forced("numba"):
        _, spans, local = nurbs_eval.scattered(*s._pack(((0, 0),)), u, v)
    for axis, (direction, t) in enumerate(((s._u, u), (s._v, v))):
        span, param = direction.locate(t)
        np.testing.assert_array_equal(spans[axis], span)
        assert np.array_equal(local[axis], param), "local parameters differ"
        assert np.array_equal(np.signbit(local[axis]), np.signbit(param))


@needs_numba
def test_shapes_broadcasting_and_empty_batches():
    s = make_surface(3, 2, True, seed=5)
    (u0, u1), (v0, v1) = s.domain
    u = np.linspace(u0, u1, 12).reshape(3, 4)
    cases = [(u, v0), (u, np.full((3, 4), v1)), (0.5 * (u0 + u1), 0.5 * (v0 + v1)),
             (np.array([]), np.array([])), ([u0, u1], [v1, v0])]
    for a, b in cases:
        results = []
        for engine in ("numpy", "numba"):
            with kernels.forced(engine):
                d = s.derivatives(a, b)
                results.append([getattr(d, f) for f in FIELDS] + [s.normals(a, b)])
        for e, g in zip(*results):
            assert g.shape == e.shape
            assert relative_error(g, e, s.size()) <= ENGINES_REL


@needs_numba
def test_out_of_domain_raises_the_same_error():
    s = make_surface(2, 3, False)
    (u0, u1), (v0, v1) = s.domain
    for u, v in (([u0, u1 + 0.01 * (u1 - u0)], [v0, v1]), ([u0], [np.nan]), ([np.inf], [v0])):
        messages = []
        for engine in ("numpy", "numba"):
            with kernels.forced(engine), pytest.raises(ParameterError) as err:
                s.evaluate(u, v)
            messages.append(str(err.value))
        assert messages[0] == messages[1]


@needs_numba
def test_a_kernel_that_fails_leaves_the_numpy_engine(monkeypatch):
    s = make_surface(3, 3, True, seed=9)
    u, v = parameters(s, np.random.default_rng(9))
    with kernels.forced("numpy"):
        expected = evaluations(s, u, v)

    def unavailable(*args):
        raise kernels.KernelUnavailable("test")

    for name in ("scattered", "rational", "check"):
        monkeypatch.setattr(nurbs_eval, name, unavailable)
    with kernels.forced("numba"):
        got = evaluations(s, u, v)
    for name, value in expected.items():
        np.testing.assert_array_equal(got[name], value, err_msg=name)


# --- the loop functions as plain Python (no numba needed) --------------------------------------
@pytest.mark.parametrize("p,q,rational", [(1, 1, False), (2, 3, True), (4, 2, False),
                                          (7, 7, True)])
def test_loop_functions_in_python_match_the_numpy_engine(p, q, rational):
    s = make_surface(p, q, rational, seed=p + 7 * q)
    u, v = parameters(s, np.random.default_rng(3), count=8)
    with kernels.forced("numpy"):
        u, v = s._check(u, v)
        expected = s._homogeneous_scattered(u, v, list(ORDERS))
        rational_expected = s.derivatives(u, v)
    checked = nurbs_eval.check.py(u, v, *s._tolerances)
    assert checked[2] and np.array_equal(checked[0], u) and np.array_equal(checked[1], v)
    orders = tuple(ORDERS)
    out, spans, local = nurbs_eval.scattered.py(*s._pack(orders), u, v)
    for k, order in enumerate(orders):
        assert relative_error(out[k], expected[order], s.size()) <= ENGINES_REL, order
    for axis, (direction, t) in enumerate(((s._u, u), (s._v, v))):
        span, param = direction.locate(t)
        assert np.array_equal(spans[axis], span) and np.array_equal(local[axis], param)
    if rational:
        needed = ((0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (2, 0))
        hom, _, _ = nurbs_eval.scattered.py(*s._pack(needed), u, v)
        index = np.zeros((3, 3), dtype=np.int64)
        for k, (a, b) in enumerate(needed):
            index[a, b] = k
        quotients = nurbs_eval.rational.py(hom, np.array(needed, dtype=np.int64), index)
        for k, name in zip(range(6), ("point", "sw", "sww", "su", "suw", "suu")):
            got = quotients[k]
            assert relative_error(got, getattr(rational_expected, name), s.size()) \
                <= ENGINES_REL, name
    assert not nurbs_eval.check.py(np.array([np.nan]), v[:1], *s._tolerances)[2]


# --- both engines against independent references -----------------------------------------------
def cox_de_boor_reference(s: NurbsSurface, u, v) -> dict:
    """Point and partial derivatives up to second order from Cox–de Boor's recursion summed
    directly, the quotient rule written out."""
    nu = [cox_de_boor(s.knots_u, s.degree_u, u, d) for d in range(3)]
    nv = [cox_de_boor(s.knots_v, s.degree_v, v, d) for d in range(3)]
    return _quotients(s, nu, nv)


def _quotients(s: NurbsSurface, nu, nv) -> dict:
    w = s.weights if s.weights is not None else np.ones(s.shape)
    a = {(i, j): np.einsum("mi,ijc,mj->mc", nu[i], s.poles * w[..., None], nv[j])
         for i in range(3) for j in range(3) if i + j <= 2}
    h = {(i, j): np.einsum("mi,ij,mj->m", nu[i], w, nv[j])[:, None]
         for i in range(3) for j in range(3) if i + j <= 2}
    pt = a[0, 0] / h[0, 0]
    su = (a[1, 0] - h[1, 0] * pt) / h[0, 0]
    sv = (a[0, 1] - h[0, 1] * pt) / h[0, 0]
    return {"point": pt, "su": su, "sw": sv,
            "suu": (a[2, 0] - 2 * h[1, 0] * su - h[2, 0] * pt) / h[0, 0],
            "sww": (a[0, 2] - 2 * h[0, 1] * sv - h[0, 2] * pt) / h[0, 0],
            "suw": (a[1, 1] - h[1, 0] * sv - h[0, 1] * su - h[1, 1] * pt) / h[0, 0]}


def _assert_matches(s: NurbsSurface, u, v, reference: dict) -> None:
    for engine in ("numpy", "numba") if HAS_NUMBA else ("numpy",):
        with kernels.forced(engine):
            d = s.derivatives(u, v)
        for name, expected in reference.items():
            err = relative_error(getattr(d, name), expected, s.size())
            assert err <= REFERENCE_REL, f"{engine} {s!r} {name}: {err:.3g}"


@pytest.mark.parametrize("p,q,rational", [(1, 2, False), (3, 3, True), (5, 4, True),
                                          (7, 7, False), (7, 2, True)])
def test_engines_against_cox_de_boor(p, q, rational):
    s = make_surface(p, q, rational, seed=p * q)
    u, v = parameters(s, np.random.default_rng(p + q))
    u, v = s._check(u, v)
    _assert_matches(s, u, v, cox_de_boor_reference(s, u, v))


@pytest.mark.parametrize("p,q,rational", [(1, 1, False), (2, 5, True), (4, 3, False),
                                          (6, 7, True)])
def test_engines_against_scipy_bspline(p, q, rational):
    interpolate = pytest.importorskip("scipy.interpolate")
    s = make_surface(p, q, rational, seed=p + q)
    u, v = parameters(s, np.random.default_rng(p * 3 + q))
    u, v = s._check(u, v)

    def basis(knots, degree, t, order):
        count = len(knots) - degree - 1
        spline = interpolate.BSpline(knots, np.eye(count), degree)
        return spline(t, nu=order) if order <= degree else np.zeros((len(t), count))

    nu = [basis(s.knots_u, s.degree_u, u, d) for d in range(3)]
    nv = [basis(s.knots_v, s.degree_v, v, d) for d in range(3)]
    _assert_matches(s, u, v, _quotients(s, nu, nv))
