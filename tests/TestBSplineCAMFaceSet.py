# SPDX-License-Identifier: LGPL-2.1-or-later
"""The certified drop-cutter over trimmed faces (core/toolpath/faceset.py) against closed forms
and brute force."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from bsplinecam_helpers import circle, cylinder_quarter, holed_plane, plane, rectangle, two_faces

from BSplineCAM.core import Surface
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.toolpath.dropcutter import DropCutter, brute_force_heights
from BSplineCAM.core.toolpath.faceset import CERTIFY, FaceSet

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def case_study():
    s = Surface.from_json(ROOT / "examples" / "case-study.json")
    ns = NurbsSurface.from_surface(s)
    return s, ns


def test_single_face_matches_todays_dropcutter(case_study):
    s, ns = case_study
    fs = FaceSet([Face(ns, rectangle(ns))])
    rng = np.random.default_rng(3)
    xy = rng.uniform(0.0, 100.0, (400, 2))
    tip, face, u, v, on_sel = fs.drop_ball(xy, 3.0)
    old, _, _ = DropCutter(s, 3.0).heights(xy)
    assert np.all(face == 0) and np.all(on_sel)
    np.testing.assert_allclose(tip, old, atol=CERTIFY)
    brute = brute_force_heights(s, 3.0, xy[:40], samples=201, zoom=21)
    assert np.all(tip[:40] >= brute - 1e-9)
    assert np.all(old[:40] >= brute - 1e-9)
    # the contact is a real surface point giving that height
    p = ns.evaluate(u, v)
    c = p[:, 2] + np.sqrt(np.maximum(9.0 - ((p[:, :2] - xy) ** 2).sum(axis=1), 0.0))
    np.testing.assert_allclose(c - 3.0, tip, atol=1e-9)


def test_bounds_are_tight(case_study):
    _s, ns = case_study
    fs = FaceSet([Face(ns, rectangle(ns))])
    lo, hi = fs.bounds()
    g = ns.grid(401, 401).reshape(-1, 3)
    assert np.all(lo <= g.min(axis=0) + 1e-9) and np.all(hi >= g.max(axis=0) - 1e-9)
    np.testing.assert_allclose(lo, g.min(axis=0), atol=2e-3)
    np.testing.assert_allclose(hi, g.max(axis=0), atol=2e-3)


def spike_surface(height: float = 11.25):
    """Uniform cubic net, 0.1 mm pole spacing near a single raised pole: a spike about
    0.44 height tall and 0.4 mm wide at its base."""
    n = 81
    x = np.linspace(0.0, 8.0, n)
    pts = np.zeros((n, n, 3))
    pts[..., 0], pts[..., 1] = np.meshgrid(x, x, indexing="ij")
    pts[40, 40, 2] = height
    return Surface(pts, knots="uniform")


def test_adversarial_spike_found_by_the_bound():
    s = spike_surface()
    ns = NurbsSurface.from_surface(s)
    fs = FaceSet([Face(ns, rectangle(ns))])
    R = 3.0
    # the spike's apex: the surface's highest point, by a dense sample near pole (40, 40)
    u = np.linspace(0.45, 0.55, 401)
    local = ns.evaluate_grid(u, u).reshape(-1, 3)
    apex = local[np.argmax(local[:, 2])]
    assert 4.9 < apex[2] < 5.1
    rng = np.random.default_rng(5)
    xy = apex[:2] + rng.uniform(-2.5, 2.5, (300, 2))
    tip, face, _u, _v, _ = fs.drop_ball(xy, R)
    old, _, _ = DropCutter(s, R).heights(xy)
    # today's sampled seeds miss the spike for some of these queries
    assert np.max(tip - old) > 0.1
    # brute force: a dense sample near the spike, then three 10x zooms around each best
    # sample (at a maximum of f the sampling error is quadratic in the spacing)
    brute = np.empty(len(xy))
    step = u[1] - u[0]
    for k, q in enumerate(xy):
        cu, cv, du = 0.5, 0.5, 0.05
        best = -np.inf
        for _ in range(4):
            gu = np.clip(np.linspace(cu - du, cu + du, 41), 0, 1)
            gv = np.clip(np.linspace(cv - du, cv + du, 41), 0, 1)
            pts = ns.evaluate_grid(gu, gv)
            d2 = ((pts[..., :2] - q) ** 2).sum(axis=-1)
            f = np.where(d2 <= R * R, pts[..., 2] + np.sqrt(np.maximum(R * R - d2, 0)), -np.inf)
            i, j = np.unravel_index(np.argmax(f), f.shape)
            best = max(best, f[i, j])
            cu, cv, du = gu[i], gv[j], du / 10
        brute[k] = max(best - R, 0.0)
    assert step > 0
    assert np.all(tip >= brute - 1e-9)
    assert np.all(tip <= brute + CERTIFY + 1e-6)
    # analytic bound: a ball reaching the apex rests at least on it
    r = np.hypot(*(xy - apex[:2]).T)
    near = r < R
    assert np.all(tip[near] >= apex[2] + np.sqrt(R * R - r[near] ** 2) - R - 1e-9)


def test_rational_cylinder_closed_form():
    rho, R = 10.0, 3.0
    ns = cylinder_quarter(rho, 30.0)
    assert ns.rational
    fs = FaceSet([Face(ns, rectangle(ns))])
    rng = np.random.default_rng(7)
    x = rng.uniform(-0.65, 0.65, 200) * (rho + R)
    y = rng.uniform(R, 30.0 - R, 200)
    tip, face, _u, _v, _ = fs.drop_ball(np.column_stack([x, y]), R)
    exact = np.sqrt((rho + R) ** 2 - x ** 2) - R
    assert np.all(face == 0)
    assert np.all(tip <= exact + 1e-9)
    np.testing.assert_allclose(tip, exact, atol=CERTIFY)


def test_rational_drift_bounds_the_coordinate():
    """The bound behind the rational patches' trimmed extremes and drop-cutter bounds: on random
    rational Bezier patches (degrees 1-4, weights 0.2-5, sub-boxes by de Casteljau) a
    coordinate never exceeds its control values' affine part at (s, t) plus their largest
    residual plus :func:`_rational_drift`, sampled at 400 points each; and the drift does
    shrink on sub-patches (so the bound converges)."""
    from BSplineCAM.core.toolpath.faceset import (
        _bernstein,
        _bernstein_grid,
        _rational_drift,
        _sub_net,
    )

    rng = np.random.default_rng(11)
    for trial in range(40):
        p, q = rng.integers(1, 5, 2)
        P = rng.normal(size=(p + 1, q + 1)) * 10.0
        w = rng.uniform(0.2, 5.0, (p + 1, q + 1))
        net = np.stack([P * w, P * w, P * w, w])[None]  # homogeneous: (1, 4, p+1, q+1)
        lo = rng.uniform(0.0, 0.6, 2)
        hi = lo + rng.uniform(0.05, 0.4, 2)
        sub = _sub_net(net, lo[:1], hi[:1], lo[1:], hi[1:])[0]
        design = _bernstein_grid(int(p), int(q))
        pinv = np.linalg.pinv(design)
        ws = sub[3].ravel()
        vals = sub[0].ravel() / ws
        coef = vals @ pinv.T
        resid = float((vals - coef @ design.T).max())
        drift = float(_rational_drift(ws[None], coef[None])[0])
        st = rng.uniform(0.0, 1.0, (400, 2))
        bs, bt = _bernstein(int(p), st[:, 0]), _bernstein(int(q), st[:, 1])
        num = np.einsum("ni,ij,nj->n", bs, sub[0], bt)
        den = np.einsum("ni,ij,nj->n", bs, sub[3], bt)
        x = num / den
        bound = coef[0] + coef[1] * st[:, 0] + coef[2] * st[:, 1] + resid + drift
        assert np.all(x <= bound + 1e-9), (trial, float((x - bound).max()))
    # the drift of nested sub-patches shrinks like the square of their size
    half = []
    for size in (0.2, 0.1, 0.05):
        sub = _sub_net(net, np.array([0.3]), np.array([0.3 + size]), np.array([0.3]),
                       np.array([0.3 + size]))[0]
        ws = sub[3].ravel()
        coef = (sub[0].ravel() / ws) @ np.linalg.pinv(_bernstein_grid(int(p), int(q))).T
        half.append(float(_rational_drift(ws[None], coef[None])[0]))
    assert half[2] <= 0.35 * half[1] <= 0.35 ** 2 * half[0] * 1.2


def test_bounds_of_a_trimmed_rational_face_tied_along_a_trim_edge():
    """A quarter cylinder (rational) trimmed inside its domain: its largest x is reached all
    along the trim edge u = 0.02, a tie along a curve that the corners' bound converged to
    only linearly (a fillet of examples/part.step: 48 halvings, 1.6 s).  The box encloses a
    dense sample of the material and is within 2e-3 mm of it."""
    ns = cylinder_quarter(10.0, 30.0)
    outer = np.array([[0.02, 0.02], [0.98, 0.02], [0.98, 0.98], [0.02, 0.98], [0.02, 0.02]])
    face = Face(ns, outer, holes=(circle(0.5, 0.5, 0.2, 200),))
    fs = FaceSet([face])
    lo, hi = fs.bounds()
    uu, vv = np.meshgrid(np.linspace(0.02, 0.98, 481), np.linspace(0.02, 0.98, 481))
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    inside = np.hypot(uv[:, 0] - 0.5, uv[:, 1] - 0.5) >= 0.2
    g = ns.evaluate(uv[inside, 0], uv[inside, 1])
    assert np.all(lo <= g.min(axis=0) + 1e-9) and np.all(hi >= g.max(axis=0) - 1e-9)
    np.testing.assert_allclose(lo, g.min(axis=0), atol=2e-3)
    np.testing.assert_allclose(hi, g.max(axis=0), atol=2e-3)


def test_ball_rests_on_the_rim_of_a_hole():
    face = holed_plane()
    fs = FaceSet([face])
    R, a, z0 = 3.0, 8.0, 1.5
    a_in = a * math.cos(math.pi / 1000)  # the polygon's inscribed circle
    rng = np.random.default_rng(11)
    r_q = rng.uniform(a - R + 0.2, a - 0.1, 150)
    t = rng.uniform(0.0, 2 * np.pi, 150)
    xy = np.column_stack([20 + r_q * np.cos(t), 20 + r_q * np.sin(t)])
    tip, face_idx, _u, _v, _ = fs.drop_ball(xy, R)
    hi = z0 + np.sqrt(R * R - (a_in - r_q) ** 2) - R  # rim of the inscribed circle: lower
    lo = z0 + np.sqrt(R * R - (a - r_q) ** 2) - R  # rim of the true circle: higher bound
    assert np.all(face_idx == 0)
    assert np.all(tip >= np.minimum(lo, hi) - CERTIFY)
    assert np.all(tip <= np.maximum(lo, hi) + CERTIFY)
    # far from the rim the ball sits on the plane; in the middle of a wide hole on nothing
    far = np.array([[3.0, 3.0], [37.0, 5.0], [20.0, 5.0]])
    np.testing.assert_allclose(fs.drop_ball(far, R)[0], z0 - 0.0, atol=1e-12)
    assert np.isnan(fs.drop_ball(np.array([[20.0, 20.0]]), R)[0][0])


def test_height_probe_inside_and_in_holes(case_study):
    _s, ns = case_study
    face = Face(ns, rectangle(ns), holes=(circle(0.5, 0.5, 0.2, 400),))
    fs = FaceSet([face])
    rng = np.random.default_rng(13)
    uv = rng.uniform(0.02, 0.98, (300, 2))
    p = ns.evaluate(uv[:, 0], uv[:, 1])
    z, idx, u, v, found = fs.height(p[:, :2])
    in_hole = np.hypot(uv[:, 0] - 0.5, uv[:, 1] - 0.5) < 0.2
    assert not found[in_hole].any() and np.all(np.isnan(z[in_hole]))
    assert found[~in_hole].all()
    np.testing.assert_allclose(z[~in_hole], p[~in_hole, 2], atol=1e-7)


def test_check_face_is_never_gouged_and_never_cut():
    faces = two_faces()
    fs = FaceSet(faces)
    R = 3.0
    rng = np.random.default_rng(17)
    xy = np.column_stack([rng.uniform(15, 30, 300), rng.uniform(1, 23, 300)])
    tip, face, _u, _v, on_sel = fs.drop_ball(xy, R)
    only_check = FaceSet([faces[1]]).drop_ball(xy, R)[0]
    only_sel = FaceSet([faces[0]]).drop_ball(xy, R)[0]
    assert np.all(np.nan_to_num(tip, nan=-9) >= np.nan_to_num(only_check, nan=-9) - CERTIFY)
    assert np.all(np.nan_to_num(tip, nan=-9) >= np.nan_to_num(only_sel, nan=-9) - CERTIFY)
    assert np.all(on_sel == (face == 0))
    assert (face == 1).any() and (face == 0).any()


# --------------------------------------------------------------------------- tangent joints
# A rolling-ball fillet meeting a flat top tangentially (G1): along the shared edge the maximum
# of f ties between the two faces, the case the per-face certified regions are for.  The top is
# a larger surface trimmed at the edge (its side of the joint is a trim segment), the fillet's
# side is its domain's own side.

RHO, R_BALL, LENGTH = 10.0, 3.0, 8.0


def fillet_arc(rho: float = RHO, length: float = LENGTH) -> NurbsSurface:
    """Exact quarter cylinder (axis along y at x = z = 0, radius rho) from its top line
    (0, y, rho) down to (rho, y, 0): a rational quadratic arc extruded along y."""
    c = math.sqrt(0.5)
    arc = [(0.0, rho), (rho, rho), (rho, 0.0)]
    poles = np.array([[[x, y, z] for y in (0.0, length)] for x, z in arc])
    weights = np.array([[1.0, 1.0], [c, c], [1.0, 1.0]])
    return NurbsSurface(poles, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1, weights=weights)


def trimmed_top(surface: NurbsSurface, x_edge: float = 0.0, y0: float = 0.0,
                y1: float = LENGTH) -> Face:
    """The part x <= x_edge, y0 <= y <= y1 of a surface whose x grows linearly with u and y
    with v (a plane-like net): the trim rectangle in (u, v)."""
    (u0, u1), (v0, v1) = surface.domain
    ends = surface.evaluate(np.array([u0, u1, u0]), np.array([v0, v0, v1]))
    ue = u0 + (x_edge - ends[0, 0]) / (ends[1, 0] - ends[0, 0]) * (u1 - u0)
    va = v0 + (y0 - ends[0, 1]) / (ends[2, 1] - ends[0, 1]) * (v1 - v0)
    vb = v0 + (y1 - ends[0, 1]) / (ends[2, 1] - ends[0, 1]) * (v1 - v0)
    outer = np.array([[u0, va], [ue, va], [ue, vb], [u0, vb], [u0, va]])
    return Face(surface, outer, index=2)


def fillet_exact(x: np.ndarray) -> np.ndarray:
    """Closed-form tip height over the fillet and the flat top at z = RHO (x < 0)."""
    return np.where(x <= 0.0, RHO, np.sqrt((RHO + R_BALL) ** 2 - np.maximum(x, 0.0) ** 2)
                    - R_BALL)


def test_tangent_fillet_and_top_closed_form():
    fillet = fillet_arc()
    top = trimmed_top(plane(-6.0, 1.0, -1.0, LENGTH + 1.0, RHO))
    fs = FaceSet([Face(fillet, rectangle(fillet)), top])
    rng = np.random.default_rng(23)
    # a band across the joint, densest where the two faces tie (|x| small)
    x = np.concatenate([rng.uniform(-3.0, RHO + R_BALL - 1.0, 300),
                        rng.uniform(-0.05, 0.05, 300), np.linspace(-1e-3, 1e-3, 41)])
    y = rng.uniform(R_BALL, LENGTH - R_BALL, len(x))
    tip, face, u, v, _ = fs.drop_ball(np.column_stack([x, y]), R_BALL)
    exact = fillet_exact(x)
    assert np.all(tip <= exact + 1e-9)
    np.testing.assert_allclose(tip, exact, atol=CERTIFY)
    assert set(np.unique(face)) == {0, 1}
    assert fs.stats["uncertified"] == 0


def bumped_top(bump: float) -> NurbsSurface:
    """A flat top at z = RHO (uniform cubic net, poles 0.25 mm apart, x from -6 to 2) with one
    pole next to the joint (x = -0.5, y = 4) raised by ``bump``: a narrow hump on the top just
    before the fillet, lower than the ball's reach from the fillet side only by a little."""
    xs = np.linspace(-6.0, 2.0, 33)
    ys = np.linspace(-1.0, LENGTH + 1.0, 41)
    pts = np.zeros((len(xs), len(ys), 3))
    pts[..., 0], pts[..., 1] = np.meshgrid(xs, ys, indexing="ij")
    pts[..., 2] = RHO
    pts[22, 20, 2] += bump  # x = -0.5, y = 4
    return NurbsSurface.from_surface(Surface(pts, knots="uniform"))


