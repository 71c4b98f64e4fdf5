# SPDX-License-Identifier: LGPL-2.1-or-later
"""The certified drop-cutter over trimmed faces (core/toolpath/faceset.py) against closed forms
and brute force."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from BSplineCAM.core import Surface
from BSplineCAM.core.faces import Face
from BSplineCAM.core.nurbs import NurbsSurface
from BSplineCAM.core.toolpath import to_moves
from BSplineCAM.core.toolpath.dropcutter import DropCutter, brute_force_heights
from BSplineCAM.core.toolpath.faceset import CERTIFY, FaceSet

ROOT = Path(__file__).resolve().parent.parent


def rectangle(surface) -> np.ndarray:
    (u0, u1), (v0, v1) = surface.domain
    return np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1], [u0, v0]])


def circle(cu: float, cv: float, r: float, n: int) -> np.ndarray:
    t = np.linspace(0.0, 2.0 * np.pi, n + 1)
    t[-1] = 0.0
    return np.column_stack([cu + r * np.cos(t), cv + r * np.sin(t)])


def plane(x0, x1, y0, y1, z) -> NurbsSurface:
    """Bilinear plane: u, v in [0, 1] map linearly onto [x0, x1] x [y0, y1] at height z."""
    poles = np.array([[[x0, y0, z], [x0, y1, z]], [[x1, y0, z], [x1, y1, z]]], float)
    return NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)


def gcode(toolpath, feed: float = 1000.0) -> str:
    lines = ["G21 G90"]
    for m in to_moves(toolpath):
        word = "G0" if m.kind == "rapid" else "G1"
        tail = "" if m.kind == "rapid" else f" F{feed:g}"
        lines.append(f"{word} X{m.x:.4f} Y{m.y:.4f} Z{m.z:.4f}{tail}")
    lines.append("M2")
    return "\n".join(lines) + "\n"


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


def cylinder_quarter(rho: float, length: float) -> NurbsSurface:
    """Exact quarter of a circular cylinder (axis along y at z = 0, radius rho), from 45 to
    135 degrees: a rational quadratic arc ("The NURBS Book" sec. 7.3) extruded along y."""
    c = math.sqrt(0.5)
    arc = [(rho * c, rho * c), (0.0, rho * 2 * c), (-rho * c, rho * c)]
    poles = np.array([[[x, y, z] for y in (0.0, length)] for x, z in arc])
    weights = np.array([[1.0, 1.0], [c, c], [1.0, 1.0]])
    return NurbsSurface(poles, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1, weights=weights)


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


def holed_plane(n: int = 1000):
    ns = plane(0.0, 40.0, 0.0, 40.0, 1.5)
    return Face(ns, rectangle(ns), holes=(circle(0.5, 0.5, 0.2, n),))


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


def two_faces():
    """A selected bicubic bump next to a higher check plane."""
    n = 7
    x = np.linspace(0.0, 24.0, n)
    y = np.linspace(0.0, 24.0, n)
    pts = np.zeros((n, n, 3))
    pts[..., 0], pts[..., 1] = np.meshgrid(x, y, indexing="ij")
    pts[..., 2] = 0.8 * np.exp(-((pts[..., 0] - 12) ** 2 + (pts[..., 1] - 12) ** 2) / 60.0)
    bump = NurbsSurface.from_surface(Surface(pts, knots="clamped"))
    sel = Face(bump, rectangle(bump), holes=(circle(0.5, 0.5, 0.12, 300),), index=1)
    check = plane(24.0, 32.0, 0.0, 24.0, 1.0)
    return [sel, Face(check, rectangle(check), index=2, selected=False)]


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
