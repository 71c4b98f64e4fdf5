# SPDX-License-Identifier: LGPL-2.1-or-later
"""The matrix evaluator against independent references: SciPy's B-splines and Cox–de Boor."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import CASE_STUDY, random_net
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.interpolate import BSpline, bisplev

from BSplineCAM import Surface
from BSplineCAM.core.errors import NetError, ParameterError
from BSplineCAM.core.geometry import matrix
from BSplineCAM.core.geometry.basis import (
    cox_de_boor,
    cox_de_boor_surface,
    knot_vector,
    unique_knots,
)

LAYOUTS = ["uniform", "clamped"]


# --- the paper's matrix --------------------------------------------------------------------
def test_mb_is_the_papers_matrix():
    expected = np.array([[-1, 3, -3, 1], [3, -6, 3, 0], [-3, 0, 3, 0], [1, 4, 1, 0]]) / 6
    np.testing.assert_array_equal(matrix.MB, expected)


def test_mb_derived_from_cox_de_boor():
    """Expanding the Cox–de Boor cubics of a uniform central span in [s^3, s^2, s, 1] gives MB."""
    knots = np.arange(-3.0, 5.0)  # t_i = i - (k - 1), appendix A (A.1), 8 knots, 4 functions
    s = np.linspace(0.05, 0.95, 9)
    values = cox_de_boor(knots, 3, s)  # central span [0, 1)
    fitted, *_ = np.linalg.lstsq(np.vander(s, 4), values, rcond=None)
    np.testing.assert_allclose(fitted, matrix.MB, atol=1e-13)


@pytest.mark.parametrize("count", [4, 5, 6, 7, 12])
def test_clamped_span_matrices_reproduce_cox_de_boor(count, rng):
    mats = matrix.span_matrices(count, "clamped")
    knots = knot_vector(count, "clamped")
    spans = count - 3
    for j, m in enumerate(mats):
        s = rng.random(20)
        expected = cox_de_boor(knots, 3, (j + s) / spans)[:, j : j + 4]
        np.testing.assert_allclose(np.vander(s, 4) @ m, expected, atol=1e-13)
    if count >= 10:  # the central spans of an open uniform vector are uniform: MB again
        np.testing.assert_allclose(mats[3], matrix.MB, atol=1e-13)


# --- Cox–de Boor against SciPy ----------------------------------------------------------------
@pytest.mark.parametrize("degree", [0, 1, 2, 3, 4, 5])
@pytest.mark.parametrize("derivative", [0, 1, 2])
def test_cox_de_boor_matches_scipy(degree, derivative, rng):
    count = degree + 6
    inner = np.sort(rng.random(count - degree - 1))
    knots = np.concatenate([np.zeros(degree + 1), inner, np.ones(degree + 1)])
    u = np.concatenate([rng.random(50), [0.0, 1.0]])
    ours = cox_de_boor(knots, degree, u, derivative)
    if derivative > degree:
        assert not ours.any()
        return
    for i in range(count):
        c = np.zeros(count)
        c[i] = 1
        spline = BSpline(knots, c, degree)
        ref = spline.derivative(derivative)(u) if derivative else spline(u)
        np.testing.assert_allclose(ours[:, i], ref, atol=1e-9 * max(1, np.abs(ref).max()))


# --- surfaces against SciPy FITPACK and Cox–de Boor -------------------------------------------
@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("du,dw", [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)])
def test_grid_matches_fitpack(layout, du, dw, rng):
    net = random_net(rng, 8, 11)
    surface = Surface(net, layout)
    u = np.linspace(0, 1, 23)
    w = np.concatenate([[0.0], np.sort(rng.random(15)), [1.0]])
    ours = surface.evaluate_grid(u, w, du, dw)
    ku, kw = surface.knot_vectors()
    for c in range(3):
        tck = (ku, kw, net[:, :, c].ravel(), 3, 3)
        ref = bisplev(u, w, tck, dx=du, dy=dw)
        scale = max(1.0, np.abs(ref).max())
        np.testing.assert_allclose(ours[:, :, c], ref, atol=1e-10 * scale)


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("du,dw", [(0, 0), (1, 0), (0, 1), (1, 1), (2, 0), (0, 2)])
def test_scattered_matches_grid(layout, du, dw, rng):
    surface = Surface(random_net(rng), layout)
    u, w = rng.random(300), rng.random(300)
    scattered = surface.evaluate(u, w, du, dw)
    diagonal = np.array([surface.evaluate_grid(a, b, du, dw)[0, 0] for a, b in zip(u, w)])
    np.testing.assert_allclose(scattered, diagonal, atol=1e-9)


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("du", [0, 1, 2])
@pytest.mark.parametrize("dw", [0, 1, 2])
def test_patch_form_matches_grid(layout, du, dw, rng):
    """The per-patch power-basis coefficients A_ij = M_i P_ij M_j^T reproduce the grid
    evaluator at random points, knots included, for every partial derivative up to 2."""
    net = random_net(rng, 8, 11)
    form = matrix.patch_form(net, layout)
    assert form.coef.shape == (5 * 8, 4, 12)
    u = np.concatenate([rng.random(200), [0.0, 1.0, 0.2, 0.4]])
    w = np.concatenate([rng.random(200), [1.0, 0.0, 0.125, 0.5]])
    ours = matrix.evaluate_patches(form, u, w, du, dw)
    grid = np.array([matrix.evaluate_grid(net, layout, [a], [b], du, dw)[0, 0]
                     for a, b in zip(u, w)])
    scale = max(1.0, np.abs(grid).max())
    np.testing.assert_allclose(ours, grid, atol=1e-10 * scale)
    # several orders in one pass agree with one at a time, and Surface uses the cached form
    many = matrix.evaluate_patch_orders(form, u, w, [(du, dw), (0, 0)])
    np.testing.assert_array_equal(many[0], ours)
    surface = Surface(net, layout)
    assert surface.patch_form is surface.patch_form
    np.testing.assert_array_equal(surface.evaluate(u, w, du, dw), ours)


def test_derivatives_in_one_pass_match_evaluate(rng):
    surface = Surface(random_net(rng), "clamped")
    u, w = rng.random(50), rng.random(50)
    d = surface.derivatives(u, w)
    for value, (du, dw) in zip((d.point, d.su, d.sw, d.suu, d.suw, d.sww),
                               ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))):
        np.testing.assert_array_equal(value, surface.evaluate(u, w, du, dw))


def test_scattered_chunks_agree(rng, monkeypatch):
    surface = Surface(random_net(rng), "clamped")
    u, w = rng.random(1000), rng.random(1000)
    whole = surface.evaluate(u, w)
    monkeypatch.setattr(matrix, "SCATTER_CHUNK", 37)
    np.testing.assert_array_equal(surface.evaluate(u, w), whole)


def test_clamped_interpolates_corners_uniform_does_not(rng):
    net = random_net(rng)
    clamped = Surface(net, "clamped")
    corners = clamped.evaluate([0, 0, 1, 1], [0, 1, 0, 1])
    np.testing.assert_allclose(corners, net[[0, 0, -1, -1], [0, -1, 0, -1]], atol=1e-12)
    uniform = Surface(net, "uniform")
    # the paper's form at u = w = 0: ([1 4 1 0]/6) P ([1 4 1 0]/6)^T over the first 4x4 block
    b = np.array([1, 4, 1, 0]) / 6
    expected = np.einsum("i,ijc,j->c", b, net[:4, :4], b)
    np.testing.assert_allclose(uniform.evaluate(0, 0), expected, atol=1e-12)
    assert np.linalg.norm(uniform.evaluate(0, 0) - net[0, 0]) > 1e-3


def test_curve_matches_scipy(rng):
    points = rng.normal(size=(9, 3))
    t = np.linspace(0, 1, 41)
    for layout in LAYOUTS:
        spline = BSpline(knot_vector(9, layout), points, 3)
        for d in (0, 1, 2):
            ref = spline.derivative(d)(t) if d else spline(t)
            np.testing.assert_allclose(matrix.evaluate_curve(points, layout, t, d), ref, atol=1e-9 * max(1, np.abs(ref).max()))


def test_unique_knots_and_multiplicities():
    values, mults = unique_knots(knot_vector(7, "clamped"))
    np.testing.assert_allclose(values, [0, 0.25, 0.5, 0.75, 1])
    assert mults.tolist() == [4, 1, 1, 1, 4]
    values, mults = unique_knots(knot_vector(5, "uniform"))
    assert len(values) == 9 and mults.tolist() == [1] * 9


# --- normals ---------------------------------------------------------------------------------
@pytest.mark.parametrize("layout", LAYOUTS)
def test_normals_are_unit_and_perpendicular(layout, rng):
    surface = Surface(random_net(rng), layout)
    u, w = rng.random(200), rng.random(200)
    n = surface.normals(u, w)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1, atol=1e-12)
    for d in ((1, 0), (0, 1)):
        tangent = surface.evaluate(u, w, *d)
        assert np.abs(np.einsum("mc,mc->m", n, tangent)).max() < 1e-9 * np.abs(tangent).max()
    # height field laid out along +x (rows) and +y (columns): normals point up
    assert (n[:, 2] > 0).all()
    grid_n = surface.normals(u[:5], w[:7], grid=True)
    np.testing.assert_allclose(grid_n[2, 3], surface.normals(u[2], w[3]), atol=1e-12)


def test_normals_on_degenerate_edge_are_finite():
    x, y = np.meshgrid(np.linspace(0, 30, 5), np.linspace(0, 30, 5), indexing="ij")
    net = np.stack([x, y, np.zeros_like(x)], -1)
    net[0, :] = net[0, 0]  # collapse the u = 0 edge to a point
    n = Surface(net, "clamped").normals(np.zeros(5), np.linspace(0, 1, 5))
    assert np.isfinite(n).all()
    np.testing.assert_allclose(np.abs(n[:, 2]), 1, atol=1e-6)


def test_grid_with_normals_shapes():
    surface = Surface.from_json(CASE_STUDY)
    points, normals = surface.grid_with_normals(31, 17)
    assert points.shape == normals.shape == (31, 17, 3)


def _cox_de_boor_grid_normals(net, layout, u, w):
    """Unit normals on the grid u x w from Cox–de Boor basis derivatives (independent)."""
    ku, kw = (knot_vector(n, layout) for n in net.shape[:2])
    bu, du = cox_de_boor(ku, 3, u), cox_de_boor(ku, 3, u, derivative=1)
    bw, dw = cox_de_boor(kw, 3, w), cox_de_boor(kw, 3, w, derivative=1)
    su = np.einsum("ai,ijc,bj->abc", du, net, bw)
    sw = np.einsum("ai,ijc,bj->abc", bu, net, dw)
    n = np.cross(su, sw)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _wild_net(rng):
    """Control points scattered at random: folds, near-vanishing normals, a badly conditioned
    product Su x Sw."""
    return rng.normal(scale=30.0, size=(7, 9, 3))


@pytest.mark.parametrize("layout", LAYOUTS)
@pytest.mark.parametrize("make", [random_net, _wild_net, lambda rng: Surface.from_json(
    CASE_STUDY).control_points], ids=["wavy", "wild", "case-study"])
def test_grid_normals_equal_cox_de_boor_and_the_tangent_path(layout, make, rng):
    """Grid normals (evaluated as one Bernstein polynomial per patch) against Cox–de Boor
    tangents crossed per point, and against the blocked tangent path, within 1e-12: on a
    regular grid and on unsorted parameters, clamped and uniform."""
    net = np.asarray(make(rng), dtype=float)
    surface = Surface(net, layout)
    for u, w in ((np.linspace(0, 1, 61), np.linspace(0, 1, 47)), (rng.random(23), rng.random(19))):
        fast = surface.normals(u, w, grid=True)
        np.testing.assert_allclose(fast, _cox_de_boor_grid_normals(net, layout, u, w), atol=1e-12)
        slow, degenerate = matrix.grid_normals(net, layout, u, w)
        assert not degenerate.any()
        np.testing.assert_allclose(fast, slow, atol=1e-12)
    points, normals = surface.grid_with_normals(31, 17)
    np.testing.assert_array_equal(normals, surface.normals(np.linspace(0, 1, 31),
                                                           np.linspace(0, 1, 17), grid=True))


@pytest.mark.parametrize("threads", [1, 2])
def test_large_grid_normals_in_threads_equal_the_tangent_path(threads, monkeypatch):
    """A grid large enough to be shared among threads gives the same normals."""
    monkeypatch.setattr(matrix, "GRID_THREADS", threads)
    surface = Surface.from_json(CASE_STUDY)
    u, w = np.linspace(0, 1, 540), np.linspace(0, 1, 500)
    assert len(u) * len(w) >= 2 * matrix.GRID_THREAD_POINTS  # enough for two threads
    slow, _ = matrix.grid_normals(surface.control_points, surface.knots, u, w)
    np.testing.assert_allclose(surface.normals(u, w, grid=True), slow, atol=1e-12)


def test_grid_normals_on_a_collapsed_edge_match_the_tangent_path():
    """A net with its u = 0 edge collapsed to a point: the zero normals there are flagged and
    replaced the same way as the blocked tangent path does, the rest agree within 1e-12."""
    x, y = np.meshgrid(np.linspace(0, 30, 6), np.linspace(0, 30, 5), indexing="ij")
    net = np.stack([x, y, 0.02 * (x - 15) ** 2 + 0.01 * y * x], -1)
    net[0, :] = net[0, 0]
    surface = Surface(net, "clamped")
    u, w = np.linspace(0, 1, 41), np.linspace(0, 1, 33)
    form = surface.patch_form
    fast, degenerate = matrix.grid_unit_normals(form, matrix.normal_form(form), u, w)
    slow, slow_degenerate = matrix.grid_normals(net, "clamped", u, w)
    np.testing.assert_array_equal(degenerate, slow_degenerate)
    assert degenerate[0].all() and not degenerate[1:].any()
    np.testing.assert_allclose(fast, slow, atol=1e-12)
    normals = surface.normals(u, w, grid=True)
    assert np.isfinite(normals).all()
    np.testing.assert_allclose(np.linalg.norm(normals, axis=-1), 1.0, atol=1e-12)


def _collapsed_corner_net():
    """A clamped net whose u = 0 and w = 0 edges are one point."""
    x, y = np.meshgrid(np.linspace(0, 30, 6), np.linspace(0, 30, 5), indexing="ij")
    net = np.stack([x, y, 0.02 * (x - 15) ** 2 + 0.01 * y * x], -1)
    net[0, :] = net[:, 0] = net[0, 0]
    return net


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("collapsed", ["corner", "point"])
def test_large_grid_normals_on_collapsed_nets_in_threads(threads, collapsed, monkeypatch):
    """Zero normals in every block of a grid shared among threads: two edges collapsed to one
    point (the normals along them vanish), or the whole net (all vanish, exactly).  They are
    flagged like the blocked tangent path flags them, without a floating-point warning in any
    thread, the rest agree with that path within 1e-12, and the surface's normals are unit."""
    monkeypatch.setattr(matrix, "GRID_THREADS", threads)
    net = _collapsed_corner_net() if collapsed == "corner" else np.full((6, 5, 3), 7.0)
    surface = Surface(net, "clamped")
    u, w = np.linspace(0, 1, 540), np.linspace(0, 1, 500)
    assert len(u) * len(w) >= 2 * matrix.GRID_THREAD_POINTS  # enough for two threads
    form = surface.patch_form
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fast, degenerate = matrix.grid_unit_normals(form, matrix.normal_form(form), u, w)
    slow, slow_degenerate = matrix.grid_normals(net, "clamped", u, w)
    np.testing.assert_array_equal(degenerate, slow_degenerate)
    expected = np.ones_like(degenerate)
    if collapsed == "corner":
        expected[1:, 1:] = False
    np.testing.assert_array_equal(degenerate, expected)
    np.testing.assert_allclose(fast, slow, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(surface.normals(u, w, grid=True), axis=-1), 1.0,
                               atol=1e-12)