def brute_top(face: Face, q: np.ndarray, R: float) -> float:
    """Largest f over a trimmed top's material (u up to its trim edge): a dense sample of the
    material, then three 10x zooms around each of its four best samples (the hump's top and
    the trim edge are separate local maxima)."""
    s = face.surface
    (u0, _u1), _ = s.domain
    ue = float(face.outer[1, 0])
    va, vb = float(face.outer[0, 1]), float(face.outer[2, 1])

    def f_grid(gu, gv):
        pts = s.evaluate_grid(gu, gv)
        d2 = ((pts[..., :2] - q) ** 2).sum(axis=-1)
        return np.where(d2 <= R * R, pts[..., 2] + np.sqrt(np.maximum(R * R - d2, 0)), -np.inf)

    gu, gv = np.linspace(u0, ue, 161), np.linspace(va, vb, 161)
    f = f_grid(gu, gv)
    best = float(f.max())
    for flat in np.argsort(f, axis=None)[-4:]:
        i, j = np.unravel_index(flat, f.shape)
        cu, cv, du, dv = gu[i], gv[j], 2 * (gu[1] - gu[0]), 2 * (gv[1] - gv[0])
        for _ in range(3):
            zu = np.clip(np.linspace(cu - du, cu + du, 41), u0, ue)
            zv = np.clip(np.linspace(cv - dv, cv + dv, 41), va, vb)
            fz = f_grid(zu, zv)
            k, m = np.unravel_index(np.argmax(fz), fz.shape)
            best = max(best, float(fz[k, m]))
            cu, cv, du, dv = zu[k], zv[m], du / 10, dv / 10
    return best


