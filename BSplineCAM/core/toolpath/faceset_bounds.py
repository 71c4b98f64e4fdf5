# SPDX-License-Identifier: LGPL-2.1-or-later
"""Bounds of the drop-cutter's maximand over sub-patches (:mod:`.faceset`).

For each (query, sub-patch) pair of a level, :func:`sub_patch_bounds` gives an upper bound of
f(p) = p_z + sqrt(R^2 - |p_xy - q|^2) over the sub-patch's material (the smaller of the box
bound and the tangent-plane bound at the net's centroid, evaluated at the material's vertices;
near the ball's rim also the material's own reach) and a lower bound from surface points
inside the trim (corners, trim vertices, and on shallow sub-patches the point below the
control point nearest the query).

Under the numba engine (:mod:`..kernels`) the net planes, the box and tangent-plane bounds,
the straddling sub-patches' material and the corners' lower bounds run in one compiled call
(:func:`..kernels.faceset_round_kernels.bound_pairs`), the same arithmetic in the same order
but for the nets' affine parts, whose products numpy leaves to its BLAS: the same bounds to
rounding, the same lower bounds and contacts."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import kernels
from ..errors import BSplineCAMError
from ..kernels import faceset_kernels as fk
from ..kernels import faceset_rim_kernels as rimk
from ..kernels import faceset_round_kernels as rk
from ..typing import FloatArray
from .faceset_bezier import _corner_index, _material_reach, _rational_drift
from .faceset_params import (
    CORNERS,
    MAX_SEGMENTS,
    RIM_DEPTH,
    RIM_FRACTION,
    RIM_ROUNDING_MM,
    SEED_DEPTH,
    TOUCH,
)
from .faceset_trims import _FaceData, _Items


def sub_patch_bounds(d: _FaceData, it: _Items, q: FloatArray, R: float,
                     floor: FloatArray | float = -np.inf):
    """Upper bound of f over each sub-patch's material, a lower bound (f at a surface
    point inside the trim, -inf if none) and that point's (u, v).  Pairs whose bound is
    at most ``floor`` (per pair: they will be dropped) are not bounded more tightly."""
    if kernels.use_numba() and it.nets.shape[2] * it.nets.shape[3] <= fk.MAX_NET:
        try:
            return _fused_bounds(d, it, q, R, floor)
        except kernels.KernelUnavailable:
            pass
    n = len(it.query)
    R2 = R * R
    P = _net_planes(d, it.nets)
    nd = it.node
    qq = q[it.query]
    ub, dd, reach = _box_bound(P, nd, qq, R2)
    cz, s0, lin_ok, coef, resid, amax = _tangent_plane(P, nd, qq, R2)
    cok = np.ones((n, 4), bool)
    m = _straddling(d, it, P, coef, amax, reach, cok)
    lin = cz + s0 + amax + resid
    ub = np.where(lin_ok & (lin < ub), lin, ub)
    ub[~reach] = -np.inf
    _rim_bound(d, it, P, qq, R, ub, dd, floor, m)
    lb, lu, lv = _lower_bounds(d, it, P, qq, R2, reach, cok, m)
    return ub, lb, lu, lv


def _fused_bounds(d: _FaceData, it: _Items, q: FloatArray, R: float,
                  floor: FloatArray | float):
    """:func:`sub_patch_bounds` in one compiled call (the nets' planes and every pair's
    bounds, the surface points of the lower bounds included:
    :func:`..kernels.faceset_round_kernels.bound_pairs`), and the rim bound in a second
    (:func:`_rim_compiled`) where some pair needs it."""
    n = len(it.query)
    R2 = R * R
    N = len(it.nets)
    flat = np.ascontiguousarray(it.nets.reshape(N, 4, -1))
    qq = np.ascontiguousarray(q[it.query], dtype=float)
    fl = (np.full(n, float(floor)) if np.ndim(floor) == 0
          else np.ascontiguousarray(floor, dtype=float))
    bands = d._bands
    (ub, dd, reach, lb, lu, lv, strad, st, ok, aval, listed, kv, rim, fine, PX, PY, PZ, cen, C,
     RS) = rk.bound_pairs(
        np.ascontiguousarray(it.node, dtype=np.int64), qq, R2, flat,
        bool(d.face.surface.rational), d._pinv, d._design, TOUCH * R2, d._corners, CORNERS,
        np.ascontiguousarray(it.box, dtype=float), np.ascontiguousarray(it.segs, dtype=np.int64),
        np.ascontiguousarray(it.status, dtype=np.int8), d.edges, bands.table, float(bands.v0),
        float(bands.h), d._inner, fl, np.ascontiguousarray(it.depth, dtype=np.int64),
        (RIM_FRACTION * R) ** 2, RIM_DEPTH, SEED_DEPTH, *d.point_pack())
    m = (_Straddling(strad, st, ok, aval, listed) if len(strad)
         else _Straddling(strad, None, None, None, None))
    P = _NetPlanes(flat, PX, PY, PZ, cen[:, 0], cen[:, 1], cen[:, 2], C, RS)
    if not fine:
        raise BSplineCAMError(f"face {d.index}: a sub-patch's point fell outside its surface's "
                              "domain (the sub-patch's box is not within the domain)")
    if rim:
        _rim_bound(d, it, P, qq, R, ub, dd, floor, m)
    return ub, lb, lu, lv


@dataclass
class _NetPlanes:
    """The query-free part of the bounds, once per sub-patch of the table (see
    :class:`.faceset_trims._Items`): the control points' coordinate planes, their centroid,
    and the affine part and residuals of (z, x, y) about it."""

    #: the homogeneous nets (N, 4, K)
    flat: FloatArray
    #: the control points' coordinates (N, K) each
    PX: FloatArray
    PY: FloatArray
    PZ: FloatArray
    #: their centroid (N,) each
    CX: FloatArray
    CY: FloatArray
    CZ: FloatArray
    #: affine parts (3, N, 3) of (z, x, y) about the centroid, and residuals (3, N, K)
    C: FloatArray
    RS: FloatArray


def _net_planes(d: _FaceData, nets: FloatArray) -> _NetPlanes:
    """:class:`_NetPlanes` of the table ``nets`` (N, 4, p+1, q+1) of face ``d``."""
    N = len(nets)
    flat = nets.reshape(N, 4, -1)
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
    return _NetPlanes(flat, PX, PY, PZ, CX, CY, CZ, C, RS)


def _box_bound(P: _NetPlanes, nd: np.ndarray, qq: FloatArray,
               R2: float) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """The box bound z_max + sqrt(R^2 - dist(q, box_xy)^2) of each pair (-inf out of reach),
    the squared xy distance of its net's box and whether it is within reach."""
    dx = np.maximum(np.maximum(P.PX.min(axis=1)[nd] - qq[:, 0],
                               qq[:, 0] - P.PX.max(axis=1)[nd]), 0.0)
    dy = np.maximum(np.maximum(P.PY.min(axis=1)[nd] - qq[:, 1],
                               qq[:, 1] - P.PY.max(axis=1)[nd]), 0.0)
    dd = dx * dx + dy * dy
    reach = dd <= R2
    ub = np.where(reach, P.PZ.max(axis=1)[nd] + np.sqrt(np.maximum(R2 - dd, 0.0)), -np.inf)
    return ub, dd, reach


