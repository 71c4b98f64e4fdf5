# SPDX-License-Identifier: LGPL-2.1-or-later
"""Helpers shared by the pytest modules: trimmed faces with closed forms and the G-code text of
a toolpath over them, faces of revolution, the ball and checks of the faces finishing tests,
and height-field nets with the ridge's closed form.

Not a test module (no ``TestBSplineCAM`` prefix, so pytest does not collect it) and free of
FreeCAD; the test modules import it as ``from bsplinecam_helpers import ...`` (pytest puts
tests/ on sys.path, conftest.py the repository).
"""

from __future__ import annotations

import math

import numpy as np

from BSplineCAM.core import Surface
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.toolpath import to_moves
from BSplineCAM.core.toolpath.faceset import FaceSet


# -- trimmed faces and the G-code text of a toolpath -------------------------------------------
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


def cylinder_quarter(rho: float, length: float) -> NurbsSurface:
    """Exact quarter of a circular cylinder (axis along y at z = 0, radius rho), from 45 to
    135 degrees: a rational quadratic arc ("The NURBS Book" sec. 7.3) extruded along y."""
    c = math.sqrt(0.5)
    arc = [(rho * c, rho * c), (0.0, rho * 2 * c), (-rho * c, rho * c)]
    poles = np.array([[[x, y, z] for y in (0.0, length)] for x, z in arc])
    weights = np.array([[1.0, 1.0], [c, c], [1.0, 1.0]])
    return NurbsSurface(poles, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1, weights=weights)


def holed_plane(n: int = 1000):
    ns = plane(0.0, 40.0, 0.0, 40.0, 1.5)
    return Face(ns, rectangle(ns), holes=(circle(0.5, 0.5, 0.2, n),))


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


# -- faces of revolution: a boss's fillet on a plate with a hole -------------------------------
def revolved_face(profile, weights=None, centre=(0.0, 0.0), index=1, source="Revolved"):
    """A face of revolution about the vertical axis through ``centre``: u the angle (a
    rational quadratic full circle, its seam along +x), v the profile, a Bezier curve of
    poles ``profile`` [(r, z), ...] and ``weights`` (degree len - 1)."""
    c = math.sqrt(0.5)
    square = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0)]
    wu = np.array([1, c, 1, c, 1, c, 1, c, 1])
    wv = np.ones(len(profile)) if weights is None else np.asarray(weights, dtype=float)
    poles = np.array([[[centre[0] + r * x, centre[1] + r * y, z] for r, z in profile]
                      for x, y in square], dtype=float)
    ku = [0, 0, 0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1, 1, 1]
    q = len(profile) - 1
    s = NurbsSurface(poles, ku, [0] * (q + 1) + [1] * (q + 1), 2, q,
                     weights=wu[:, None] * wv[None, :], name=f"Face{index}")
    loop = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    return Face(s, loop, index=index, source=source)


def fillet_ring(centre=(20.0, 20.0), wall=12.0, rho=3.0, base=10.0):
    """The concave fillet at the foot of a round boss (radius ``wall``) on a plate at ``base``:
    the quarter circle of radius ``rho`` from (wall + rho, base) to (wall, base + rho) about
    (wall + rho, base + rho), revolved about the boss's axis (rational quadratics both ways)."""
    profile = [(wall + rho, base), (wall, base), (wall, base + rho)]  # (r, z), corner middle
    return revolved_face(profile, [1.0, math.sqrt(0.5), 1.0], centre, 2, "Toroid")


def plate_with_hole(size=40.0, centre=(20.0, 20.0), hole=15.0, base=10.0):
    poles = np.array([[[0, 0, base], [0, size, base]], [[size, 0, base], [size, size, base]]],
                     dtype=float)
    s = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1, name="Face1")
    t = np.linspace(0.0, 2 * np.pi, 241)
    ring = np.column_stack([centre[0] + hole * np.cos(t), centre[1] + hole * np.sin(t)]) / size
    ring[-1] = ring[0]
    loop = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    return Face(s, loop, (ring,), index=1, source="Plane")