@pytest.mark.parametrize("bump", [0.0, 0.1, 0.3])
def test_hump_next_to_a_tangent_joint_is_kept(bump):
    """The per-face regions drop the top's sub-patches near the shared edge once the fillet
    holds the maximum; a hump on the top right there (a higher point than the top's edge)
    must still be found: against a brute-force sample of the top plus the fillet's closed
    form."""
    fillet = fillet_arc()
    top = trimmed_top(bumped_top(bump))
    fs = FaceSet([Face(fillet, rectangle(fillet)), top])
    rng = np.random.default_rng(29)
    x = np.concatenate([rng.uniform(-0.6, 1.5, 50), rng.uniform(-0.05, 0.05, 30)])
    y = 4.0 + rng.uniform(-0.6, 0.6, len(x))
    xy = np.column_stack([x, y])
    tip, _face, _u, _v, _ = fs.drop_ball(xy, R_BALL)
    fillet_f = np.where(x >= 0.0, np.sqrt((RHO + R_BALL) ** 2 - np.maximum(x, 0) ** 2),
                        RHO + np.sqrt(R_BALL ** 2 - np.minimum(x, 0) ** 2))
    ref = np.maximum(fillet_f, [brute_top(top, q, R_BALL) for q in xy]) - R_BALL
    # tip is f at a real surface point (never above the truth), the sample never above the
    # truth either and within 1e-6 of it; a missed hump would leave tip up to 0.13 mm low
    assert np.all(tip >= ref - CERTIFY - 1e-9)
    assert np.all(tip <= ref + 1e-6)
    if bump > 0.1:  # the hump holds the maximum for some of these queries
        assert np.any(ref > fillet_f - R_BALL + 1e-3)