def _tangent_plane(P: _NetPlanes, nd: np.ndarray, qq: FloatArray, R2: float) -> tuple:
    """The parts of the tangent-plane bound of the concave maximand at the net's centroid:
    (centroid z, sqrt(R^2 - d0^2), whether d0 is well inside R, the affine part's coefficients
    (n, 3): a(s, t) = c0 + c1 s + c2 t, the largest residual, the affine part's largest value
    on the box)."""
    cz = P.CZ[nd]
    ox, oy = P.CX[nd] - qq[:, 0], P.CY[nd] - qq[:, 1]
    d0 = ox * ox + oy * oy
    lin_ok = d0 < 0.999 * R2
    s0 = np.sqrt(np.maximum(R2 - d0, 1e-300))
    a_, b_ = (ox / s0)[:, None], (oy / s0)[:, None]
    coef = P.C[0, nd] - a_ * P.C[1, nd] - b_ * P.C[2, nd]  # (n, 3): a(s, t) = c0 + c1 s + c2 t
    resid = (P.RS[0, nd] - a_ * P.RS[1, nd] - b_ * P.RS[2, nd]).max(axis=1)
    # affine part at the corners (valid for the whole box, rational patches included)
    amax = coef[:, 0] + np.maximum(coef[:, 1], 0.0) + np.maximum(coef[:, 2], 0.0)
    return cz, s0, lin_ok, coef, resid, amax