# -- the faces finishing tests: their ball, passes and tolerance, a dome, the drop check --------
#: Ball diameter D, pass spacing H and tolerance TOL of the faces finishing tests (mm); R is the
#: ball's radius, also the ball of the ridge's closed form (ridge_contact_slope).
D, H, TOL = 6.0, 0.05, 0.01
R = D / 2
#: Segments of the trim polygons of the holes (fewer than holed_plane's default: every query
#: near a hole tests the segments crossing its patch).
HOLE = 120


def dome_faces(amplitude: float = 8.0):
    """A selected bicubic dome (slopes up to about 41 degrees) with a hole at its top, next to
    a check plane standing higher than the dome's foot: 32 x 24 mm."""
    n = 9
    x = np.linspace(0.0, 24.0, n)
    pts = np.zeros((n, n, 3))
    pts[..., 0], pts[..., 1] = np.meshgrid(x, x, indexing="ij")
    pts[..., 2] = amplitude * np.exp(-((pts[..., 0] - 12) ** 2 + (pts[..., 1] - 12) ** 2) / 40.0)
    dome = NurbsSurface.from_surface(Surface(pts, knots="clamped"))
    sel = Face(dome, rectangle(dome), holes=(circle(0.5, 0.5, 0.12, HOLE),), index=1)
    check = plane(24.0, 32.0, 0.0, 24.0, 1.0)
    return [sel, Face(check, rectangle(check), index=2, selected=False)]


def step_part_queries(rows: int, radius: float = R):
    """examples/part.step's faces seen from above, and drop-cutter queries along ``rows``
    raster passes in x across their box, spaced as the raster on faces lays its base samples
    (sqrt(8 R 0.002) mm).  Needs OCP (the caller skips without it)."""
    from pathlib import Path

    from BSplineCAM.ocp import faces as ocp

    part = Path(__file__).resolve().parent.parent / "examples" / "part.step"
    faces = ocp.faces_from_shape(ocp.read_part(str(part)), "up")
    lo, hi = FaceSet(faces).bounds(selected_only=True)
    step = math.sqrt(8.0 * radius * 0.002)
    xs = np.arange(lo[0] - radius, hi[0] + radius, step)
    ys = np.linspace(lo[1] - 1.0, hi[1] + 1.0, rows)
    return faces, np.column_stack([np.tile(xs, len(ys)), np.repeat(ys, len(xs))])


def assert_above_drop(fs: FaceSet, tp):
    """Every cutter location at or above the certified drop-cutter height over all faces."""
    pts = np.concatenate(tp.passes + [lk for lk in tp.links if lk is not None])
    drop = fs.drop_ball(pts[:, :2], R)[0]
    ok = np.isfinite(drop)
    assert np.all(pts[ok, 2] >= drop[ok] - 1e-7)


# -- height fields as clamped nets, and the ridge ------------------------------------------------
#: Side of the square a bezier_net spans unless told (mm): the rest finishing tests' part.
NET_SIZE = 30.0


def bezier_net(fz, size: float = NET_SIZE) -> np.ndarray:
    """4x4 clamped net whose surface is exactly z = fz(x, y) (degree <= 2 in x, 1 in y):
    x, y linear in the parameters, z by the cubic Bernstein coefficients of a quadratic."""
    t = np.linspace(0.0, 1.0, 4)
    x, y = np.meshgrid(t * size, t * size, indexing="ij")
    net = np.stack([x, y, np.zeros_like(x)], axis=-1)
    for j in range(4):
        a, m, e = fz(0.0, y[0, j]), fz(0.5 * size, y[0, j]), fz(size, y[0, j])
        c = 2 * (a + e - 2 * m)
        b = e - a - c
        net[:, j, 2] = [a, a + b / 3, a + 2 * b / 3 + c / 3, a + b + c]
    return net


K_RIDGE = 0.04  # z = 14 - K (x - 20)^2: slope atan(2 K |x - 20|), 45 degrees at |x - 20| = 12.5


def ridge_z(x, y):
    return 14.0 - K_RIDGE * (x - 20.0) ** 2 + 0.0 * y


