# SPDX-License-Identifier: LGPL-2.1-or-later
"""A certified ball drop-cutter over several trimmed NURBS faces (issue 11, item 3).

For a ball of radius R above q = (x, y), the lowest centre height that cuts no face is

    c(q) = max over face points p inside their trims with |p_xy - q| <= R of
           f(p) = p_z + sqrt(R^2 - |p_xy - q|^2)

(Chuang, Chen & Yau 2002; see :mod:`.dropcutter`).  Here c(q) is found by branch and bound over
the Bezier patches of every face ("The NURBS Book" A5.7 decomposition, :meth:`NurbsSurface.
bezier_patches`), split by de Casteljau's algorithm (A5.4-style halving of the homogeneous
control nets, so rational patches split exactly), and the returned height is within
``CERTIFY`` (1e-4 mm) of the true maximum *by a bound*, not by sample density:

* Upper bound of f over a sub-patch.  f is concave in the 3-D point p on the cylinder
  |p_xy - q| <= R (a linear term plus a hemisphere), so its tangent plane at any p0 lies above
  it: f(p) <= f(p0) + g . (p - p0), g = grad f(p0).  On the patch, g . (S(u, v) - p0) is a
  scalar Bezier patch with coefficients g . (P_k - p0) (a convex combination for rational
  patches, weights > 0); writing them as an affine function a(s, t) of the Greville abscissae
  plus a residual r_k, the bound is f(p0) + max over the patch's material of a + max r_k, and an
  affine function is largest at a vertex of the material: the corners of an untrimmed
  sub-patch, or, where a trim loop crosses it, the corners inside the trim and the points where
  the trim polyline's segments enter and leave the sub-patch (Liang-Barsky clipping).  With p0
  the control net's centroid the gap to the true maximum shrinks as the square of the
  sub-patch size.  It is combined (the smaller wins) with the box bound
  z_max + sqrt(R^2 - dist(q, box_xy)^2), which also prunes sub-patches out of reach.  Near
  the ball's rim f's slope across it grows as R / sqrt(R^2 - r^2) and both converge only
  linearly (the tangent plane is not used there, the box reaches past a trim towards the
  query): deep sub-patches there are also bounded by the material's own z and xy distance,
  from the affine part's values at the material's vertices and the residual
  (:func:`_material_reach`), which converge as the square of the sub-patch.
* Lower bound: f at actual surface points inside the trim (the corner control points of a
  Bezier patch lie on the surface; trim vertices are evaluated; on shallow sub-patches also the
  point at the control point nearest the query), so the answer never exceeds the true height.
* Local certificates, one per face (:meth:`FaceSet._face_regions`): around each face's best
  contact (Newton-polished, on a trim edge too) a box in (u, v) on which f cannot exceed the
  contact's value plus a proved excess, from the hemisphere's strong concavity and Taylor
  bounds on the hodographs; a contact on a domain side or a trim segment counts only the
  directions into the material (the polygon of the material in the box).  Sub-patches of that
  face inside the box are dropped once the bound is within ``CERTIFY`` of the query's best, and
  a sub-patch overlapping the box is split along the box's side.  So neither the face holding
  the maximum nor a tangent (G1) neighbour, whose own maximum lies on the shared edge nearly
  tied with it (a fillet and a top), is halved down to CERTIFY there.
* Level by level, every (query, sub-patch) pair whose upper bound exceeds its query's best lower
  bound by more than ``CERTIFY`` is halved along its longer side; the rest are dropped.  When
  none remain the best lower bound is certified.  Trim-edge contacts are the vertices on the
  trim polylines (exact edge contacts on the polyline, which is within the face's trim
  tolerance of the true edge).

Everything is vectorised over queries (chunks of ``QUERY_CHUNK``) and sub-patches.  The queries
of a pass meet the same sub-patches (the halving does not depend on the query), so a level's
pairs index a table of distinct sub-patches (:class:`_Items`): each is split once and its
query-free bound terms computed once, and the trim classification and material vertices of a
sub-patch are remembered across levels and calls (:class:`_RowCache`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import BSplineCAMError, ParameterError
from ..faces import Face
from ..numeric import clamp
from ..typing import FloatArray

#: Certified accuracy of the ball-centre height (mm).
CERTIFY = 1e-4
#: Queries processed together.
QUERY_CHUNK = 2048
#: Most halvings of a root patch; a pair still open then keeps its upper bound as its gap.
MAX_DEPTH = 48
#: A point this factor of R^2 away (squared) still touches the ball: a ball whose rim just
#: grazes a face edge (distance R to rounding) finds its contact (error below R * 1e-6 mm).
TOUCH = 1.0 + 1e-12
#: Levels after which the best contacts are polished by Newton's method (a better lower bound
#: early prunes more sub-patches).
POLISH_LEVELS = (2, 4, 6, 9)
#: Newton steps per polish.
POLISH_STEPS = 4
#: Local parameters of a patch's corners, in the order of ``_corner_index``.
CORNERS = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
#: Most open sub-patches per query and face at one level (more: the lowest bounds are dropped
#: and reported in the gap, so a degenerate query cannot take unbounded time).
MAX_OPEN = 128
#: A query crowded (more than MAX_OPEN open sub-patches of a face) at this many levels is
#: given up: its open sub-patches' bounds go to its gap.  A ball in a fillet of its own
#: radius (its maximum tied along the fillet's arc) or grazing a wall's edge with its rim
#: kept 128 sub-patches open down to MAX_DEPTH: 12 000 pairs a query instead of about 50.
MAX_CROWDED = 6
#: Trim segments remembered per straddling sub-patch; with more, all of the face's are tested.
MAX_SEGMENTS = 12
#: Half-widths (fractions of the Bezier patch, largest first) of the boxes around a contact
#: tried by the local certificate (:meth:`FaceSet._face_regions`).
REGION_SIZES = (0.5, 0.25, 0.125, 0.0625, 0.03125)
#: After the last of POLISH_LEVELS, every this many levels the faces' contacts are polished
#: again and their regions sought anew (a contact found late still gets its certificate).
REGION_EVERY = 3
#: Only a face whose best contact lies within this of the query's best (mm) seeks a region:
#: a lower face's sub-patches are dropped by their bounds alone.
REGION_TIE = 0.01
#: A region's side splits a sub-patch only this far (fraction) from the sub-patch's sides.
CUT_MARGIN = 0.02
#: Sub-patch trim classifications (and vertices) remembered per face (see :class:`_RowCache`).
CLASSIFY_CACHE = 50_000
#: A sub-patch at least RIM_DEPTH halvings deep whose net's box lies farther than this
#: fraction of R from the query (in xy) is bounded by its material's own distance as well
#: (:func:`_material_reach`; shallower ones are rarely kept open by the rim, and the bound
#: costs about as much as the rest of theirs).
RIM_FRACTION = 0.9
RIM_DEPTH = 14
#: Margin (mm) taken off that distance for rounding.
RIM_ROUNDING_MM = 1e-11
#: Sub-patches this shallow also offer the surface point below their control point nearest
#: the query as a lower bound (see :meth:`FaceSet._bounds`).
SEED_DEPTH = 3
#: The point probe (:meth:`FaceSet.height`): samples per side of each Bezier patch, the
#: nearest of them in xy that start Newton's method, and its most steps.
HEIGHT_GRID = 9
HEIGHT_SEEDS = 4
HEIGHT_STEPS = 60


def _bernstein_grid(p: int, q: int) -> FloatArray:
    """Design matrix [1, i/p, j/q] of the (p+1)(q+1) Greville abscissae of a Bezier patch."""
    s, t = np.meshgrid(np.arange(p + 1) / p, np.arange(q + 1) / q, indexing="ij")
    return np.column_stack([np.ones(s.size), s.ravel(), t.ravel()])


def _bernstein(p: int, t: FloatArray) -> FloatArray:
    """Bernstein polynomials of degree p at t (n,): (n, p+1)."""
    i = np.arange(p + 1)
    c = np.array([math.comb(p, k) for k in i], float)
    return c * t[:, None] ** i * (1.0 - t[:, None]) ** (p - i)


def _corner_index(p: int, q: int) -> np.ndarray:
    """Flat indices of the corner control points (0,0), (p,0), (0,q), (p,q) of a (p+1)(q+1) net."""
    return np.array([0, p * (q + 1), q, p * (q + 1) + q])


def _split_into(work: FloatArray, axis: int, left: FloatArray, right: FloatArray) -> None:
    """de Casteljau halving at 1/2 of nets ``work`` (n, d, p+1, q+1; overwritten) along
    ``axis`` (2: u, 3: v), written into ``left`` and ``right`` ("The NURBS Book" A1.5)."""
    w = np.moveaxis(work, axis, 0)
    lv = np.moveaxis(left, axis, 0)
    rv = np.moveaxis(right, axis, 0)
    k = w.shape[0]
    lv[0] = w[0]
    rv[k - 1] = w[k - 1]
    for r in range(1, k):
        w[: k - r] += w[1 : k - r + 1]
        w[: k - r] *= 0.5
        lv[r] = w[0]
        rv[k - 1 - r] = w[k - 1 - r]


def _split_at(net: FloatArray, axis: int, t: FloatArray, keep_left: bool) -> FloatArray:
    """One side of de Casteljau's split of nets (n, d, p+1, q+1) at per-net parameters t (n,)
    along ``axis`` (2: u, 3: v) ("The NURBS Book" A1.5)."""
    w = np.moveaxis(net, axis, 0).copy()
    out = np.empty_like(w)
    k = w.shape[0]
    tt = t.reshape((1, -1) + (1,) * (w.ndim - 2))
    if keep_left:
        out[0] = w[0]
    else:
        out[k - 1] = w[k - 1]
    for r in range(1, k):
        w[: k - r] += tt[0] * (w[1 : k - r + 1] - w[: k - r])
        if keep_left:
            out[r] = w[0]
        else:
            out[k - 1 - r] = w[k - 1 - r]
    return np.moveaxis(out, 0, axis)


def _sub_net(net: FloatArray, s0: FloatArray, s1: FloatArray, t0: FloatArray,
             t1: FloatArray) -> FloatArray:
    """Nets of the sub-boxes [s0, s1] x [t0, t1] (local parameters in [0, 1], s0 < s1, t0 < t1)
    of Bezier nets (n, d, p+1, q+1)."""
    out = _split_at(net, 2, s1, True)
    out = _split_at(out, 2, s0 / s1, False)
    out = _split_at(out, 3, t1, True)
    return _split_at(out, 3, t0 / t1, False)


def _quadratic_bound(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """Largest eigenvalue of [[a, b], [b, c]]: d^T H d <= it * |d|^2 whenever H's diagonal is
    at most (a, c) and its off-diagonal at most b in magnitude."""
    return 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)


def _second_differences(net: FloatArray, p: int, q: int) -> tuple:
    """Bezier coefficients of the second partial derivatives (ss, st, tt) of scalar nets
    (..., p+1, q+1) on the unit box (hodographs; zeros where the degree is 1)."""
    z = np.zeros(net.shape[:-2] + (1, 1))
    ss = (p * (p - 1) * (net[..., 2:, :] - 2 * net[..., 1:-1, :] + net[..., :-2, :])
          if p >= 2 else z)
    tt = (q * (q - 1) * (net[..., :, 2:] - 2 * net[..., :, 1:-1] + net[..., :, :-2])
          if q >= 2 else z)
    st = p * q * (net[..., 1:, 1:] - net[..., :-1, 1:] - net[..., 1:, :-1] + net[..., :-1, :-1])
    return ss, st, tt


def _rational_drift(w: FloatArray, coef: FloatArray) -> FloatArray:
    """Bound on how far a rational patch's coordinate can exceed its control values' affine
    part a(s, t) = c0 + c1 s + c2 t taken at (s, t) (n,), from the weights w (n, K) and coef
    (n, 3).  The coordinate is sum lam_k x_k with lam_k = w_k B_k / sum w_j B_j, so its affine
    part is a at g = sum lam_k g_k (g_k the Greville abscissae, in the unit box), not at
    (s, t) = sum B_k g_k: |g - (s, t)| <= sum |lam_k - B_k| |g_k - (s, t)| <= sqrt(2) eps with
    eps = (w_max - w_min) / w_min (|lam_k - B_k| <= B_k eps), so the coordinate is at most
    a(s, t) + |(c1, c2)| sqrt(2) eps + the residual.  Subdivision evens the weights out, so
    the drift shrinks as the square of the sub-patch (a polynomial patch has none)."""
    wmin = w.min(axis=1)
    eps = (w.max(axis=1) - wmin) / wmin
    return math.sqrt(2.0) * eps * np.hypot(coef[:, 1], coef[:, 2])


def _material_reach(st: FloatArray, ok: np.ndarray, k: int, node: np.ndarray, q: FloatArray,
                    centroid: tuple, C: FloatArray, RS: FloatArray,
                    w: FloatArray | None) -> tuple[FloatArray, FloatArray]:
    """Upper bound of z and lower bound of the xy distance from q (m, 2) over the material
    of sub-patches ``node`` (m,) whose material polygon has its vertices among ``st``
    (m, 4 + 2k, 2), local (s, t), where ``ok`` (m, 4 + 2k): the corners, then the first and
    the second ends of k clipped trim segments (as :meth:`_FaceData.vertices`).

    Each coordinate is its control values' affine part a(s, t) (``C``, about the net's
    ``centroid``) plus at most its largest residual (``RS``; for a rational patch plus the
    drift of :func:`_rational_drift`, from the weights ``w``), and an affine map takes the
    polygon into the hull of its vertices' images.  So z is at most the largest a_z at a
    vertex plus its residual, and the xy distance at least the hull's distance from q, less
    the xy residual: the hull lies beyond the line of any unit normal nu at min_v nu . (a(v)
    - q), tried along the images of the box's sides and of the trim segments (the material's
    edges) and towards the nearest vertex.  Both converge as the square of the sub-patch,
    where the box of the net converges linearly, and near the ball's rim f's slope across it
    grows as R / sqrt(R^2 - r^2)."""
    cx, cy, cz = (c[node] for c in centroid)
    s_, t_ = st[..., 0], st[..., 1]
    cX, cY, cZ = C[1, node], C[2, node], C[0, node]
    ax = (cx + cX[:, 0])[:, None] + cX[:, 1:2] * s_ + cX[:, 2:3] * t_ - q[:, :1]
    ay = (cy + cY[:, 0])[:, None] + cY[:, 1:2] * s_ + cY[:, 2:3] * t_ - q[:, 1:]
    az = (cz + cZ[:, 0])[:, None] + cZ[:, 1:2] * s_ + cZ[:, 2:3] * t_
    rx, ry, rz = (np.abs(RS[j, node]).max(axis=1) for j in (1, 2, 0))
    if w is not None:
        rx = rx + _rational_drift(w, cX)
        ry = ry + _rational_drift(w, cY)
        rz = rz + _rational_drift(w, cZ)
    z_top = np.where(ok, az, -np.inf).max(axis=1) + rz
    # candidate normals (m, D): the images of the box's sides (s and t), of the trim
    # segments, and the direction of the nearest vertex
    tx = [cX[:, 1], cX[:, 2]]
    ty = [cY[:, 1], cY[:, 2]]
    if k:
        ds = st[:, 4 + k:, 0] - st[:, 4:4 + k, 0]
        dt = st[:, 4 + k:, 1] - st[:, 4:4 + k, 1]
        tx.append(cX[:, 1:2] * ds + cX[:, 2:3] * dt)
        ty.append(cY[:, 1:2] * ds + cY[:, 2:3] * dt)
    dist2 = np.where(ok, ax * ax + ay * ay, np.inf)
    j = np.argmin(dist2, axis=1)
    rows = np.arange(len(node))
    nx = np.column_stack(tuple(-v for v in ty) + (ax[rows, j],))
    ny = np.column_stack(tuple(tx) + (ay[rows, j],))
    length = np.hypot(nx, ny)
    usable = length > 0
    nx = nx / np.where(usable, length, 1.0)
    ny = ny / np.where(usable, length, 1.0)
    gap = np.zeros(len(node))
    for c in range(nx.shape[1]):
        proj = nx[:, c:c + 1] * ax + ny[:, c:c + 1] * ay  # (m, V)
        lo = np.where(ok, proj, np.inf).min(axis=1)
        hi = np.where(ok, proj, -np.inf).max(axis=1)
        gap = np.maximum(gap, np.where(usable[:, c], np.maximum(lo, -hi), 0.0))
    # less the residual, and a margin for rounding (coordinates of order 1e2 mm)
    r = np.maximum(gap - np.hypot(rx, ry) - RIM_ROUNDING_MM, 0.0)
    return z_top, r


def _clip(seg: FloatArray, box: FloatArray) -> tuple[np.ndarray, FloatArray, FloatArray]:
    """Liang-Barsky clipping of segments (n, K, 4) (u0, v0, u1, v1) by boxes (n, 4)
    (u0, u1, v0, v1): hit mask (n, K) and the clipped end points (n, K, 2) each."""
    a = seg[..., :2]
    d = seg[..., 2:] - a
    t0 = np.zeros(seg.shape[:2])
    t1 = np.ones(seg.shape[:2])
    hit = np.isfinite(seg[..., 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        for c, lo, hi in ((0, box[:, 0], box[:, 1]), (1, box[:, 2], box[:, 3])):
            dc = d[..., c]
            ac = a[..., c]
            flat = dc == 0
            hit &= ~(flat & ((ac < lo[:, None]) | (ac > hi[:, None])))
            ta = (lo[:, None] - ac) / dc
            tb = (hi[:, None] - ac) / dc
            tlo = np.where(flat, -np.inf, np.minimum(ta, tb))
            thi = np.where(flat, np.inf, np.maximum(ta, tb))
            t0 = np.maximum(t0, tlo)
            t1 = np.minimum(t1, thi)
    hit &= t0 <= t1
    return hit, a + t0[..., None] * d, a + t1[..., None] * d


class _Bands:
    """Point-in-trim test of :func:`faces.inside` (even-odd, pnpoly's half-open crossing rule,
    so the same answer) with the trim segments filed by horizontal bands of v: a point meets
    only the segments of its band, which holds every segment that can straddle its v."""

    def __init__(self, edges: FloatArray, bands: int = 256):
        keep = edges[:, 1] != edges[:, 3]  # horizontal edges never straddle the ray
        e = edges[keep]
        lo = np.minimum(e[:, 1], e[:, 3])
        hi = np.maximum(e[:, 1], e[:, 3])
        self.v0 = float(lo.min()) if len(e) else 0.0
        span = float(hi.max()) - self.v0 if len(e) else 1.0
        self.n = bands
        self.h = span / bands if span > 0 else 1.0
        first = self._band(lo)
        last = self._band(hi)
        rows = [[] for _ in range(bands)]
        for k, (f, g) in enumerate(zip(first, last)):
            for b in range(f, g + 1):
                rows[b].append(k)
        width = max(1, max(len(r) for r in rows))
        table = np.full((bands, width, 4), np.nan)
        for b, r in enumerate(rows):
            table[b, : len(r)] = e[r]
        self.table = table

    def _band(self, v: FloatArray) -> np.ndarray:
        return clamp(np.floor((v - self.v0) / self.h), 0, self.n - 1).astype(np.intp)

    def __call__(self, u: FloatArray, v: FloatArray) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        shape = np.broadcast(u, v).shape
        pu, pv = (np.broadcast_to(a, shape).ravel() for a in (u, v))
        seg = self.table[self._band(pv)]  # (m, width, 4); NaN rows never straddle
        u0, v0, u1, v1 = seg[..., 0], seg[..., 1], seg[..., 2], seg[..., 3]
        qv = pv[:, None]
        straddle = (v0 > qv) != (v1 > qv)
        with np.errstate(invalid="ignore", divide="ignore"):
            cross = u0 + (qv - v0) * ((u1 - u0) / (v1 - v0))
        hits = straddle & (pu[:, None] < cross)
        return ((np.count_nonzero(hits, axis=1) % 2) == 1).reshape(shape)


def _vertical(s) -> bool:
    """Whether the surface is ruled by vertical lines: along one parameter direction every
    row of poles shares its xy (and its weight), so each (u or v) iso-line is a vertical
    segment: a wall, a vertical cylinder, any extrusion along Z."""
    P = s.poles
    W = s.weights if s.weights is not None else np.ones(P.shape[:2])
    size = float(np.ptp(P.reshape(-1, 3), axis=0).max()) or 1.0
    for axis in (0, 1):
        dev = np.abs(P[..., :2] - np.take(P[..., :2], [0], axis=axis)).max()
        wdev = np.abs(W - np.take(W, [0], axis=axis)).max()
        if dev <= 1e-12 * size and wdev <= 1e-12 * float(W.max()) and P.shape[axis] > 1:
            return True
    return False


class _Walls:
    """Vertical check faces by their borders.

    On a face ruled by vertical lines, f = p_z + sqrt(R^2 - |p_xy - q|^2) grows with p_z along
    each ruling (xy fixed), so its maximum over the material lies where a ruling leaves it: on
    the trim loops.  Each loop segment maps to a 3-D chord of the border (exact for planar
    walls, within the trim tolerance on curved ones, as everywhere else trims are met), and
    along a chord f(t) is concave (f is concave in p, p affine in t): its maximum over the
    reachable part of [0, 1] is the stationary point of f' = 0 in closed form, clipped.  So a
    wall costs a few array operations per segment instead of a branch and bound whose best
    contacts tie with the neighbouring face's along their shared edge."""

    def __init__(self, faces: Sequence[Face], index: Sequence[int]):
        segs, owner, uv = [], [], []
        self.boxes = []
        for f, k in zip(faces, index):
            e = f._edges
            a = f.surface.evaluate(e[:, 0], e[:, 1])
            b = f.surface.evaluate(e[:, 2], e[:, 3])
            segs.append(np.stack([a, b], axis=1))
            owner.append(np.full(len(e), k))
            uv.append(e)
            pts = np.concatenate([a, b])
            self.boxes.append((pts.min(axis=0), pts.max(axis=0)))
        self.seg = np.concatenate(segs) if segs else np.zeros((0, 2, 3))
        self.owner = np.concatenate(owner) if owner else np.zeros(0, int)
        self.uv = np.concatenate(uv) if uv else np.zeros((0, 4))
        self.lo = self.seg[:, :, :2].min(axis=1)
        self.hi = self.seg[:, :, :2].max(axis=1)

    def drop(self, q: FloatArray, R: float):
        """(best centre height, face, u, v) over the walls' borders for queries q (m, 2)."""
        m = len(q)
        best = np.full(m, -np.inf)
        face = np.full(m, -1)
        bu = np.zeros(m)
        bv = np.zeros(m)
        if len(self.seg) == 0:
            return best, face, bu, bv
        dx = np.maximum(np.maximum(self.lo[None, :, 0] - q[:, :1], q[:, :1] - self.hi[None, :, 0]), 0)
        dy = np.maximum(np.maximum(self.lo[None, :, 1] - q[:, 1:], q[:, 1:] - self.hi[None, :, 1]), 0)
        qi, si = np.nonzero(dx * dx + dy * dy <= R * R)
        if len(qi) == 0:
            return best, face, bu, bv
        a = self.seg[si, 0]
        d = self.seg[si, 1] - a
        e = a[:, :2] - q[qi]
        L = (d[:, :2] ** 2).sum(axis=1)
        ed = (e * d[:, :2]).sum(axis=1)
        ee = (e * e).sum(axis=1)
        R2 = R * R
        # reachable t: L t^2 + 2 ed t + ee - R^2 <= 0
        flat = L <= 1e-300
        Ls = np.where(flat, 1.0, L)
        disc = ed * ed - L * (ee - R2)
        root = np.sqrt(np.maximum(disc, 0.0))
        t1 = np.where(flat, 0.0, (-ed - root) / Ls)
        t2 = np.where(flat, 1.0, (-ed + root) / Ls)
        ok = np.where(flat, ee <= R2, disc >= 0)
        lo_t = np.maximum(t1, 0.0)
        hi_t = np.minimum(t2, 1.0)
        ok &= lo_t <= hi_t
        # stationary point of f(t): tau = t + ed / L, L tau^2 (L + dz^2) = dz^2 (R^2 - e_perp^2)
        dz = d[:, 2]
        perp = np.maximum(ee - ed * ed / Ls, 0.0)
        tau = np.sign(dz) * np.abs(dz) * np.sqrt(np.maximum(R2 - perp, 0.0)
                                                 / (Ls * (Ls + dz * dz)))
        t = np.where(flat, np.where(dz >= 0, hi_t, lo_t), tau - ed / Ls)
        t = clamp(t, lo_t, hi_t)

        def f_at(tt):
            p = a + tt[:, None] * d
            r2 = ((p[:, :2] - q[qi]) ** 2).sum(axis=1)
            return np.where(ok & (r2 <= R2 * TOUCH), p[:, 2] + np.sqrt(np.maximum(R2 - r2, 0)),
                            -np.inf)

        # the clipped stationary point is the maximum of the concave f; the ends of the
        # reachable interval are checked too, against rounding
        cands = [t, lo_t, hi_t]
        vals = np.stack([f_at(c) for c in cands])
        k = np.argmax(vals, axis=0)
        fv = vals[k, np.arange(len(qi))]
        tb = np.choose(k, cands)
        order = np.argsort(fv, kind="stable")  # later (larger) assignments win
        qi, si, fv, tb = qi[order], si[order], fv[order], tb[order]
        good = np.isfinite(fv)
        qi, si, fv, tb = qi[good], si[good], fv[good], tb[good]
        best[qi] = fv
        face[qi] = self.owner[si]
        uvs = self.uv[si]
        bu[qi] = uvs[:, 0] + tb * (uvs[:, 2] - uvs[:, 0])
        bv[qi] = uvs[:, 1] + tb * (uvs[:, 3] - uvs[:, 1])
        return best, face, bu, bv

    def points(self, k: int, u: FloatArray, v: FloatArray) -> FloatArray:
        """The 3-D contact (m, 3) that :meth:`drop` measured for contacts (u, v) on wall ``k``:
        the point of the border chord whose trim segment holds (u, v), at the same fraction
        along it.  On a curved wall it differs from the surface at (u, v) by up to the trim
        tolerance, and the height's slope (envelope theorem) must come from the chord's
        point, the one the height was measured at."""
        mine = np.flatnonzero(self.owner == k)
        uv = np.column_stack([u, v]).astype(float)
        out = np.full((len(uv), 3), np.nan)
        if len(mine) == 0 or len(uv) == 0:
            return out
        e = self.uv[mine]
        a, dd = e[:, :2], e[:, 2:] - e[:, :2]
        L2 = (dd * dd).sum(axis=1)
        L2s = np.where(L2 > 0, L2, 1.0)
        step = max(1, 2 ** 20 // len(mine))  # bounded memory: queries x segments per block
        for start in range(0, len(uv), step):
            w = uv[start:start + step]
            rel = w[:, None, :] - a[None]
            t = np.clip((rel * dd[None]).sum(axis=2) / L2s[None], 0.0, 1.0)
            off = rel - t[..., None] * dd[None]
            j = np.argmin((off * off).sum(axis=2), axis=1)
            rows = np.arange(len(w))
            seg = self.seg[mine[j]]
            tj = t[rows, j]
            out[start:start + step] = seg[:, 0] + tj[:, None] * (seg[:, 1] - seg[:, 0])
        return out


class _SegmentGrid:
    """Trim segments filed by the cells of a G x G grid over the domain that their boxes
    meet: the segments near a point are found among its cell's few."""

    def __init__(self, edges: FloatArray, domain, cells: int = 64):
        (u0, u1), (v0, v1) = domain
        self.edges = edges
        self.o = np.array([u0, v0])
        self.h = np.array([(u1 - u0) / cells or 1.0, (v1 - v0) / cells or 1.0])
        self.g = cells
        rows: dict = {}
        if len(edges):
            lo = self._cell(np.minimum(edges[:, :2], edges[:, 2:]) - 1e-9 * self.h * cells)
            hi = self._cell(np.maximum(edges[:, :2], edges[:, 2:]) + 1e-9 * self.h * cells)
            for k in range(len(edges)):
                for i in range(lo[k, 0], hi[k, 0] + 1):
                    for j in range(lo[k, 1], hi[k, 1] + 1):
                        rows.setdefault(i * cells + j, []).append(k)
        width = max([len(r) for r in rows.values()] + [1])
        self.table = np.full((cells * cells, width), -1, dtype=np.intp)
        for c, r in rows.items():
            self.table[c, : len(r)] = r

    def _cell(self, pts: FloatArray) -> np.ndarray:
        return clamp(np.floor((pts - self.o) / self.h), 0, self.g - 1).astype(np.intp)

    def near(self, u: FloatArray, v: FloatArray, eps: float):
        pts = np.column_stack([u, v])
        c = self._cell(pts)
        cand = self.table[c[:, 0] * self.g + c[:, 1]]  # (n, width)
        qi, slot = np.nonzero(cand >= 0)
        si = cand[qi, slot]
        if len(si) == 0:
            return qi, si
        e = self.edges[si]
        a, d = e[:, :2], e[:, 2:] - e[:, :2]
        L2 = (d * d).sum(axis=1)
        t = clamp(((pts[qi] - a) * d).sum(axis=1) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
        r = pts[qi] - (a + t[:, None] * d)
        keep = (r * r).sum(axis=1) <= eps * eps
        return qi[keep], si[keep]


class _RowCache:
    """Answers of a function of a row alone, remembered by the row's bytes: ``cache(keys,
    compute)`` returns ``compute(rows)`` (a tuple of arrays, one row per index of ``rows``)
    for every row of ``keys`` (n, w), computing each distinct row not seen before once.  At
    most CLASSIFY_CACHE rows are kept (then it starts afresh)."""

    def __init__(self):
        self.index: dict = {}
        self.store: list = []
        self.size = 0

    def __call__(self, keys: FloatArray, compute) -> tuple:
        keys = np.ascontiguousarray(keys, dtype=float)
        rows = keys.view(np.dtype((np.void, keys.itemsize * keys.shape[1]))).ravel()
        uniq, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
        ukeys = uniq.tolist()
        get = self.index.get
        pos = np.fromiter((get(k, -1) for k in ukeys), np.intp, len(ukeys))
        todo = np.flatnonzero(pos < 0)
        if len(todo) and self.size + len(todo) > CLASSIFY_CACHE:
            self.index, self.store, self.size = {}, [], 0
            pos[:] = -1
            todo = np.arange(len(ukeys))
        if len(todo):
            done = compute(first[todo])
            need = self.size + len(todo)
            if not self.store or need > len(self.store[0]):
                cap = max(2 * need, 1024)
                grown = [np.empty((cap,) + a.shape[1:], a.dtype) for a in done]
                for g, old in zip(grown, self.store):
                    g[: self.size] = old[: self.size]
                self.store = grown
            for g, a in zip(self.store, done):
                g[self.size:need] = a
            pos[todo] = np.arange(self.size, need)
            self.index.update(zip([ukeys[k] for k in todo.tolist()], range(self.size, need)))
            self.size = need
        at = pos[inverse.ravel()]
        return tuple(g[at] for g in self.store)


@dataclass
class _Items:
    """(query, sub-patch) pairs of one face: homogeneous nets, parameter boxes, trim state.

    The nets live in a table ``nets`` (N, 4, p+1, q+1) that the pairs index by ``node``: the
    queries of a pass share their sub-patches, so each is split and bounded (its query-free
    part) once, not once per query.  ``status`` 1: wholly inside the trim, 2: straddling it.
    ``segs`` (n, K) indices of the trim segments crossing a straddling sub-patch (-1 padding;
    row all -2: more than K, test all).
    """

    query: np.ndarray
    node: np.ndarray
    nets: FloatArray
    box: FloatArray
    depth: np.ndarray
    status: np.ndarray
    segs: np.ndarray

    @property
    def net(self) -> FloatArray:
        """Each pair's net (n, 4, p+1, q+1)."""
        return self.nets[self.node]

    def take(self, keep: np.ndarray) -> _Items:
        return _Items(self.query[keep], self.node[keep], self.nets, self.box[keep],
                      self.depth[keep], self.status[keep], self.segs[keep])


class _FaceData:
    """Per face: Bezier nets of its patches, their boxes and trim classification."""

    def __init__(self, face: Face, index: int):
        self.face = face
        self.index = index
        s = face.surface
        bez = s.bezier_patches()
        self.p, self.q = s.degree_u, s.degree_v
        nu, nv = bez.points.shape[:2]
        hom = np.concatenate([bez.points * bez.weights[..., None], bez.weights[..., None]], -1)
        # coordinate planes (n, 4, p+1, q+1): reductions run over contiguous memory
        self.nets = np.ascontiguousarray(
            hom.reshape(nu * nv, self.p + 1, self.q + 1, 4).transpose(0, 3, 1, 2))
        self.nu, self.nv = nu, nv
        self.u_ends, self.v_ends = bez.u[:, 1].copy(), bez.v[:, 1].copy()
        uu, vv = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
        self.boxes = np.column_stack([bez.u[uu.ravel(), 0], bez.u[uu.ravel(), 1],
                                      bez.v[vv.ravel(), 0], bez.v[vv.ravel(), 1]])
        pts = bez.points.reshape(nu * nv, -1, 3)
        self.lo, self.hi = pts.min(axis=1), pts.max(axis=1)
        self._bands = _Bands(face._edges)
        # Segments (u0, v0, u1, v1) that bound the material inside the domain: those lying on
        # the domain's own sides bound nothing more than the surface's edge does (an untrimmed
        # face has none left, so none of its sub-patches straddles).
        (du0, du1), (dv0, dv1) = s.domain
        e = face._edges
        eps = 1e-12 * max(du1 - du0, dv1 - dv0)
        on_side = np.zeros(len(e), bool)
        for c, side in ((0, du0), (0, du1), (1, dv0), (1, dv1)):
            on_side |= (np.abs(e[:, c] - side) <= eps) & (np.abs(e[:, c + 2] - side) <= eps)
        self.edges = e[~on_side]
        self._elo = np.minimum(self.edges[:, :2], self.edges[:, 2:])
        self._ehi = np.maximum(self.edges[:, :2], self.edges[:, 2:])
        self._pad = 1e-9 * max(du1 - du0, dv1 - dv0)
        self._grid = _SegmentGrid(self.edges, face.surface.domain)
        self._known = _RowCache()  # classify's answers by row
        self._known_vertices = _RowCache()  # vertices' answers by row
        self.design = _bernstein_grid(self.p, self.q)
        self.pinv = np.linalg.pinv(self.design)  # (3, K)
        status, segs = self.classify(self.boxes, np.full((len(self.boxes), 1), -2))
        self.root_status, self.root_segs = status, segs
        keep = status > 0
        self.roots = np.flatnonzero(keep)

    def inside(self, u: FloatArray, v: FloatArray) -> np.ndarray:
        """Whether (u, v) lies in the material: the trim test of :func:`faces.inside`, with points
        on the domain's own sides (where pnpoly's half-open rule would put the right and top
        sides outside) moved a hair into the domain first."""
        (u0, u1), (v0, v1) = self.face.surface.domain
        eu, ev = 1e-12 * (u1 - u0), 1e-12 * (v1 - v0)
        u = clamp(np.asarray(u, dtype=float), u0 + eu, u1 - eu)
        v = clamp(np.asarray(v, dtype=float), v0 + ev, v1 - ev)
        return self._bands(u, v)

    def segments_at(self, u: FloatArray, v: FloatArray, eps: float):
        """(point index, segment index) of the trim segments within ``eps`` of each (u, v)."""
        return self._grid.near(u, v, eps)

    @property
    def selected(self) -> bool:
        return bool(self.face.selected)

    def classify(self, box: FloatArray, parent_segs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Status (0 outside, 1 inside, 2 straddling) and crossing segments of boxes (n, 4)
        whose parents were crossed by ``parent_segs`` (rows of -2: by any segment).

        A row's answer depends on the row alone, and the queries of a pass meet the same
        sub-patches (halving is the same for every query): rows are classified once each
        (duplicates within a call share the answer, earlier calls' answers are remembered:
        :class:`_RowCache`), so the trim test, which at shallow depth clips every one of the
        face's segments, runs per sub-patch, not per query."""
        if len(box) == 0:
            return np.zeros(0, np.int8), np.full((0, MAX_SEGMENTS), -1, dtype=np.int64)
        return self._known(np.column_stack([box, parent_segs]),
                           lambda rows: self._classify(box[rows], parent_segs[rows]))

    def _classify(self, box: FloatArray, parent_segs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`classify` of every row (no sharing)."""
        n = len(box)
        status = np.zeros(n, np.int8)
        segs = np.full((n, MAX_SEGMENTS), -1, dtype=np.int64)
        if n == 0:
            return status, segs
        every = parent_segs[:, 0] == -2
        E = len(self.edges)
        counts = np.zeros(n, int)
        # sub-patches whose parent was crossed by many segments: test all of them, those whose
        # boxes (padded against rounding) meet the sub-patch's by Liang-Barsky
        idx_all = np.flatnonzero(every)
        chunk = max(1, 4_000_000 // max(E, 1))
        for start in range(0, len(idx_all), chunk):
            rows = idx_all[start:start + chunk]
            b = box[rows]
            pad = self._pad
            near = ((self._elo[None, :, 0] <= b[:, 1:2] + pad)
                    & (self._ehi[None, :, 0] >= b[:, 0:1] - pad)
                    & (self._elo[None, :, 1] <= b[:, 3:4] + pad)
                    & (self._ehi[None, :, 1] >= b[:, 2:3] - pad))
            ri, ei = np.nonzero(near)  # row-major: each row's segments in ascending order
            hit, _, _ = _clip(self.edges[ei][:, None, :], b[ri])
            hr, he = ri[hit[:, 0]], ei[hit[:, 0]]
            cnt = np.bincount(hr, minlength=len(rows))
            counts[rows] = cnt
            rank = np.arange(len(hr)) - np.searchsorted(hr, hr)
            # each row's first MAX_SEGMENTS hit segment ids (-1 padding), -2 rows for more
            small = rank < MAX_SEGMENTS
            segs[rows[hr[small]], rank[small]] = he[small]
            segs[rows[cnt > MAX_SEGMENTS]] = -2
        rest = np.flatnonzero(~every)
        if len(rest) and E:
            ps = parent_segs[rest]
            valid = ps >= 0
            seg = np.where(valid[..., None], self.edges[np.maximum(ps, 0)], np.nan)
            hit, _, _ = _clip(seg, box[rest])
            counts[rest] = hit.sum(axis=1)
            # compact the surviving ids to the front of each row
            order = np.argsort(~hit, axis=1, kind="stable")
            kept = np.take_along_axis(np.where(hit, ps, -1), order, axis=1)
            segs[rest, : kept.shape[1]] = kept
        crossed = counts > 0
        status[crossed] = 2
        clear = np.flatnonzero(~crossed)
        if len(clear):
            b = box[clear]
            mid = self.inside(0.5 * (b[:, 0] + b[:, 1]), 0.5 * (b[:, 2] + b[:, 3]))
            status[clear] = np.where(mid, 1, 0)
        return status, segs

    def vertices(self, items: _Items) -> tuple[FloatArray, np.ndarray]:
        """Local (s, t) in [0, 1]^2 of the candidate vertices of the material in straddling
        sub-patches (n, 4 + 2K, 2) and their validity (n, 4 + 2K): the 4 corners (valid when
        inside the trim), then the clipped trim segment end points.  They depend on the box
        and its segments alone: computed once per distinct sub-patch (see :class:`_RowCache`)."""
        if len(items.query) == 0:
            return self._vertices(items.box, items.segs)
        return self._known_vertices(np.column_stack([items.box, items.segs]),
                                    lambda rows: self._vertices(items.box[rows], items.segs[rows]))

    def _vertices(self, box: FloatArray, ps: np.ndarray) -> tuple[FloatArray, np.ndarray]:
        """:meth:`vertices` of every row (no sharing)."""
        n = len(box)
        st = np.zeros((n, 4 + 2 * MAX_SEGMENTS, 2))
        ok = np.zeros((n, 4 + 2 * MAX_SEGMENTS), bool)
        st[:, :4] = CORNERS
        du = box[:, 1] - box[:, 0]
        dv = box[:, 3] - box[:, 2]
        ok[:, :4] = self.inside(box[:, [0, 1, 0, 1]], box[:, [2, 2, 3, 3]])
        valid = ps >= 0
        seg = np.where(valid[..., None], self.edges[np.maximum(ps, 0)], np.nan)
        hit, e0, e1 = _clip(seg, box)
        pts = np.concatenate([e0, e1], axis=1)  # (n, 2K, 2)
        loc = np.empty_like(pts)
        loc[..., 0] = (pts[..., 0] - box[:, :1]) / du[:, None]
        loc[..., 1] = (pts[..., 1] - box[:, 2:3]) / dv[:, None]
        st[:, 4:] = clamp(np.nan_to_num(loc), 0.0, 1.0)
        ok[:, 4:] = np.concatenate([hit, hit], axis=1)
        return st, ok


@dataclass
class DropResult:
    """Ball-centre heights and contacts of :meth:`FaceSet.drop_ball` (mm, parameters)."""

    centre: FloatArray
    face: np.ndarray
    u: FloatArray
    v: FloatArray
    gap: FloatArray


class FaceSet:
    """The faces a job sees: ``selected`` ones are machined, the others are check surfaces.

    >>> fs = FaceSet(faces)
    >>> tip, face, u, v, on_selected = fs.drop_ball(xy, radius=3.0)
    """

    def __init__(self, faces: Sequence[Face]):
        faces = list(faces)
        if not faces:
            raise BSplineCAMError("the face set is empty: select at least one face")
        self.faces = faces
        # Unselected vertical faces (walls) enter by their borders only (see _Walls)
        walls = [k for k, f in enumerate(faces) if not f.selected and _vertical(f.surface)]
        self.walls = _Walls([faces[k] for k in walls], walls)
        self.data = [_FaceData(f, k) for k, f in enumerate(faces) if k not in set(walls)]
        boxes = [(d.lo.min(axis=0), d.hi.max(axis=0)) for d in self.data] + self.walls.boxes
        lo = np.min([b[0] for b in boxes], axis=0)
        hi = np.max([b[1] for b in boxes], axis=0)
        self.size = float(np.linalg.norm(hi - lo))
        self.stats = {"pairs": 0, "levels": 0, "uncertified": 0}
        self._box_memo: dict = {}  # bounds() per selected_only: the faces never change

    def trim_test(self, k: int):
        """The inside test (u, v) -> bool array of face ``k`` (its index in ``faces``, not
        in ``data``: unselected walls have no entry there).  A wall has none."""
        for d in self.data:
            if d.index == k:
                return d.inside
        raise IndexError(f"face {k} is a wall or out of range: no trim test")

    def contact_points(self, face: np.ndarray, u: FloatArray, v: FloatArray) -> FloatArray:
        """The 3-D points (m, 3) where :meth:`drop_ball`'s contacts (face, u, v) touch the
        ball (NaN where face is -1): the surface at (u, v), or on a wall the point of its
        border chord the height was measured at (:meth:`_Walls.points`)."""
        face = np.asarray(face)
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        out = np.full((len(face), 3), np.nan)
        walls = set(self.walls.owner.tolist())
        for k in np.unique(face[face >= 0]).tolist():
            idx = np.flatnonzero(face == k)
            if k in walls:
                out[idx] = self.walls.points(k, u[idx], v[idx])
            else:
                out[idx] = self.faces[k].surface.evaluate(u[idx], v[idx])
        return out

    # -- drop-cutter ---------------------------------------------------------------------------
    def drop_ball(self, xy, radius: float, selected_only: bool = False,
                  certify: float = CERTIFY):
        """Tip heights (m,) (mm; NaN where the ball meets no face), contact face index (-1
        none), contact (u, v) and whether the contact lies on a selected face.

        The centre height c = tip + R is within ``certify`` mm (default ``CERTIFY``) below
        the true maximum of f over all faces (only the selected ones if ``selected_only``),
        by the bound of the module docstring.  A looser ``certify`` stops the branch and
        bound sooner (callers that add it back get a height never below the true one).
        """
        R = float(radius)
        if not (math.isfinite(R) and R > 0):
            raise ParameterError(f"radius must be a finite number > 0 mm, got {radius!r}")
        q = np.asarray(xy, dtype=float).reshape(-1, 2)
        if not np.all(np.isfinite(q)):
            bad = int(np.flatnonzero(~np.isfinite(q).all(axis=1))[0])
            raise ParameterError(f"query point {bad} is not finite (mm): {q[bad].tolist()}")
        res = self.centre_heights(q, R, selected_only, certify)
        tip = res.centre - R
        tip[~np.isfinite(tip)] = np.nan
        on_sel = np.zeros(len(q), bool)
        found = res.face >= 0
        sel = np.array([f.selected for f in self.faces])
        on_sel[found] = sel[res.face[found]]
        return tip, res.face, res.u, res.v, on_sel

    def centre_heights(self, q: FloatArray, R: float, selected_only: bool = False,
                       certify: float = CERTIFY) -> DropResult:
        """Certified ball-centre heights (see :meth:`drop_ball`), chunk by chunk."""
        m = len(q)
        if m == 0:
            e = np.zeros(0)
            return DropResult(e, np.zeros(0, int), e, e, e)
        out = DropResult(np.full(m, -np.inf), np.full(m, -1), np.zeros(m), np.zeros(m),
                         np.zeros(m))
        data = [d for d in self.data if d.selected or not selected_only]
        for start in range(0, m, QUERY_CHUNK):
            sl = slice(start, min(m, start + QUERY_CHUNK))
            r = self._chunk(q[sl], R, data, not selected_only, certify)
            out.centre[sl], out.face[sl], out.u[sl], out.v[sl], out.gap[sl] = r
        return out

    def _chunk(self, q: FloatArray, R: float, data: list, walls: bool = True,
               certify: float = CERTIFY) -> tuple:
        m = len(q)
        best = np.full(m, -np.inf)
        face = np.full(m, -1)
        bu = np.zeros(m)
        bv = np.zeros(m)
        gap = np.zeros(m)
        if walls:
            best, face, bu, bv = self.walls.drop(q, R)
        R2 = R * R
        groups = []
        for j, d in enumerate(data):
            roots = d.roots
            if len(roots) == 0:
                continue
            dx = np.maximum(np.maximum(d.lo[roots, 0][None] - q[:, :1],
                                       q[:, :1] - d.hi[roots, 0][None]), 0.0)
            dy = np.maximum(np.maximum(d.lo[roots, 1][None] - q[:, 1:],
                                       q[:, 1:] - d.hi[roots, 1][None]), 0.0)
            qi, ri = np.nonzero(dx * dx + dy * dy <= R2)
            if len(qi) == 0:
                continue
            r = roots[ri]
            groups.append((j, d, _Items(qi, r, d.nets, d.boxes[r], np.zeros(len(r), int),
                                        d.root_status[r], d.root_segs[r])))
        # per face (rows follow ``data``): its best lower bound and contact, and the certified
        # region around that contact (box in (u, v), the bound of f on it; inf: none)
        nf = len(data)
        fb = np.full((nf, m), -np.inf)
        fu = np.zeros((nf, m))
        fv = np.zeros((nf, m))
        reg_box = np.zeros((nf, m, 4))
        reg_val = np.full((nf, m), np.inf)
        sought = np.full((nf, m), np.nan)  # fb when a region was last sought
        crowded_levels = np.zeros(m, int)
        level = 0
        while groups:
            level += 1
            given_up = crowded_levels >= MAX_CROWDED
            crowded_now = np.zeros(m, bool)
            evaluated = []
            for j, d, it in groups:
                ub, lb, lu, lv = self._bounds(d, it, q, R, best[it.query] + certify)
                evaluated.append((j, d, it, ub))
                good = np.isfinite(lb)
                if good.any():
                    gi = np.flatnonzero(good)
                    order = gi[np.argsort(lb[gi], kind="stable")]
                    qq = it.query[order]
                    better = lb[order] > fb[j, qq]
                    qq, order = qq[better], order[better]
                    # later (larger) assignments win
                    fb[j, qq] = lb[order]
                    fu[j, qq], fv[j, qq] = lu[order], lv[order]
            self._merge(data, fb, fu, fv, best, face, bu, bv)
            if level in POLISH_LEVELS[1:] or (level > POLISH_LEVELS[-1]
                                              and level % REGION_EVERY == 0):
                self._certify_faces(q, R, data, evaluated, fb, fu, fv, best, face, bu, bv,
                                    certify, reg_box, reg_val, sought)
            groups = []
            for j, d, it, ub in evaluated:
                self.stats["pairs"] += len(it.query)
                qs = it.query
                open_ = ub > best[qs] + certify
                # sub-patches inside their face's certified region
                rb = reg_box[j, qs]
                inreg = reg_val[j, qs] <= best[qs] + certify
                open_ &= ~(inreg & (it.box[:, 0] >= rb[:, 0]) & (it.box[:, 1] <= rb[:, 1])
                           & (it.box[:, 2] >= rb[:, 2]) & (it.box[:, 3] <= rb[:, 3]))
                deep = open_ & (it.depth >= MAX_DEPTH)
                if deep.any():
                    np.maximum.at(gap, qs[deep], ub[deep] - best[qs[deep]])
                    self.stats["uncertified"] += int(deep.sum())
                open_ &= ~deep
                stop = open_ & given_up[qs]
                if stop.any():
                    # crowded for MAX_CROWDED levels: its bounds no longer close in
                    np.maximum.at(gap, qs[stop], ub[stop] - best[qs[stop]])
                    self.stats["uncertified"] += int(stop.sum())
                    open_ &= ~stop
                crowded = np.bincount(qs[open_], minlength=len(q)) > MAX_OPEN
                crowded_now |= crowded
                if crowded.any():
                    # a query whose maximum is (nearly) tied along a curve: keep its MAX_OPEN
                    # best sub-patches; the rest's bounds are reported as its gap
                    idx = np.flatnonzero(open_ & crowded[qs])
                    order = idx[np.lexsort((-ub[idx], qs[idx]))]
                    qo = qs[order]
                    first = np.searchsorted(qo, qo)
                    drop = order[np.arange(len(order)) - first >= MAX_OPEN]
                    np.maximum.at(gap, qs[drop], ub[drop] - best[qs[drop]])
                    self.stats["uncertified"] += len(drop)
                    open_[drop] = False
                if open_.any():
                    children = self._children(d, it, open_,
                                              self._region_cuts(it, open_, rb, inreg))
                    if len(children.query):
                        groups.append((j, d, children))
            crowded_levels += crowded_now
        self.stats["levels"] = max(self.stats["levels"], level)
        # a final polish: smooth maxima to machine precision, so that neighbouring heights are
        # consistent to far better than CERTIFY (the chord checks compare them)
        self._polish(q, R, best, face, bu, bv, steps=2 * POLISH_STEPS)
        return best, face, bu, bv, gap

    @staticmethod
    def _region_cuts(it: _Items, open_: np.ndarray, rb: FloatArray,
                     inreg: np.ndarray) -> tuple[FloatArray, np.ndarray]:
        """Where an open sub-patch overlaps its face's certified region, split it along a side
        of the region instead of at its middle (the side cutting it most evenly, if it cuts it
        between CUT_MARGIN and 1 - CUT_MARGIN), so that the piece inside the region is dropped
        after a few splits instead of being halved down to the region's scale."""
        b = it.box
        over = (open_ & inreg & (b[:, 0] < rb[:, 1]) & (b[:, 1] > rb[:, 0])
                & (b[:, 2] < rb[:, 3]) & (b[:, 3] > rb[:, 2]))
        t = np.full(len(b), np.nan)
        along_u = np.zeros(len(b), bool)
        if not over.any():
            return t, along_u
        wu = b[:, 1] - b[:, 0]
        wv = b[:, 3] - b[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            cand = np.column_stack([(rb[:, 0] - b[:, 0]) / wu, (rb[:, 1] - b[:, 0]) / wu,
                                    (rb[:, 2] - b[:, 2]) / wv, (rb[:, 3] - b[:, 2]) / wv])
        ok = (cand > CUT_MARGIN) & (cand < 1.0 - CUT_MARGIN) & over[:, None]
        score = np.where(ok, np.abs(cand - 0.5), np.inf)
        k = np.argmin(score, axis=1)
        rows = np.flatnonzero(np.isfinite(score[np.arange(len(b)), k]))
        t[rows] = cand[rows, k[rows]]
        along_u[rows] = k[rows] < 2
        return t, along_u

    @staticmethod
    def _merge(data: list, fb: FloatArray, fu: FloatArray, fv: FloatArray, best: FloatArray,
               face: np.ndarray, bu: FloatArray, bv: FloatArray) -> None:
        """Raise each query's best (and its contact) to its faces' best lower bounds."""
        if len(fb) == 0:
            return
        k = np.argmax(fb, axis=0)
        cols = np.arange(fb.shape[1])
        top = fb[k, cols]
        up = np.flatnonzero(top > best)
        if len(up):
            best[up] = top[up]
            face[up] = np.array([d.index for d in data])[k[up]]
            bu[up], bv[up] = fu[k[up], up], fv[k[up], up]

    def _certify_faces(self, q: FloatArray, R: float, data: list, evaluated: list,
                       fb: FloatArray, fu: FloatArray, fv: FloatArray, best: FloatArray,
                       face: np.ndarray, bu: FloatArray, bv: FloatArray, certify: float,
                       reg_box: FloatArray, reg_val: FloatArray, sought: FloatArray) -> None:
        """Polish each face's best contact of the queries with sub-patches of that face still
        open, then seek a certified region around it (:meth:`_face_regions`).

        A region of face F proves f <= reg_val on the material of F inside reg_box; F's
        sub-patches inside it are dropped once reg_val <= best + certify.  So the face that
        holds the maximum, and a tangent neighbour whose own maximum lies on the shared edge
        (a trim or domain side of it, nearly tied with the first), both stop halving there."""
        todo = []
        for j, d, it, ub in evaluated:
            qs = np.unique(it.query[ub > best[it.query] + certify])
            if len(qs) == 0:
                continue
            # contacts whose value rose since the last attempt (a better contact: a tighter
            # certificate, a larger region)
            fj, sj = fb[j, qs], sought[j, qs]
            qs = qs[np.isfinite(fj) & ~(fj <= sj) & (fj >= best[qs] - REGION_TIE)]
            if len(qs) == 0:
                continue
            fcs = np.full(len(qs), d.index)
            b, u, v = fb[j, qs].copy(), fu[j, qs].copy(), fv[j, qs].copy()
            self._polish(q[qs], R, b, fcs, u, v, steps=2 * POLISH_STEPS)
            fb[j, qs], fu[j, qs], fv[j, qs] = b, u, v
            todo.append((j, d, qs))
        if not todo:
            return
        self._merge(data, fb, fu, fv, best, face, bu, bv)
        for j, d, qs in todo:
            limit = best[qs] + certify - fb[j, qs]
            found, box, excess = self._face_regions(d, q[qs], R, fu[j, qs], fv[j, qs], limit)
            sought[j, qs] = fb[j, qs]
            hit = qs[found]
            reg_box[j, hit] = box[found]
            reg_val[j, hit] = fb[j, hit] + excess[found]

    def _polish(self, q: FloatArray, R: float, best: FloatArray, face: np.ndarray,
                bu: FloatArray, bv: FloatArray, steps: int = POLISH_STEPS) -> None:
        """Raise the lower bounds in place by projected Newton ascent of f(u, v) from the best
        contacts (Nocedal & Wright 16.7); a step counts only at a real surface point inside
        its face's trim that raises f, so ``best`` stays a lower bound."""
        R2 = R * R
        for d in self.data:
            idx = np.flatnonzero(face == d.index)
            if len(idx) == 0:
                continue
            s = d.face.surface
            (u0, u1), (v0, v1) = s.domain
            u, v = bu[idx].copy(), bv[idx].copy()
            qq = q[idx]
            fbest = best[idx].copy()
            # a contact whose step was refused would take the same step again: only the
            # contacts that moved go on
            live = np.arange(len(idx))
            for _ in range(steps):
                ul, vl, ql = u[live], v[live], qq[live]
                with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                    ok_, nu_, nv_ = self._newton_step(s, ul, vl, ql, R2)
                nu_ = clamp(nu_, u0, u1)
                nv_ = clamp(nv_, v0, v1)
                p = s.evaluate(nu_, nv_)
                pd = ((p[:, :2] - ql) ** 2).sum(axis=1)
                fv = np.where(pd <= R2, p[:, 2] + np.sqrt(np.maximum(R2 - pd, 0.0)), -np.inf)
                good = (fv > fbest[live]) & ok_ & (np.abs(nu_ - ul) + np.abs(nv_ - vl) > 0)
                if good.any():
                    good[good] = d.inside(nu_[good], nv_[good])
                if not good.any():
                    break
                live = live[good]
                u[live], v[live], fbest[live] = nu_[good], nv_[good], fv[good]
            best[idx], bu[idx], bv[idx] = fbest, u, v
            if len(d.edges):
                self._edge_polish(d, q, R, idx, best, bu, bv)

    def _edge_polish(self, d: _FaceData, q: FloatArray, R: float, idx: np.ndarray,
                     best: FloatArray, bu: FloatArray, bv: FloatArray) -> None:
        """Newton's method along the trim segments that hold a contact (a maximum on the trim
        edge, where the ball rests on the face's boundary): the contacts the halving finds
        there (trim vertices, clipped segment ends) are polished to machine precision, so that
        neighbouring heights along a pass agree to far better than CERTIFY."""
        (u0, u1), (v0, v1) = d.face.surface.domain
        eps = 1e-10 * max(u1 - u0, v1 - v0)
        qi, si = d.segments_at(bu[idx], bv[idx], eps)
        if len(qi) == 0:
            return
        rows = idx[qi]
        e = d.edges[si]
        a = e[:, :2]
        dd = e[:, 2:] - a
        L2 = (dd * dd).sum(axis=1)
        t = clamp(((np.column_stack([bu[rows], bv[rows]]) - a) * dd).sum(axis=1)
                  / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
        qq = q[rows]
        R2 = R * R
        s = d.face.surface
        ft = np.full(len(rows), -np.inf)
        for _ in range(2 * POLISH_STEPS):
            uu, vv = a[:, 0] + t * dd[:, 0], a[:, 1] + t * dd[:, 1]
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                gu, gw, huu, huw, hww = self._grad_hess(s, uu, vv, qq, R2)
                f1 = gu * dd[:, 0] + gw * dd[:, 1]
                f2 = huu * dd[:, 0] ** 2 + 2 * huw * dd[:, 0] * dd[:, 1] + hww * dd[:, 1] ** 2
                step = np.where(f2 < 0, -f1 / f2, np.sign(f1))
            nt = clamp(t + np.nan_to_num(step), 0.0, 1.0)
            p = s.evaluate(a[:, 0] + nt * dd[:, 0], a[:, 1] + nt * dd[:, 1])
            pd = ((p[:, :2] - qq) ** 2).sum(axis=1)
            fv = np.where(pd <= R2, p[:, 2] + np.sqrt(np.maximum(R2 - pd, 0.0)), -np.inf)
            better = fv > ft
            t = np.where(better, nt, t)
            ft = np.where(better, fv, ft)
            if not better.any():
                break
        uu, vv = a[:, 0] + t * dd[:, 0], a[:, 1] + t * dd[:, 1]
        order = np.argsort(ft, kind="stable")  # later (larger) assignments win
        rows, ft, uu, vv = rows[order], ft[order], uu[order], vv[order]
        up = ft > best[rows]
        best[rows[up]] = ft[up]
        bu[rows[up]], bv[rows[up]] = uu[up], vv[up]

    def _face_regions(self, d: _FaceData, qq: FloatArray, R: float, u: FloatArray,
                      v: FloatArray, limit: FloatArray) -> tuple[np.ndarray, FloatArray,
                                                                  FloatArray]:
        """Boxes in (u, v) of face ``d`` around contacts x* = (u, v) of queries ``qq`` on whose
        material f <= f(x*) + excess is proved, excess <= ``limit`` (a local certificate):
        (found, box (n, 4), excess).

        f(p) = p_z + sqrt(R^2 - |p_xy - q|^2) is concave in p with the hemisphere's Hessian at
        most -I/R in xy, so for p0 = S(x*) and g = grad f(p0):

            f(S(x)) - f(p0) <= g . (S(x) - p0) - |S_xy(x) - p0_xy|^2 / (2R)
                             = [N(x) w(x) - |E(x)|^2 / (2R)] / w(x)^2

        with the homogeneous net (A, w) of S, N = g . (A - w p0) and E = A_xy - w p0_xy, both
        polynomial patches vanishing at x*.  Taylor's theorem with the Bezier hulls of their
        second derivatives over the box (hodographs) bounds N <= n1 . d + lam |d|^2 / 2 and
        |E| >= (sigma - M2 rho / 2) |d|, d = x - x* (rho the box's largest |d|, sigma the least
        singular value of E's Jacobian at x*, n1 = grad N(x*)), so with
        k = (sigma - M2 rho / 2)+^2 / (2R) - lam w_max / 2 > 0 the bracket is at most
        w_max (n1 . d)+ - k |d|^2.  The same per direction: |E|^2 >= d^T J^T J d - M2 rho
        sigma_max |d|^2 (J = E's Jacobian at x*) and the hulls of N_ss, |N_st|, N_tt bound
        the Taylor term in (|ds|, |dt|), so the least eigenvalue of the 2x2 matrix they make
        is a k as well; the larger of the two is used.  Where a face turns steep its xy map
        nears singular across the slope (sigma -> 0: the first k fails), while N, concave
        across the slope, and J along it keep the second positive.  For any unit vector nu
        with alpha = n1 . nu >= 0 and beta = |n1 x nu|, n1 . d <= alpha delta + beta |d|
        where delta = max nu . d over the material in the box (a polygon: its largest value is
        at a vertex, the box corners in the material and the trim segments' ends clipped to
        the box), hence

            bracket <= w_max alpha delta + (w_max beta)^2 / (4 k).

        nu = n1 / |n1| and the axes cover an interior maximum and one on a side of the domain;
        the normals of the trim segments in the box cover a maximum on a trim edge (the
        material lies on one side of a straight edge: delta = 0, and beta, the slope along
        the edge, vanishes at the edge's maximum).  The least bound over these, divided by
        w_min^2, is the excess.  Boxes are tried largest first (REGION_SIZES: the first alone,
        then the rest in one pass, each query keeping the largest that holds) and stay inside
        the Bezier patch that holds x*."""
        n = len(u)
        found = np.zeros(n, bool)
        out_box = np.zeros((n, 4))
        out_ex = np.full(n, np.inf)
        if n == 0:
            return found, out_box, out_ex
        R2 = R * R
        s = d.face.surface
        iu = clamp(np.searchsorted(d.u_ends, u, side="left"), 0, d.nu - 1)
        iv = clamp(np.searchsorted(d.v_ends, v, side="left"), 0, d.nv - 1)
        root = iu * d.nv + iv
        box = d.boxes[root]
        wu, wv = box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]
        cs = clamp((u - box[:, 0]) / wu, 0.0, 1.0)
        ct = clamp((v - box[:, 2]) / wv, 0.0, 1.0)
        j = s.derivatives(u, v)
        p0 = j.point
        D = p0[:, :2] - qq
        dd = (D * D).sum(axis=1)
        valid = (dd < R2 * (1.0 - 1e-9)) & (limit > 0)
        h0 = np.sqrt(np.maximum(R2 - dd, 1e-300))
        g = np.column_stack([-D / h0[:, None], np.ones(n)])
        gp = (g * p0).sum(axis=1)
        nets = d.nets[root]
        if s.rational:
            bs = _bernstein(d.p, cs)
            bt = _bernstein(d.q, ct)
            wstar = np.einsum("ni,nij,nj->n", bs, nets[:, 3], bt)
        else:
            wstar = np.ones(n)
        todo = valid.copy()
        # trim segments crossing each box: those of the (nested) box tried before it
        segs = d.root_segs[root]
        stat = d.root_status[root]
        # the largest box first; where it fails, all the smaller ones in one pass (a call's
        # cost is in its array operations, not its rows), each query taking the largest
        # that holds.  A nested box's trim segments are among its first box's.
        for sizes in (REGION_SIZES[:1], REGION_SIZES[1:]):
            if not todo.any() or not sizes:
                break
            asked = np.flatnonzero(todo)
            k_ = np.repeat(asked, len(sizes))
            rho = np.tile(np.asarray(sizes, float), len(asked))
            s0, s1 = np.maximum(cs[k_] - rho, 0.0), np.minimum(cs[k_] + rho, 1.0)
            t0, t1 = np.maximum(ct[k_] - rho, 0.0), np.minimum(ct[k_] + rho, 1.0)
            sub = _sub_net(nets[k_], s0, s1, t0, t1)
            ls, lt = (cs[k_] - s0) / (s1 - s0), (ct[k_] - t0) / (t1 - t0)
            du, dv = (s1 - s0) * wu[k_], (t1 - t0) * wv[k_]
            gk, pk = g[k_], p0[k_]
            hw = sub[:, 3]
            N = np.einsum("nc,ncij->nij", gk, sub[:, :3]) - hw * gp[k_, None, None]
            E = sub[:, :2] - hw[:, None] * pk[:, :2, None, None]
            nss, nst, ntt = _second_differences(N, d.p, d.q)
            h_ss, h_st, h_tt = (nss.max(axis=(-2, -1)), np.abs(nst).max(axis=(-2, -1)),
                                ntt.max(axis=(-2, -1)))
            lam = _quadratic_bound(h_ss, h_st, h_tt)
            ess, est, ett = _second_differences(E, d.p, d.q)
            mc = _quadratic_bound(np.abs(ess).max(axis=(-2, -1)),
                                  np.abs(est).max(axis=(-2, -1)),
                                  np.abs(ett).max(axis=(-2, -1)))
            m2 = np.hypot(mc[:, 0], mc[:, 1])
            wmax, wmin = hw.max(axis=(1, 2)), hw.min(axis=(1, 2))
            ws = wstar[k_]
            js = j.su[k_] * du[:, None]
            jt = j.sw[k_] * dv[:, None]
            n1 = np.column_stack([ws * (gk * js).sum(axis=1), ws * (gk * jt).sum(axis=1)])
            a11, a12, a21, a22 = ws * js[:, 0], ws * jt[:, 0], ws * js[:, 1], ws * jt[:, 1]
            fro = a11 * a11 + a12 * a12 + a21 * a21 + a22 * a22
            det = np.abs(a11 * a22 - a12 * a21)
            smax = np.sqrt(0.5 * (fro + np.sqrt(np.maximum(fro * fro - 4 * det * det, 0.0))))
            sigma = np.where(smax > 0, det / np.where(smax > 0, smax, 1.0), 0.0)
            rmax = np.hypot(np.maximum(ls, 1 - ls), np.maximum(lt, 1 - lt))
            s_eff = sigma - 0.5 * m2 * rmax
            lam_w = np.where(lam >= 0, lam * wmax, lam * wmin)
            kk = np.where(s_eff > 0, s_eff, 0.0) ** 2 / (2.0 * R) - 0.5 * lam_w
            # the same per direction (where the face turns steep, its xy map is nearly
            # singular across the slope, where N is strongly concave, and not along it):
            # |E|^2 >= |J d|^2 - 2 e |d| |J d| >= d^T (J^T J) d - 2 e smax |d|^2 with
            # e = M2 rho / 2, and w d^T H_N d <= (a, 2b, c) . (ds^2, |ds dt|, dt^2) with the
            # hulls' a, b, c (times w_max or w_min by sign), so the bracket is at most
            # w_max (n1 . d)+ - d'^T K d' for d' = (|ds|, |dt|) (|d'| = |d|): the least
            # eigenvalue of K serves as k too
            e_s = 0.5 * m2 * rmax * smax / R
            g_ss, g_tt = a11 * a11 + a21 * a21, a12 * a12 + a22 * a22
            g_st = np.abs(a11 * a12 + a21 * a22)
            k11 = g_ss / (2.0 * R) - e_s - 0.5 * np.where(h_ss >= 0, h_ss * wmax, h_ss * wmin)
            k22 = g_tt / (2.0 * R) - e_s - 0.5 * np.where(h_tt >= 0, h_tt * wmax, h_tt * wmin)
            k12 = g_st / (2.0 * R) + 0.5 * h_st * wmax
            k_dir = 0.5 * (k11 + k22) - np.sqrt(0.25 * (k11 - k22) ** 2 + k12 * k12)
            kk = np.maximum(kk, k_dir)
            # the material's polygon in the box: its vertices in the box's local (s, t)
            b = box[k_]
            rbox = np.column_stack([b[:, 0] + s0 * wu[k_], b[:, 0] + s1 * wu[k_],
                                    b[:, 2] + t0 * wv[k_], b[:, 2] + t1 * wv[k_]])
            # inside a box wholly in the material (status 1) the nested box is too: the
            # material is the box; the others are classified against their box's segments
            status = np.ones(len(k_), np.int8)
            segs_k = np.full((len(k_), MAX_SEGMENTS), -1, dtype=np.int64)
            st = np.zeros((len(k_), 4 + 2 * MAX_SEGMENTS, 2))
            st[:, :4] = CORNERS
            okv = np.zeros((len(k_), 4 + 2 * MAX_SEGMENTS), bool)
            okv[:, :4] = True
            cut = np.flatnonzero(stat[k_] == 2)
            if len(cut) and len(d.edges):
                status[cut], segs_k[cut] = d.classify(rbox[cut], segs[k_[cut]])
                segs[k_[cut]] = segs_k[cut]
                stat[k_[cut]] = status[cut]
                st[cut], okv[cut] = d.vertices(_Items(np.zeros(len(cut), int),
                                                      np.arange(len(cut)), sub[cut],
                                                      rbox[cut], np.zeros(len(cut), int),
                                                      status[cut], segs_k[cut]))
            # too many segments to list: the whole box's corners bound the polygon
            whole = (segs_k[:, 0] == -2) | ~okv.any(axis=1)
            okv[whole] = False
            okv[whole, :4] = True
            rel = st - np.column_stack([ls, lt])[:, None, :]  # (n, V, 2): d of each vertex
            # candidate directions nu (n, C, 2): n1's own, the axes, the segments' normals
            n1n = np.hypot(n1[:, 0], n1[:, 1])
            unit = n1 / np.where(n1n > 0, n1n, 1.0)[:, None]
            eye = np.broadcast_to(np.eye(2), (len(k_), 2, 2))
            valid_seg = segs_k >= 0
            e = (d.edges if len(d.edges) else np.zeros((1, 4)))[np.maximum(segs_k, 0)]
            tan = np.stack([(e[..., 2] - e[..., 0]) / du[:, None],
                            (e[..., 3] - e[..., 1]) / dv[:, None]], axis=-1)
            nrm = np.stack([-tan[..., 1], tan[..., 0]], axis=-1)
            nl = np.hypot(nrm[..., 0], nrm[..., 1])
            valid_seg &= nl > 0
            nrm = nrm / np.where(nl > 0, nl, 1.0)[..., None]
            nu = np.concatenate([unit[:, None], eye, nrm], axis=1)
            cok = np.concatenate([np.ones((len(k_), 3), bool), valid_seg], axis=1)
            alpha = np.einsum("nc,nkc->nk", n1, nu)
            nu = nu * np.where(alpha < 0, -1.0, 1.0)[..., None]  # orient: alpha >= 0
            alpha = np.abs(alpha)
            beta = np.sqrt(np.maximum(n1n[:, None] ** 2 - alpha ** 2, 0.0))
            proj = np.einsum("nkc,nvc->nkv", nu, rel)
            delta = np.maximum(np.where(okv[:, None, :], proj, -np.inf).max(axis=2), 0.0)
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                cand = wmax[:, None] * alpha * delta + (wmax[:, None] * beta) ** 2 / (
                    4.0 * kk[:, None])
                cand = np.where(cok, cand, np.inf)
                excess = cand.min(axis=1) / (wmin * wmin)
            usable = (status > 0) | whole
            # k > 0 is all the bound needs: where the face turns steep its xy map nears
            # singular (s_eff <= 0, no concavity from the hemisphere), but a convex face's own
            # curvature (lam < 0) still makes f strongly concave along it
            ok = np.flatnonzero((kk > 0) & (wmin > 0) & usable & (excess <= limit[k_]))
            # rows run query by query, largest box first: each query's first good row
            first = ok[np.unique(k_[ok], return_index=True)[1]]
            hit = k_[first]
            found[hit] = True
            out_box[hit] = rbox[first]
            out_ex[hit] = excess[first]
            todo[hit] = False
        return found, out_box, out_ex

    @staticmethod
    def _grad_hess(s, u: FloatArray, v: FloatArray, qq: FloatArray, R2: float):
        """Gradient (gu, gw) and Hessian (Huu, Huw, Hww) of f(u, v) = S_z + sqrt(R^2 -
        |S_xy - q|^2)."""
        j = s.derivatives(u, v)
        D = j.point[:, :2] - qq
        h = np.sqrt(np.maximum(R2 - (D * D).sum(axis=1), 1e-300))
        Du, Dw = j.su[:, :2], j.sw[:, :2]
        dDu = (D * Du).sum(1)
        dDw = (D * Dw).sum(1)
        gu = j.su[:, 2] - dDu / h
        gw = j.sw[:, 2] - dDw / h
        h3 = h ** 3
        Huu = j.suu[:, 2] - ((Du * Du).sum(1) + (D * j.suu[:, :2]).sum(1)) / h - dDu ** 2 / h3
        Hww = j.sww[:, 2] - ((Dw * Dw).sum(1) + (D * j.sww[:, :2]).sum(1)) / h - dDw ** 2 / h3
        Huw = (j.suw[:, 2] - ((Du * Dw).sum(1) + (D * j.suw[:, :2]).sum(1)) / h
               - dDu * dDw / h3)
        return gu, gw, Huu, Huw, Hww

    @staticmethod
    def _newton_step(s, u: FloatArray, v: FloatArray, qq: FloatArray, R2: float):
        """Newton step of f(u, v) (gradient and Hessian as in :meth:`DropCutter.refine`):
        (concave here, new u, new v)."""
        gu, gw, Huu, Huw, Hww = FaceSet._grad_hess(s, u, v, qq, R2)
        det = Huu * Hww - Huw * Huw
        concave = (Huu < 0) & (det > 0)
        safe = np.where(concave, det, 1.0)
        du = np.where(concave, -(Hww * gu - Huw * gw) / safe, 0.0)
        dw = np.where(concave, -(Huu * gw - Huw * gu) / safe, 0.0)
        # on a side of the domain with the ascent pointing out: Newton along the side only
        (u0, u1), (v0, v1) = s.domain
        pin_u = ((u <= u0) & (gu < 0)) | ((u >= u1) & (gu > 0))
        pin_v = ((v <= v0) & (gw < 0)) | ((v >= v1) & (gw > 0))
        side_u = pin_u & ~pin_v & (Hww < 0)
        side_v = pin_v & ~pin_u & (Huu < 0)
        du = np.where(side_u, 0.0, np.where(side_v, -gu / np.where(side_v, Huu, 1.0), du))
        dw = np.where(side_v, 0.0, np.where(side_u, -gw / np.where(side_u, Hww, 1.0), dw))
        ok = (concave | side_u | side_v) & np.isfinite(du) & np.isfinite(dw)
        return ok, u + np.where(ok, du, 0.0), v + np.where(ok, dw, 0.0)

    def _bounds(self, d: _FaceData, it: _Items, q: FloatArray, R: float,
                floor: FloatArray | float = -np.inf):
        """Upper bound of f over each sub-patch's material, a lower bound (f at a surface
        point inside the trim, -inf if none) and that point's (u, v).  Pairs whose bound is
        at most ``floor`` (per pair: they will be dropped) are not bounded more tightly."""
        n = len(it.query)
        R2 = R * R
        # the query-free part, once per sub-patch of the table (see _Items)
        N = len(it.nets)
        flat = it.nets.reshape(N, 4, -1)
        if d.face.surface.rational:
            w = flat[:, 3]
            PX, PY, PZ = flat[:, 0] / w, flat[:, 1] / w, flat[:, 2] / w  # (N, K) planes
        else:
            PX, PY, PZ = flat[:, 0], flat[:, 1], flat[:, 2]
        CX, CY, CZ = PX.mean(axis=1), PY.mean(axis=1), PZ.mean(axis=1)
        # g = grad f(centroid) . (P_k - centroid) = G0 - a GX - b GY (a, b from the query):
        # its affine part and residuals split the same way
        G = np.stack([PZ - CZ[:, None], PX - CX[:, None], PY - CY[:, None]])  # (3, N, K)
        C = G @ d.pinv.T  # (3, N, 3)
        RS = G - C @ d.design.T  # (3, N, K)
        nd = it.node
        qq = q[it.query]
        qx, qy = qq[:, :1], qq[:, 1:]
        dx = np.maximum(np.maximum(PX.min(axis=1)[nd] - qq[:, 0],
                                   qq[:, 0] - PX.max(axis=1)[nd]), 0.0)
        dy = np.maximum(np.maximum(PY.min(axis=1)[nd] - qq[:, 1],
                                   qq[:, 1] - PY.max(axis=1)[nd]), 0.0)
        dd = dx * dx + dy * dy
        reach = dd <= R2
        ub = np.where(reach, PZ.max(axis=1)[nd] + np.sqrt(np.maximum(R2 - dd, 0.0)), -np.inf)
        # tangent-plane bound of the concave maximand at the net's centroid
        cz = CZ[nd]
        ox, oy = CX[nd] - qq[:, 0], CY[nd] - qq[:, 1]
        d0 = ox * ox + oy * oy
        lin_ok = d0 < 0.999 * R2
        s0 = np.sqrt(np.maximum(R2 - d0, 1e-300))
        a_, b_ = (ox / s0)[:, None], (oy / s0)[:, None]
        coef = C[0, nd] - a_ * C[1, nd] - b_ * C[2, nd]  # (n, 3): a(s, t) = c0 + c1 s + c2 t
        resid = (RS[0, nd] - a_ * RS[1, nd] - b_ * RS[2, nd]).max(axis=1)
        # affine part at the corners (valid for the whole box, rational patches included)
        amax = coef[:, 0] + np.maximum(coef[:, 1], 0.0) + np.maximum(coef[:, 2], 0.0)
        cok = np.ones((n, 4), bool)
        strad = np.flatnonzero(it.status == 2)
        if len(strad):
            st, ok = d.vertices(it.take(strad))
            cok[strad] = ok[:, :4]
            cs = coef[strad]
            aval = cs[:, :1] + cs[:, 1:2] * st[..., 0] + cs[:, 2:3] * st[..., 1]
            listed = it.segs[strad, 0] != -2  # else too many segments: the whole box bounds
            at = np.where(ok, aval, -np.inf).max(axis=1)
            if d.face.surface.rational:
                # the material's vertices plus the drift of the affine part (at most the
                # corners' bound, which holds as well)
                at = at + _rational_drift(flat[:, 3][nd[strad]], cs)
                amax[strad[listed]] = np.minimum(amax[strad[listed]], at[listed])
            else:
                # polynomial patch: the material's vertices
                amax[strad[listed]] = at[listed]
            none = ~ok.any(axis=1) & listed
            reach[strad[none]] = False
        lin = cz + s0 + amax + resid
        ub = np.where(lin_ok & (lin < ub), lin, ub)
        ub[~reach] = -np.inf
        # next to the ball's rim the box's distance bounds f only to first order, by a slope
        # that grows without bound there: the material's own distance instead (where the
        # bounds so far leave the pair open)
        rim = np.flatnonzero((ub > floor) & (dd >= (RIM_FRACTION * R) ** 2)
                             & (it.depth >= RIM_DEPTH))
        if len(rim):
            in_strad = np.full(n, -1)
            if len(strad):
                in_strad[strad[listed]] = np.flatnonzero(listed)
            k_ = in_strad[rim]
            zb = np.empty(len(rim))
            rb = np.empty(len(rim))
            w_all = flat[:, 3] if d.face.surface.rational else None
            cut = k_ >= 0
            for sel in (np.flatnonzero(~cut), np.flatnonzero(cut)):
                if len(sel) == 0:
                    continue
                rows = rim[sel]
                if cut[sel[0]]:
                    # the corners and the ends of the segments present (at most kk of them)
                    kk = max(int((it.segs[rows] >= 0).sum(axis=1).max()), 1)
                    cols = np.r_[0:4 + kk, 4 + MAX_SEGMENTS:4 + MAX_SEGMENTS + kk]
                    vst, vok = st[k_[sel]][:, cols], ok[k_[sel]][:, cols]
                else:
                    kk = 0
                    vst = np.broadcast_to(CORNERS, (len(sel), 4, 2))
                    vok = np.ones((len(sel), 4), bool)
                zb[sel], rb[sel] = _material_reach(
                    vst, vok, kk, nd[rows], qq[rows], (CX, CY, CZ), C, RS,
                    None if w_all is None else w_all[nd[rows]])
            far = rb * rb > R2
            ub[rim[far]] = -np.inf
            near = ~far
            ub[rim[near]] = np.minimum(ub[rim[near]],
                                       zb[near] + np.sqrt(np.maximum(R2 - rb[near] ** 2, 0.0)))
        # lower bound: corners (control points on the surface) inside the trim
        cidx = _corner_index(d.p, d.q)
        cx_, cy_, cz_ = PX[:, cidx][nd], PY[:, cidx][nd], PZ[:, cidx][nd]
        cd = (cx_ - qx) ** 2 + (cy_ - qy) ** 2
        fc = np.where((cd <= TOUCH * R2) & cok, cz_ + np.sqrt(np.maximum(R2 - cd, 0.0)),
                      -np.inf)
        k = np.argmax(fc, axis=1)
        rows = np.arange(n)
        lb = fc[rows, k]
        sloc = CORNERS[k]

        def ball_at(sel, loc):
            """(u, v) of the points at local ``loc`` of sub-patches ``sel`` and the tip height
            of the ball resting on each (-inf out of its reach)."""
            b = it.box[sel]
            uu = b[:, 0] + loc[:, 0] * (b[:, 1] - b[:, 0])
            vv = b[:, 2] + loc[:, 1] * (b[:, 3] - b[:, 2])
            p = d.face.surface.evaluate(uu, vv)
            pd = ((p[:, :2] - qq[sel]) ** 2).sum(axis=1)
            fv = np.where(pd <= TOUCH * R2, p[:, 2] + np.sqrt(np.maximum(R2 - pd, 0.0)),
                          -np.inf)
            return uu, vv, fv

        def raise_bound(sel, loc, fv) -> None:
            better = fv > lb[sel]
            lb[sel[better]] = fv[better]
            sloc[sel[better]] = loc[better]

        # straddling sub-patches: the best trim vertex, evaluated on the surface
        if len(strad):
            tv = np.where(ok[:, 4:], aval[:, 4:], -np.inf)
            kk = np.argmax(tv, axis=1)
            has = np.isfinite(tv[np.arange(len(strad)), kk]) & reach[strad]
            sel, kk = strad[has], kk[has]
            if len(sel):
                loc = st[np.flatnonzero(has), 4 + kk]
                raise_bound(sel, loc, ball_at(sel, loc)[2])
        # shallow sub-patches (their corners mostly out of the ball's reach): also the surface
        # point at the Greville abscissae of the control point nearest the query in xy, about
        # where the ball comes down, so that an early lower bound prunes the other faces
        sel = np.flatnonzero((it.depth <= SEED_DEPTH) & reach)
        if len(sel):
            ns = nd[sel]
            kn = np.argmin((PX[ns] - qx[sel]) ** 2 + (PY[ns] - qy[sel]) ** 2, axis=1)
            loc = d.design[kn, 1:]
            uu, vv, fv = ball_at(sel, loc)
            strad_sel = it.status[sel] == 2
            if strad_sel.any():
                fv[strad_sel] = np.where(d.inside(uu[strad_sel], vv[strad_sel]),
                                         fv[strad_sel], -np.inf)
            raise_bound(sel, loc, fv)
        b = it.box
        lu = b[:, 0] + sloc[:, 0] * (b[:, 1] - b[:, 0])
        lv = b[:, 2] + sloc[:, 1] * (b[:, 3] - b[:, 2])
        return ub, lb, lu, lv

    def _children(self, d: _FaceData, it: _Items, mask: np.ndarray | None = None,
                  cut: tuple | None = None) -> _Items:
        """Halve each sub-patch (those in ``mask``) along its longer side (corner distances);
        with ``cut`` = (t, along_u) (n,) each, a sub-patch whose t is finite is split at its
        local parameter t along u (along_u) or v instead.

        Halving depends on the sub-patch alone, and the queries of a pass share their shallow
        sub-patches: each node of the table is halved once, its halves shared (the pieces of
        a split at a region's side, which depends on the query, are the pair's own)."""
        idx_all = np.arange(len(it.query)) if mask is None else np.flatnonzero(mask)
        free = np.ones(len(idx_all), bool)
        if cut is not None:
            t_all = cut[0][idx_all]
            free = ~np.isfinite(t_all)
        nets, boxes, parents, nodes = [], [], [], []
        count = 0
        fi = idx_all[free]
        if len(fi):
            un, inv = np.unique(it.node[fi], return_inverse=True)
            inv = inv.ravel()
            pn = it.nets[un]
            along_u = self._longer_u(d, pn)
            left = np.empty_like(pn)
            right = np.empty_like(pn)
            for axis, sel in ((2, along_u), (3, ~along_u)):
                if sel.any():
                    k = np.flatnonzero(sel)
                    lk = np.empty_like(pn[k])
                    rk = np.empty_like(lk)
                    _split_into(pn[k], axis, lk, rk)
                    left[k], right[k] = lk, rk
            b = it.box[fi]
            au = along_u[inv]
            mu = 0.5 * (b[:, 0] + b[:, 1])
            mv = 0.5 * (b[:, 2] + b[:, 3])
            bl, br = b.copy(), b.copy()
            bl[:, 1] = np.where(au, mu, b[:, 1])
            br[:, 0] = np.where(au, mu, b[:, 0])
            bl[:, 3] = np.where(au, b[:, 3], mv)
            br[:, 2] = np.where(au, b[:, 2], mv)
            nets += [left, right]
            boxes += [bl, br]
            parents += [fi, fi]
            nodes += [inv, len(un) + inv]
            count = 2 * len(un)
        ci = idx_all[~free]
        if len(ci):
            t = t_all[~free]
            along = cut[1][ci]
            b = it.box[ci]
            for axis, sel in ((2, along), (3, ~along)):
                idx = ci[sel]
                m = len(idx)
                if m == 0:
                    continue
                lo, hi = (0, 1) if axis == 2 else (2, 3)
                tt = t[sel]
                bb = b[sel]
                mid = bb[:, lo] + tt * (bb[:, hi] - bb[:, lo])
                b0, b1 = bb.copy(), bb.copy()
                b0[:, hi] = mid
                b1[:, lo] = mid
                pn = it.nets[it.node[idx]]
                nets += [_split_at(pn, axis, tt, True), _split_at(pn, axis, tt, False)]
                boxes += [b0, b1]
                parents += [idx, idx]
                nodes += [count + np.arange(m), count + m + np.arange(m)]
                count += 2 * m
        if not parents:
            return it.take(np.zeros(0, np.intp))
        out = np.concatenate(nets)
        box = np.concatenate(boxes)
        parent = np.concatenate(parents)
        node = np.concatenate(nodes)
        n2 = len(parent)
        status = np.ones(n2, np.int8)
        segs = np.full((n2, MAX_SEGMENTS), -1, dtype=np.int64)
        strad = np.flatnonzero(it.status[parent] == 2)
        if len(strad):
            status[strad], segs[strad] = d.classify(box[strad], it.segs[parent[strad]])
        children = _Items(it.query[parent], node, out, box, it.depth[parent] + 1, status, segs)
        keep = status > 0
        return children if keep.all() else children.take(keep)

    @staticmethod
    def _longer_u(d: _FaceData, net: FloatArray) -> np.ndarray:
        """Whether each net's u side is the longer (the sum of its corners' xy distances)."""
        k2, k3 = net.shape[2] - 1, net.shape[3] - 1
        corner = net[:, :, ::k2, ::k3]  # (n, 4, 2, 2)
        if d.face.surface.rational:
            corner = corner[:, :2] / corner[:, 3:]
        len_u = np.abs(corner[:, :2, 1] - corner[:, :2, 0]).sum(axis=(1, 2))
        len_v = np.abs(corner[:, :2, :, 1] - corner[:, :2, :, 0]).sum(axis=(1, 2))
        return len_u >= len_v

    # -- point probe ---------------------------------------------------------------------------
    def height(self, xy, selected_only: bool = False):
        """Top-most face point above each xy (a point probe): (z, face, u, v, inside).

        Per face, the xy map S_xy(u, v) = q is inverted by Newton's method from the
        HEIGHT_SEEDS nearest (in xy) of a HEIGHT_GRID x HEIGHT_GRID sample of every patch whose
        box holds q (several: near a vertical bit the map folds); a root counts when it lies in
        the patch's domain (to 1e-9) within the trim and reproduces q to 1e-9 of the set's size.
        z is NaN and ``inside`` False where no face lies above.
        """
        q = np.asarray(xy, dtype=float).reshape(-1, 2)
        m = len(q)
        z = np.full(m, -np.inf)
        face = np.full(m, -1)
        uo = np.zeros(m)
        vo = np.zeros(m)
        tol = 1e-9 * max(self.size, 1.0)
        grid = np.linspace(0.0, 1.0, HEIGHT_GRID)
        for d in self.data:
            if selected_only and not d.selected:
                continue
            s = d.face.surface
            roots = d.roots
            eps = 1e-9 * max(self.size, 1.0)
            hit = ((q[:, None, 0] >= d.lo[roots, 0] - eps) & (q[:, None, 0] <= d.hi[roots, 0] + eps)
                   & (q[:, None, 1] >= d.lo[roots, 1] - eps)
                   & (q[:, None, 1] <= d.hi[roots, 1] + eps))
            qi, ri = np.nonzero(hit)
            if len(qi) == 0:
                continue
            box = d.boxes[roots[ri]]
            su = box[:, :1] + grid[None] * (box[:, 1:2] - box[:, :1])
            sv = box[:, 2:3] + grid[None] * (box[:, 3:4] - box[:, 2:3])
            uu = np.repeat(su, HEIGHT_GRID, axis=1)
            vv = np.tile(sv, (1, HEIGHT_GRID))
            pts = s.evaluate(uu, vv)
            dist = ((pts[..., :2] - q[qi, None]) ** 2).sum(axis=-1)
            # several seeds: where the face turns vertical the xy map folds, and the nearest
            # sample may lie on the far side of the fold from the root
            k = np.argsort(dist, axis=1)[:, :HEIGHT_SEEDS]
            rows = np.repeat(np.arange(len(qi)), k.shape[1])
            u, v = uu[rows, k.ravel()], vv[rows, k.ravel()]
            qi, box = qi[rows], box[rows]
            (u0, u1), (v0, v1) = s.domain
            for _ in range(HEIGHT_STEPS):
                p = s.evaluate(u, v)
                su_ = s.evaluate(u, v, du=1)
                sv_ = s.evaluate(u, v, dw=1)
                r = q[qi] - p[:, :2]
                det = su_[:, 0] * sv_[:, 1] - su_[:, 1] * sv_[:, 0]
                det = np.where(np.abs(det) > 1e-300, det, 1e-300)
                du = (r[:, 0] * sv_[:, 1] - r[:, 1] * sv_[:, 0]) / det
                dv = (su_[:, 0] * r[:, 1] - su_[:, 1] * r[:, 0]) / det
                lim_u = box[:, 1] - box[:, 0]
                lim_v = box[:, 3] - box[:, 2]
                du = clamp(du, -lim_u, lim_u)
                dv = clamp(dv, -lim_v, lim_v)
                u = clamp(u + du, u0, u1)
                v = clamp(v + dv, v0, v1)
                if np.all(np.abs(r).max(axis=1) < 1e-3 * tol):
                    break
            p = s.evaluate(u, v)
            ok = np.hypot(*(p[:, :2] - q[qi]).T) <= tol
            ok &= d.inside(u, v)
            ok &= p[:, 2] > z[qi]
            idx = np.flatnonzero(ok)
            order = idx[np.argsort(p[idx, 2], kind="stable")]
            z[qi[order]] = p[order, 2]
            face[qi[order]] = d.index
            uo[qi[order]], vo[qi[order]] = u[order], v[order]
        found = face >= 0
        z[~found] = np.nan
        return z, face, uo, vo, found

    # -- bounds --------------------------------------------------------------------------------
    def bounds(self, selected_only: bool = True) -> tuple[FloatArray, FloatArray]:
        """(lo, hi) 3-vectors (mm): a box enclosing the faces (inside their trims), each side
        found by branch and bound on the Bezier boxes to within 1e-6 of the set's size
        (computed once per ``selected_only``: the op's extent and its passes both ask)."""
        key = bool(selected_only)
        if key not in self._box_memo:
            self._box_memo[key] = self._bounds_box(key)
        lo, hi = self._box_memo[key]
        return lo.copy(), hi.copy()

    def _bounds_box(self, selected_only: bool) -> tuple[FloatArray, FloatArray]:
        data = [d for d in self.data if d.selected or not selected_only]
        if not data and (selected_only or not self.walls.boxes):
            raise BSplineCAMError("no selected face: the selection is empty")
        tol = 1e-6 * max(self.size, 1e-9)
        lo = np.empty(3)
        hi = np.empty(3)
        for c in range(3):
            for sign, out in ((1.0, hi), (-1.0, lo)):
                best = -np.inf
                for d in data:
                    best = max(best, self._extreme(d, c, sign, tol, best))
                out[c] = sign * best
        if not selected_only:
            for wlo, whi in self.walls.boxes:  # a wall's extremes lie on its border
                lo, hi = np.minimum(lo, wlo), np.maximum(hi, whi)
        return lo, hi

    def _extreme(self, d: _FaceData, c: int, sign: float, tol: float, best: float) -> float:
        """max of sign * coordinate c over the face's material (branch and bound)."""
        r = d.roots
        it = _Items(np.zeros(len(r), int), r, d.nets, d.boxes[r], np.zeros(len(r), int),
                    d.root_status[r], d.root_segs[r])
        cap = -np.inf
        for _ in range(MAX_DEPTH):
            if len(it.query) == 0:
                break
            flat = it.net.reshape(len(it.query), 4, -1)
            vals = sign * flat[:, c] / flat[:, 3]
            ub = vals.max(axis=1)
            coef = vals @ d.pinv.T
            resid = (vals - coef @ d.design.T).max(axis=1)
            cidx = _corner_index(d.p, d.q)
            cok = np.ones((len(vals), 4), bool)
            strad = np.flatnonzero(it.status == 2)
            if len(strad):
                st, ok = d.vertices(it.take(strad))
                cok[strad] = ok[:, :4]
                listed = it.segs[strad, 0] != -2
                if listed.any():
                    # the coordinate is a scalar Bezier patch: affine part at the material's
                    # vertices plus the largest residual of its coefficients (a rational
                    # patch: plus the affine part's drift, :func:`_rational_drift`)
                    strad, st, ok = strad[listed], st[listed], ok[listed]
                    cs = coef[strad]
                    aval = cs[:, :1] + cs[:, 1:2] * st[..., 0] + cs[:, 2:3] * st[..., 1]
                    extra = resid[strad]
                    if d.face.surface.rational:
                        extra = extra + _rational_drift(flat[strad, 3], cs)
                    ub[strad] = np.minimum(ub[strad],
                                           np.where(ok, aval, -np.inf).max(axis=1) + extra)
                loc = st[:, 4:]
                good = ok[:, 4:]
                if good.any():
                    b = it.box[strad]
                    uu = b[:, :1] + loc[..., 0] * (b[:, 1:2] - b[:, :1])
                    vv = b[:, 2:3] + loc[..., 1] * (b[:, 3:4] - b[:, 2:3])
                    p = d.face.surface.evaluate(uu[good], vv[good])
                    best = max(best, float((sign * p[:, c]).max()))
            cv = np.where(cok, vals[:, cidx], -np.inf)
            best = max(best, float(cv.max(initial=-np.inf)))
            keep = ub > best + tol
            # what is dropped is bounded by its upper bounds: the result encloses the face
            cap = max(cap, float(ub[~keep].max(initial=-np.inf)))
            if not keep.any():
                break
            if _ == MAX_DEPTH - 1:
                cap = max(cap, float(ub.max()))
            it = self._children(d, it, keep)
        return max(best, cap)


__all__ = ["CERTIFY", "DropResult", "FaceSet"]