@dataclass
class _Straddling:
    """The pairs whose sub-patch straddles the trim, and their material's vertices."""

    #: pair indices (s,)
    strad: np.ndarray
    #: the vertices' local (s, t) (s, 4 + 2K, 2), their validity and the affine part there
    st: FloatArray | None
    ok: np.ndarray | None
    aval: FloatArray | None
    #: whether the pair's trim segments are listed (else the whole box bounds it)
    listed: np.ndarray | None


def _straddling(d: _FaceData, it: _Items, P: _NetPlanes, coef: FloatArray, amax: FloatArray,
                reach: np.ndarray, cok: np.ndarray) -> _Straddling:
    """On straddling sub-patches, the affine part's largest value ``amax`` over the
    material's vertices instead of the box's corners (rational patches: plus its drift, where
    smaller), the corners' validity ``cok`` and ``reach`` (no material: out of reach), all
    in place."""
    strad = np.flatnonzero(it.status == 2)
    if not len(strad):
        return _Straddling(strad, None, None, None, None)
    nd = it.node
    st, ok = d.vertices(it.take(strad))
    cok[strad] = ok[:, :4]
    cs = coef[strad]
    aval = cs[:, :1] + cs[:, 1:2] * st[..., 0] + cs[:, 2:3] * st[..., 1]
    listed = it.segs[strad, 0] != -2  # else too many segments: the whole box bounds
    at = np.where(ok, aval, -np.inf).max(axis=1)
    if d.face.surface.rational:
        # the material's vertices plus the drift of the affine part (at most the
        # corners' bound, which holds as well)
        at = at + _rational_drift(P.flat[:, 3][nd[strad]], cs)
        amax[strad[listed]] = np.minimum(amax[strad[listed]], at[listed])
    else:
        # polynomial patch: the material's vertices
        amax[strad[listed]] = at[listed]
    none = ~ok.any(axis=1) & listed
    reach[strad[none]] = False
    return _Straddling(strad, st, ok, aval, listed)


def _rim_bound(d: _FaceData, it: _Items, P: _NetPlanes, qq: FloatArray, R: float,
               ub: FloatArray, dd: FloatArray, floor: FloatArray | float,
               m: _Straddling) -> None:
    """Next to the ball's rim the box's distance bounds f only to first order, by a slope
    that grows without bound there: deep pairs far out in xy that the bounds so far leave
    open (above ``floor``) are bounded by the material's own z and distance as well
    (:func:`.faceset_bezier._material_reach`), ``ub`` in place."""
    n = len(it.query)
    R2 = R * R
    nd = it.node
    if kernels.use_numba():
        try:
            _rim_compiled(d, it, P, qq, R, ub, dd, floor, m)
            return
        except kernels.KernelUnavailable:
            pass
    rim = np.flatnonzero((ub > floor) & (dd >= (RIM_FRACTION * R) ** 2)
                         & (it.depth >= RIM_DEPTH))
    if not len(rim):
        return
    strad = m.strad
    in_strad = np.full(n, -1)
    if len(strad):
        in_strad[strad[m.listed]] = np.flatnonzero(m.listed)
    k_ = in_strad[rim]
    zb = np.empty(len(rim))
    rb = np.empty(len(rim))
    w_all = P.flat[:, 3] if d.face.surface.rational else None
    cut = k_ >= 0
    for sel in (np.flatnonzero(~cut), np.flatnonzero(cut)):
        if len(sel) == 0:
            continue
        rows = rim[sel]
        if cut[sel[0]]:
            # the corners and the ends of the segments present (at most kk of them)
            kk = max(int((it.segs[rows] >= 0).sum(axis=1).max()), 1)
            cols = np.r_[0:4 + kk, 4 + MAX_SEGMENTS:4 + MAX_SEGMENTS + kk]
            vst, vok = m.st[k_[sel]][:, cols], m.ok[k_[sel]][:, cols]
        else:
            kk = 0
            vst = np.broadcast_to(CORNERS, (len(sel), 4, 2))
            vok = np.ones((len(sel), 4), bool)
        zb[sel], rb[sel] = _material_reach(
            vst, vok, kk, nd[rows], qq[rows], (P.CX, P.CY, P.CZ), P.C, P.RS,
            None if w_all is None else w_all[nd[rows]])
    far = rb * rb > R2
    ub[rim[far]] = -np.inf
    near = ~far
    ub[rim[near]] = np.minimum(ub[rim[near]],
                               zb[near] + np.sqrt(np.maximum(R2 - rb[near] ** 2, 0.0)))