def test_height_probe_on_near_vertical_fillet_matches_faces_height():
    """On examples/part.step the fillet along y = 60 turns vertical (y 59 to 60): the point probe
    finds it there, as the Z-map heights of verification (core/faces_height.py, seeded from a
    dense raster) do, instead of the bottom face below."""
    pytest.importorskip("OCP")
    from BSplineCAM.core.geometry.faces_height import FacesHeight
    from BSplineCAM.ocp import faces as ocp

    faces = ocp.faces_from_shape(ocp.read_part(ROOT / "examples" / "part.step"), "up",
                                 tolerance=0.01)
    fs = FaceSet(faces)
    xs, ys = np.meshgrid(np.linspace(0.6, 79.4, 120), np.linspace(58.6, 59.98, 24))
    x, y = xs.ravel(), ys.ravel()
    z, face, _, _, found = fs.height(np.column_stack([x, y]))
    ref = FacesHeight(faces, 0.05).points(x, y)
    assert found.all()
    np.testing.assert_array_equal(face, ref.face)
    np.testing.assert_allclose(z, ref.z, atol=1e-6)


def wavy_fillet() -> NurbsSurface:
    """fillet_arc with its straight direction raised to degree 5 (poles spread unevenly in y
    and weights varied along it): the hull of N's second derivatives along y is no longer zero
    and the net is rational in both directions, as on the STEP part's fillets (degree 8)."""
    c = math.sqrt(0.5)
    arc = [(0.0, RHO), (RHO, RHO), (RHO, 0.0)]
    ys = np.array([0.0, 1.0, 3.5, 4.0, 6.5, LENGTH])
    wy = np.array([1.0, 1.1, 0.9, 1.05, 0.95, 1.0])
    poles = np.array([[[x, y, z] for y in ys] for x, z in arc])
    weights = np.array([[w * wy_ for wy_ in wy] for w in (1.0, c, 1.0)])
    knots_v = [0.0] * 6 + [1.0] * 6
    return NurbsSurface(poles, [0, 0, 0, 1, 1, 1], knots_v, 2, 5, weights=weights)