def ridge_contact_slope(x: np.ndarray) -> np.ndarray:
    """Closed form: slope (degrees) at the contact of a ball of radius R whose tip is above
    x on the ridge; the centre lies on the normal, R sin(alpha) further from the crest than
    the contact, so |x - 20| = d + R sin(atan(2 K d)), solved for d by bisection."""
    target = np.abs(x - 20.0)
    lo, hi = np.zeros_like(target), target.copy()
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        f = mid + R * np.sin(np.arctan(2 * K_RIDGE * mid)) - target
        lo, hi = np.where(f < 0, mid, lo), np.where(f < 0, hi, mid)
    return np.degrees(np.arctan(2 * K_RIDGE * 0.5 * (lo + hi)))


def cut_moves(moves, start_height: float, height, tool, grid, z_min: float, z_top: float):
    """Cut roughing ``moves`` one at a time out of the Z-map ``height`` (float32, changed in
    place) with core.simulation.simulate's swept envelope, the tool starting above the first
    move at ``start_height``; no material below ``z_min``, none met above ``z_top``.  Yields
    (index, move, start xyz, end xyz, (ix0, iy0) of the window, drop) for each move that reaches
    the stock, drop the window's height lowered by the move (mm)."""
    from BSplineCAM.core.simulation.simulate import _cut, _windows

    pos = np.array([moves[0].x, moves[0].y, start_height]) if moves else None
    for i, m in enumerate(moves):
        end = np.array([m.x, m.y, m.z])
        st, en = pos[None, :], end[None, :]
        win = _windows(st, en, tool.radius, grid)
        ix0, ix1, iy0, iy1 = (int(v) for v in win[0])
        if ix1 < ix0 or iy1 < iy0 or min(pos[2], end[2]) >= z_top:
            pos = end
            continue
        before = height[iy0:iy1 + 1, ix0:ix1 + 1].copy()
        _cut(height, np.array([0]), st, en, win, tool, grid, None)
        np.maximum(height, np.float32(z_min), out=height)  # no material below the stock
        yield i, m, pos, end, (ix0, iy0), before, before - height[iy0:iy1 + 1, ix0:ix1 + 1]
        pos = end


# -- engine agreement --------------------------------------------------------------------------
def numba_ready() -> bool:
    """Whether the numba engine runs in this process."""
    from BSplineCAM.core import kernels

    with kernels.forced("numba") as engine:
        return engine.name == "numba"


def under_both(fn):
    """(``fn()`` under the numpy engine, ``fn()`` under the numba engine)."""
    from BSplineCAM.core import kernels

    with kernels.forced("numpy"):
        a = fn()
    with kernels.forced("numba"):
        b = fn()
    return a, b


def same(a, b):
    """Equal arrays (NaN where NaN), or tuples or lists of them, to the last bit."""
    if isinstance(a, tuple | list):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            same(x, y)
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.dtype.kind == b.dtype.kind
    if a.dtype.kind == "f":
        assert np.array_equal(a, b, equal_nan=True), np.nanmax(np.abs(a - b))
    else:
        assert np.array_equal(a, b)


def close(a, b, atol=1e-12):
    """Arrays, or tuples or lists of them, equal to ``atol`` (infinities and NaN where they
    are)."""
    if isinstance(a, tuple | list):
        assert len(a) == len(b)
        for x, y in zip(a, b):
            close(x, y, atol)
        return
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    fa, fb = np.isfinite(a), np.isfinite(b)
    assert np.array_equal(fa, fb)
    assert np.array_equal(a[~fa], b[~fb], equal_nan=True)
    np.testing.assert_allclose(a[fa], b[fb], rtol=0, atol=atol)


def same_drops(first, second):
    """Two engines' ``(FaceSet.drop_ball answer, FaceSet.stats)``: the same counters, centre
    heights and (u, v) to 1e-12 mm, the same faces and gaps to the last bit."""
    (ra, sa), (rb, sb) = first, second
    assert sa == sb
    close(ra[0], rb[0])
    same(ra[1], rb[1])
    same(ra[4], rb[4])
    close(ra[2], rb[2])
    close(ra[3], rb[3])