_NO_WEIGHTS = np.ones((1, 1))


def _rim_compiled(d: _FaceData, it: _Items, P: _NetPlanes, qq: FloatArray, R: float,
                  ub: FloatArray, dd: FloatArray, floor: FloatArray | float,
                  m: _Straddling) -> None:
    """:func:`_rim_bound` in one compiled call (:func:`..kernels.faceset_rim_kernels.
    rim_bound`: the same pairs, vertices and bits).  Raises :class:`..kernels.
    KernelUnavailable` where the kernel cannot run."""
    n = len(ub)
    R2 = R * R
    f64 = np.float64
    fl = (np.full(n, float(floor)) if np.ndim(floor) == 0
          else np.ascontiguousarray(floor, dtype=f64))
    strad = np.ascontiguousarray(m.strad, dtype=np.int64)
    V = 4 + 2 * it.segs.shape[1]
    if len(strad):
        st = np.ascontiguousarray(m.st, dtype=f64)
        ok = np.ascontiguousarray(m.ok, dtype=bool)
        listed = np.ascontiguousarray(m.listed, dtype=bool)
    else:
        st, ok, listed = np.zeros((0, V, 2)), np.zeros((0, V), bool), np.zeros(0, bool)
    rational = bool(d.face.surface.rational)
    W = np.ascontiguousarray(P.flat[:, 3], dtype=f64) if rational else _NO_WEIGHTS
    rimk.rim_bound(ub, np.ascontiguousarray(dd, dtype=f64), fl,
                   np.ascontiguousarray(it.depth, dtype=np.int64), (RIM_FRACTION * R) ** 2,
                   RIM_DEPTH, R2, np.ascontiguousarray(it.node, dtype=np.int64),
                   np.ascontiguousarray(qq, dtype=f64), strad, listed, st, ok,
                   np.ascontiguousarray(it.segs, dtype=np.int64),
                   np.ascontiguousarray(P.CX, dtype=f64), np.ascontiguousarray(P.CY, dtype=f64),
                   np.ascontiguousarray(P.CZ, dtype=f64), np.ascontiguousarray(P.C, dtype=f64),
                   np.ascontiguousarray(P.RS, dtype=f64), rational, W, RIM_ROUNDING_MM)