@pytest.mark.parametrize("slope_deg", [10.0, 45.0, 70.0, 80.0, 86.0])
def test_region_certificate_holds_on_a_dense_sample(slope_deg):
    """The local certificate (FaceSet._face_regions) claims f <= f(x*) + excess on a box
    around any surface point x*; checked against f on a dense sample of that box, for balls
    resting on a fillet from gentle to nearly vertical (where the xy map turns singular and the
    bound per direction holds the region), at the contact and at points beside it (where the
    excess is not zero and depends on the concavity bound: one 30 times too strong fails)."""
    fillet = wavy_fillet()
    fs = FaceSet([Face(fillet, rectangle(fillet))])
    d = fs.data[0]
    a = math.radians(slope_deg)
    # the ball touching the arc (radius RHO about the y axis) at angle a from the top
    x = np.full(3, (RHO + R_BALL) * math.sin(a))
    q = np.column_stack([x, [2.2, 4.0, 5.7]])
    res = fs.centre_heights(q, R_BALL)
    assert np.all(res.gap == 0.0)
    exact = math.sqrt((RHO + R_BALL) ** 2 - x[0] ** 2)
    assert np.all((exact - CERTIFY - 1e-9 <= res.centre) & (res.centre <= exact + 1e-9))
    for du, dv in ((0.0, 0.0), (0.01, 0.0), (0.0, 0.02)):
        u, v = np.clip(res.u + du, 0.0, 1.0), np.clip(res.v + dv, 0.0, 1.0)
        p = fillet.evaluate(u, v)
        f0 = p[:, 2] + np.sqrt(R_BALL ** 2 - ((p[:, :2] - q) ** 2).sum(axis=1))
        found, box, excess = fs._face_regions(d, q, R_BALL, u, v, np.full(3, 1.0))
        assert found.all()
        for k in range(3):
            b = box[k]
            gu, gv = np.linspace(b[0], b[1], 121), np.linspace(b[2], b[3], 121)
            pts = fillet.evaluate_grid(gu, gv).reshape(-1, 3)
            d2 = ((pts[:, :2] - q[k]) ** 2).sum(axis=1)
            f = np.where(d2 <= R_BALL ** 2,
                         pts[:, 2] + np.sqrt(np.maximum(R_BALL ** 2 - d2, 0.0)), -np.inf)
            assert f.max() <= f0[k] + excess[k] + 1e-12