@pytest.mark.parametrize("edge", ["u1", "w1"])
def test_normals_on_an_edge_collapsed_to_a_point_follow_the_inside(edge):
    """Where the u = 1 (or w = 1) edge of the net is one point, Su x Sw there is rounding
    noise (1e-14 of the longest, pointing anywhere, even down): those normals count as
    degenerate and come from just inside, on the grid and at scattered points, for the
    cubic Surface and the general NurbsSurface alike.  The reference is the normal 1e-4 in."""
    from BSplineCAM.core.geometry.nurbs import NurbsSurface

    x, y = np.meshgrid(np.linspace(0, 60, 6), np.linspace(0, 50, 5), indexing="ij")
    net = np.stack([x, y, 5 * np.sin(x / 20) + 3 * np.cos(y / 15)], -1)
    if edge == "u1":
        net[-1, :, :] = net[-1, 2, :]
    else:
        net[:, -1, :] = net[2, -1, :]
    surface = Surface(net, "clamped")
    t = np.linspace(0, 1, 151)
    one, inside = np.ones_like(t), np.full_like(t, 1 - 1e-4)
    u, w = (one, t) if edge == "u1" else (t, one)
    ui, wi = (inside, t) if edge == "u1" else (t, inside)
    reference = surface.normals(ui, wi)
    assert reference[:, 2].min() > 0.5  # the surface faces up everywhere near that edge
    grid = surface.normals(t, t, grid=True)
    on_edge = grid[-1] if edge == "u1" else grid[:, -1]
    np.testing.assert_allclose(on_edge, reference, atol=1e-3)
    np.testing.assert_allclose(surface.normals(u, w), reference, atol=1e-3)
    nurbs = NurbsSurface.from_surface(surface)
    np.testing.assert_allclose(nurbs.normals(u, w), reference, atol=1e-3)
    nurbs_grid = nurbs.normals(t, t, grid=True)
    np.testing.assert_allclose(nurbs_grid[-1] if edge == "u1" else nurbs_grid[:, -1], reference,
                               atol=1e-3)