def _lower_bounds(d: _FaceData, it: _Items, P: _NetPlanes, qq: FloatArray, R2: float,
                  reach: np.ndarray, cok: np.ndarray,
                  m: _Straddling) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The best of f at each pair's surface points inside the trim (-inf if none) and that
    point's (u, v): the corners (control points on the surface), a straddling sub-patch's
    best trim vertex, and on shallow sub-patches the point below the control point nearest
    the query."""
    n = len(it.query)
    nd = it.node
    qx, qy = qq[:, :1], qq[:, 1:]
    # corners (control points on the surface) inside the trim
    cidx = _corner_index(d.p, d.q)
    cx_, cy_, cz_ = P.PX[:, cidx][nd], P.PY[:, cidx][nd], P.PZ[:, cidx][nd]
    cd = (cx_ - qx) ** 2 + (cy_ - qy) ** 2
    fc = np.where((cd <= TOUCH * R2) & cok, cz_ + np.sqrt(np.maximum(R2 - cd, 0.0)),
                  -np.inf)
    k = np.argmax(fc, axis=1)
    rows = np.arange(n)
    lb = fc[rows, k]
    return _lower_rest(d, it, P, qq, R2, reach, m, lb, k)


def _lower_rest(d: _FaceData, it: _Items, P: _NetPlanes, qq: FloatArray, R2: float,
                reach: np.ndarray, m: _Straddling, lb: FloatArray,
                k: np.ndarray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`_lower_bounds` past the corners (``lb``, the best of them, at corner ``k``):
    the trim vertices and the shallow sub-patches' points, and the points' (u, v)."""
    sloc = CORNERS[k]
    strad = m.strad
    # straddling sub-patches: the best trim vertex, evaluated on the surface
    if len(strad):
        tv = np.where(m.ok[:, 4:], m.aval[:, 4:], -np.inf)
        kk = np.argmax(tv, axis=1)
        has = np.isfinite(tv[np.arange(len(strad)), kk]) & reach[strad]
        sel, kk = strad[has], kk[has]
        if len(sel):
            loc = m.st[np.flatnonzero(has), 4 + kk]
            _raise_bound(lb, sloc, sel, loc, _ball_at(d, it, qq, R2, sel, loc)[2])
    # shallow sub-patches (their corners mostly out of the ball's reach): also the surface
    # point at the Greville abscissae of the control point nearest the query in xy, about
    # where the ball comes down, so that an early lower bound prunes the other faces
    sel = np.flatnonzero((it.depth <= SEED_DEPTH) & reach)
    if len(sel):
        loc, fv = _seed_points(d, it, P, qq, R2, sel)
        _raise_bound(lb, sloc, sel, loc, fv)
    b = it.box
    lu = b[:, 0] + sloc[:, 0] * (b[:, 1] - b[:, 0])
    lv = b[:, 2] + sloc[:, 1] * (b[:, 3] - b[:, 2])
    return lb, lu, lv


def _seed_points(d: _FaceData, it: _Items, P: _NetPlanes, qq: FloatArray, R2: float,
                 sel: np.ndarray) -> tuple[FloatArray, FloatArray]:
    """The local points of shallow sub-patches ``sel`` below their control point nearest
    the query (its Greville abscissae) and the centre height of the ball resting there
    (-inf outside the trim or the ball's reach)."""
    ns = it.node[sel]
    qs = qq[sel]
    kn = np.argmin((P.PX[ns] - qs[:, :1]) ** 2 + (P.PY[ns] - qs[:, 1:]) ** 2, axis=1)
    loc = d.design[kn, 1:]
    uu, vv, fv = _ball_at(d, it, qq, R2, sel, loc)
    strad_sel = it.status[sel] == 2
    if strad_sel.any():
        fv[strad_sel] = np.where(d.inside(uu[strad_sel], vv[strad_sel]),
                                 fv[strad_sel], -np.inf)
    return loc, fv


def _ball_at(d: _FaceData, it: _Items, qq: FloatArray, R2: float, sel: np.ndarray,
             loc: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(u, v) of the points at local ``loc`` of sub-patches ``sel`` and the centre height
    of the ball resting on each (-inf out of its reach)."""
    b = it.box[sel]
    uu = b[:, 0] + loc[:, 0] * (b[:, 1] - b[:, 0])
    vv = b[:, 2] + loc[:, 1] * (b[:, 3] - b[:, 2])
    p = d.face.surface.evaluate(uu, vv)
    pd = ((p[:, :2] - qq[sel]) ** 2).sum(axis=1)
    fv = np.where(pd <= TOUCH * R2, p[:, 2] + np.sqrt(np.maximum(R2 - pd, 0.0)),
                  -np.inf)
    return uu, vv, fv


def _raise_bound(lb: FloatArray, sloc: FloatArray, sel: np.ndarray, loc: FloatArray,
                 fv: FloatArray) -> None:
    """Raise the lower bounds ``lb`` of pairs ``sel`` to ``fv`` where larger, and their local
    points ``sloc`` to ``loc``, in place."""
    better = fv > lb[sel]
    lb[sel[better]] = fv[better]
    sloc[sel[better]] = loc[better]