def test_slopes_of_contacts_on_a_curved_wall_match_the_heights():
    """A wall (an unselected vertical face) is met by the 3-D chords of its trimmed border
    (faceset._Walls), which leave the cylinder of examples/part.step's boss by up to the trim
    tolerance: the height's slope (envelope theorem, FaceQuery.slopes) must come from the chord
    point the height was measured at, not from the surface at the contact's (u, v) (0.008 off
    there, enough to split the chord checks along a link over the boss down to 1e-5 mm:
    25 000 drop-cutter queries for one 2.5 mm link)."""
    pytest.importorskip("OCP")
    from BSplineCAM.core.toolpath.faces_raster import FaceQuery
    from BSplineCAM.ocp import faces as ocp

    faces = ocp.faces_from_shape(ocp.read_part(ROOT / "examples" / "part.step"), "up",
                                 tolerance=0.002)
    fs = FaceSet(faces)
    wall = next(k for k, f in enumerate(faces) if f.name == "Face6")
    assert wall in fs.walls.owner  # met by its border
    query = FaceQuery(fs, 3.0)
    x = np.linspace(52.8, 55.1, 47)
    xy = np.column_stack([x, np.full_like(x, 23.2257)])
    h = 1e-5
    z, face, u, v, _ = query.heights(xy)
    assert np.all(face == wall)
    grad = query.slopes(xy, face, u, v)
    for axis in (0, 1):
        step = np.zeros(2)
        step[axis] = h
        zp = query.heights(xy + step)[0]
        zm = query.heights(xy - step)[0]
        np.testing.assert_allclose(grad[:, axis], (zp - zm) / (2 * h), atol=2e-4)
    # the contact the slope uses lies on the ball: its centre is R from it
    p = fs.contact_points(face, u, v)
    centre = np.column_stack([xy, z + 3.0])
    np.testing.assert_allclose(np.linalg.norm(p - centre, axis=1), 3.0, atol=1e-9)