# --- properties (hypothesis) ------------------------------------------------------------------
finite = st.floats(-1e3, 1e3, allow_nan=False, allow_infinity=False)
params = st.floats(0.0, 1.0, allow_nan=False)


@st.composite
def nets(draw):
    rows = draw(st.integers(4, 8))
    cols = draw(st.integers(4, 8))
    return draw(arrays(np.float64, (rows, cols, 3), elements=finite))


@settings(max_examples=60, deadline=None)
@given(st.integers(4, 12), st.sampled_from(LAYOUTS), st.lists(params, min_size=1, max_size=20))
def test_partition_of_unity(count, layout, ts):
    ts = np.array(ts)
    weights = matrix.basis_rows(ts, count, layout)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-12)
    assert (weights >= -1e-14).all()
    np.testing.assert_allclose(cox_de_boor(knot_vector(count, layout), 3, ts).sum(axis=1), 1.0, atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(nets(), st.sampled_from(LAYOUTS), params, params)
def test_matrix_form_equals_cox_de_boor(net, layout, u, w):
    s = Surface(net, layout)
    ku, kw = s.knot_vectors()
    ref = cox_de_boor_surface(net, ku, kw, [u], [w])[0]
    scale = max(1.0, np.abs(net).max())
    np.testing.assert_allclose(s.evaluate(u, w), ref, atol=1e-11 * scale)


@settings(max_examples=60, deadline=None)
@given(nets(), st.sampled_from(LAYOUTS), params, params,
       arrays(np.float64, (3, 3), elements=st.floats(-3, 3)), arrays(np.float64, 3, elements=finite))
def test_affine_invariance(net, layout, u, w, linear, shift):
    moved = net @ linear.T + shift
    lhs = Surface(moved, layout).evaluate(u, w)
    rhs = Surface(net, layout).evaluate(u, w) @ linear.T + shift
    scale = max(1.0, np.abs(moved).max(), np.abs(net).max() * 3)
    np.testing.assert_allclose(lhs, rhs, atol=1e-10 * scale)


@settings(max_examples=60, deadline=None)
@given(nets(), st.sampled_from(LAYOUTS), params, params)
def test_convex_hull(net, layout, u, w):
    """A point lies in the convex hull of the 4x4 control points of its patch (weights ≥ 0)."""
    s = Surface(net, layout)
    iu, wu = matrix.local_weights([u], s.shape[0], layout)
    iw, ww = matrix.local_weights([w], s.shape[1], layout)
    weights = np.outer(wu[0], ww[0])
    assert weights.min() >= -1e-14
    assert abs(weights.sum() - 1) < 1e-12
    block = net[iu[0] : iu[0] + 4, iw[0] : iw[0] + 4]
    point = s.evaluate(u, w)
    np.testing.assert_allclose(point, np.einsum("kl,klc->c", weights, block), atol=1e-9 * max(1, np.abs(net).max()))
    tol = 1e-9 * max(1, np.abs(net).max())
    assert (point >= block.reshape(-1, 3).min(0) - tol).all()
    assert (point <= block.reshape(-1, 3).max(0) + tol).all()


@settings(max_examples=60, deadline=None)
@given(nets(), st.sampled_from(LAYOUTS))
def test_normal_bounds_hold_on_every_patch(net, layout):
    """The per-patch bounds of |Su x Sw| that spare the grid normals their length check: on a
    7 x 7 sample of every patch the tangents' cross product (the blocked tangent path, not the
    normal polynomial) is no shorter than ``least`` and no longer than ``greatest``."""
    surface = Surface(net, layout)
    nform = matrix.normal_form(surface.patch_form)
    pu, pw = nform.spans
    local = np.linspace(0, 1, 7)
    u = np.concatenate([(i + local) / pu for i in range(pu)])
    w = np.concatenate([(j + local) / pw for j in range(pw)])
    su, sw = matrix.evaluate_patch_orders(surface.patch_form, *np.meshgrid(u, w, indexing="ij"),
                                          ((1, 0), (0, 1)))
    length = np.linalg.norm(np.cross(su, sw), axis=-1).reshape(pu, 7, pw, 7)
    tangent = 3.0 * max(pu, pw) * max(1.0, float(np.abs(net).max()))  # rounding's scale
    tol = 1e-12 * tangent * tangent
    assert (length.min(axis=(1, 3)) >= nform.least - tol).all()
    assert (length.max(axis=(1, 3)) <= nform.greatest + tol).all()


@pytest.mark.parametrize("threads", [1, 2])
def test_grid_normals_where_one_patch_turns_right_round(threads, monkeypatch):
    """A 4 x 4 net folded into a tube: the normal of its one patch turns through more than
    180 degrees, so its bounds certify nothing and every block is searched for short normals;
    none is degenerate, and they agree with the tangent path."""
    monkeypatch.setattr(matrix, "GRID_THREADS", threads)
    angle = np.linspace(0, 1.6 * np.pi, 4)
    x, y = np.meshgrid(20 * np.cos(angle), np.linspace(0, 30, 4), indexing="ij")
    z = np.meshgrid(20 * np.sin(angle), np.zeros(4), indexing="ij")[0]
    net = np.stack([x, y, z], -1)
    form = Surface(net, "clamped").patch_form
    nform = matrix.normal_form(form)
    assert not nform.least[0, 0] > 0  # the bound proves nothing here
    u, w = np.linspace(0, 1, 520), np.linspace(0, 1, 510)
    fast, degenerate = matrix.grid_unit_normals(form, nform, u, w)
    slow, slow_degenerate = matrix.grid_normals(net, "clamped", u, w)
    assert not degenerate.any() and not slow_degenerate.any()
    np.testing.assert_allclose(fast, slow, atol=1e-12)


# --- parameters ------------------------------------------------------------------------------
def test_parameters_outside_domain_are_rejected(rng):
    s = Surface(random_net(rng))
    with pytest.raises(ParameterError, match="parameter u"):
        s.evaluate(1.5, 0.2)
    with pytest.raises(ParameterError, match="parameter w"):
        s.evaluate(0.5, np.nan)
    with pytest.raises(ParameterError, match="at least 2"):
        s.grid(1, 5)


def test_unknown_layout_is_named(rng):
    with pytest.raises(NetError, match="unknown knot layout 'periodic'"):
        Surface(random_net(rng), "periodic")