def test_ball_on_a_trimmed_edge_next_to_its_rim_is_certified():
    """A tilted plate (z = 1 + 0.2 x) trimmed at x = 20 inside its domain (x from 0 to 30,
    x = 15 u + 15 u^2: a cubic in u with unevenly spaced poles, as a STEP part's top is), the
    ball's axis R - eps beyond that edge (eps from 1e-7 to 1e-2 mm): it rests on the edge,
    tip = z(20) + sqrt(R^2 - (R - eps)^2) - R.  There f's slope across the edge grows as
    R / sqrt(2 R eps), the sub-patches straddling the trim reach past it towards the ball,
    and the parametrisation's curvature, times that slope, defeats the local certificate:
    bounded by their box, they would stay open down to MAX_DEPTH (hundreds of uncertified
    pairs per query); bounded by the material's own distance, every height is certified."""
    R, x_e = 3.0, 20.0
    xs = np.array([0.0, 5.0, 15.0, 30.0])
    poles = np.array([[[x, y, 1.0 + 0.2 * x] for y in (0.0, 20.0)] for x in xs])
    ns = NurbsSurface(poles, [0, 0, 0, 0, 1, 1, 1, 1], [0, 0, 1, 1], 3, 1)
    ue = (math.sqrt(1.0 + 4.0 * x_e / 15.0) - 1.0) / 2.0  # 15 u + 15 u^2 = x_e
    outer = np.array([[0.0, 0.0], [ue, 0.0], [ue, 1.0], [0.0, 1.0], [0.0, 0.0]])
    fs = FaceSet([Face(ns, outer)])
    rng = np.random.default_rng(3)
    eps = 10.0 ** rng.uniform(-7.0, -2.0, 60)
    xy = np.column_stack([x_e + R - eps, rng.uniform(5.0, 15.0, 60)])
    tip, face, _u, _v, _ = fs.drop_ball(xy, R)
    exact = 1.0 + 0.2 * x_e + np.sqrt(R * R - (R - eps) ** 2) - R
    assert np.all(face == 0)
    assert fs.stats["uncertified"] == 0
    assert np.all(tip <= exact + 1e-9) and np.all(tip >= exact - CERTIFY)


def test_material_reach_bounds_a_dense_sample():
    """The rim bound (:func:`_material_reach`): on random rational Bezier patches (degrees
    1-4, weights 0.2-5) cut by a random trim line, no material point lies higher than its z
    bound or nearer a random query in xy than its distance bound (a dense sample of the
    material and of the trim edge), and on sub-patches the distance bound is within the
    square of their size of the sample's nearest point."""
    from BSplineCAM.core.toolpath.faceset import (
        _bernstein,
        _bernstein_grid,
        _material_reach,
        _sub_net,
    )

    rng = np.random.default_rng(23)
    gs = np.linspace(0.0, 1.0, 61)
    grid = np.column_stack([a.ravel() for a in np.meshgrid(gs, gs)])
    gaps = {}
    for trial in range(60):
        p, q = (int(v) for v in rng.integers(1, 5, 2))
        P = rng.normal(size=(3, p + 1, q + 1)) * 10.0
        w = rng.uniform(0.2, 5.0, (p + 1, q + 1)) if trial % 2 else np.ones((p + 1, q + 1))
        net = np.concatenate([P * w, w[None]])[None]
        size = [1.0, 0.25, 0.0625][trial % 3]
        lo = rng.uniform(0.0, 1.0 - size, 2)
        sub = _sub_net(net, lo[:1], lo[:1] + size, lo[1:], lo[1:] + size)
        flat = sub.reshape(1, 4, -1)
        PX, PY, PZ = (flat[:, k] / flat[:, 3] for k in range(3))
        CX, CY, CZ = PX.mean(axis=1), PY.mean(axis=1), PZ.mean(axis=1)
        design = _bernstein_grid(p, q)
        G = np.stack([PZ - CZ[:, None], PX - CX[:, None], PY - CY[:, None]])
        C = G @ np.linalg.pinv(design).T
        RS = G - C @ design.T
        # the material: the box's part where n . (s, t) <= c, a line through a random point
        ang = rng.uniform(0.0, 2 * np.pi)
        n = np.array([math.cos(ang), math.sin(ang)])
        c = float(n @ rng.uniform(0.2, 0.8, 2))
        t = np.linspace(-2.0, 2.0, 4001)
        line = np.array([c * n[0], c * n[1]]) + t[:, None] * np.array([-n[1], n[0]])
        edge = line[(line >= 0.0).all(axis=1) & (line <= 1.0).all(axis=1)]
        corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
        st = np.concatenate([corners, edge[:1], edge[-1:]])[None]
        ok = np.concatenate([corners @ n <= c, [True, True]])[None]
        pts = np.concatenate([grid[grid @ n <= c], edge])
        bs, bt = _bernstein(p, pts[:, 0]), _bernstein(q, pts[:, 1])
        xyzw = np.einsum("ni,kij,nj->nk", bs, sub[0], bt)
        xyz = xyzw[:, :3] / xyzw[:, 3:]
        qs = xyz[rng.integers(0, len(xyz), 20), :2] + rng.normal(size=(20, 2)) * 5.0
        node = np.zeros(20, int)
        z_top, r = _material_reach(np.repeat(st, 20, 0), np.repeat(ok, 20, 0), 1, node, qs,
                                   (CX, CY, CZ), C, RS,
                                   np.repeat(flat[:, 3], 20, 0) if trial % 2 else None)
        assert np.all(xyz[:, 2] <= z_top[0] + 1e-9), trial
        dist = np.hypot(xyz[None, :, 0] - qs[:, :1], xyz[None, :, 1] - qs[:, 1:]).min(axis=1)
        assert np.all(r <= dist + 1e-9), (trial, float((r - dist).max()))
        gaps.setdefault(size, []).append(float((dist - r).max()))
    # the distance bound tightens as the square of the sub-patch (the sample's own spacing,
    # 1/60 of the sub-patch, is the floor)
    assert np.median(gaps[0.0625]) < 0.05 * np.median(gaps[1.0])
